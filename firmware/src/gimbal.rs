//! The gimbal model behind the endpoint: two servo axes with a constant-rate
//! motion model, hard stops, presets and the status words of Tables 5, 6,
//! 6A, 6B. Pure logic (no registers), so the same code runs in the firmware
//! and in the bench image.
//!
//! Units: positions in hundredths of a degree on the wire (Table 15), held
//! here in thousandths of that ("milli-centidegrees") so that a rate in
//! hundredths of a degree per second moves the axis `rate` units per
//! millisecond with no rounding drift. Time is milliseconds (SysTick).

use sagebrush_protocol::{
    Angle, AwakeStatus, Axis as WireAxis, Command, DataRate, DeviceHandler, ErrorCodes, Extended, Identity, Position,
    Rate, Reply, ReplyTo, Response, Row, StatusBits,
};

/// Hard stops, hundredths of a degree: pan +-180.00, tilt +-90.00.
const PAN_LIMIT: i16 = 18_000;
const TILT_LIMIT: i16 = 9_000;
/// Fastest slew, hundredths of a degree per second (60 deg/s); `SPF`/`STF`.
pub const MAX_RATE: u16 = 6_000;
/// Rate at power-up (20 deg/s).
const DEFAULT_RATE: u16 = 2_000;
/// Presets 00..PRESETS-1 exist (1.6.1: others are answered with NIC);
/// each starts at home.
pub const PRESETS: usize = 32;
/// A time step longer than this is cut (a stalled main loop must not make
/// an axis jump, and `rate * dt` must stay far from `i32::MAX`).
const MAX_STEP_MS: u64 = 1_000;
/// Identification (Table 6): protocol revision and the two text fields.
const REVISION: [u8; 2] = *b"19";
const NAME: &[u8] = b"SAGEBRUSH QEMU PT";
const SERIAL: &[u8] = b"LM3S6965-0001";

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Motion {
    Idle,
    /// Towards a position, milli-centidegrees.
    GoTo(i32),
    /// Constant rate until stopped or at a hard stop: +1 CCW, -1 CW.
    Slew(i8),
}

/// One axis: position, what it is doing, its rate and its hard stops.
#[derive(Clone, Copy, Debug)]
struct Axis {
    /// Milli-centidegrees.
    position: i32,
    motion: Motion,
    /// Hundredths of a degree per second.
    rate: u16,
    /// Hard stop, centidegrees (symmetric).
    limit: i16,
    /// Table 6B bits latched by the last move (limit reached, hard stop hit).
    status: u16,
}

impl Axis {
    const fn new(limit: i16) -> Self {
        Self {
            position: 0,
            motion: Motion::Idle,
            rate: DEFAULT_RATE,
            limit,
            status: 0,
        }
    }

    fn max(&self) -> i32 {
        i32::from(self.limit) * 1000
    }

    fn angle(&self) -> Angle {
        // |position| <= limit * 1000 with limit <= 18000: the quotient fits.
        Angle((self.position / 1000) as i16)
    }

    fn go_to(&mut self, target: Angle) {
        // min/max, not clamp: clamp asserts its bounds are ordered (a panic site).
        let limit = i32::from(self.limit);
        let target = i32::from(target.0).min(limit).max(-limit);
        self.motion = Motion::GoTo(target * 1000);
        self.status = 0;
    }

    fn slew(&mut self, direction: i8) {
        self.motion = Motion::Slew(direction);
        self.status = 0;
    }

    fn stop(&mut self) {
        self.motion = Motion::Idle;
    }

    /// Moves for `dt` milliseconds.
    fn advance(&mut self, dt: u64) {
        let step = i32::from(self.rate) * dt.min(MAX_STEP_MS) as i32;
        let max = self.max();
        match self.motion {
            Motion::Idle => {}
            Motion::GoTo(target) => {
                let remaining = target - self.position;
                if remaining.abs() <= step {
                    self.position = target;
                    self.motion = Motion::Idle;
                } else {
                    self.position += step * remaining.signum();
                }
            }
            Motion::Slew(direction) => {
                self.position += step * i32::from(direction);
                if self.position >= max {
                    self.position = max;
                    self.motion = Motion::Idle;
                    self.status = StatusBits::POSITIVE_LIMIT_FOUND | StatusBits::POSITIVE_HARD_STOP;
                } else if self.position <= -max {
                    self.position = -max;
                    self.motion = Motion::Idle;
                    self.status = StatusBits::NEGATIVE_LIMIT_FOUND | StatusBits::NEGATIVE_HARD_STOP;
                }
            }
        }
    }
}

/// The whole gimbal as the protocol sees it.
#[derive(Debug)]
pub struct Gimbal {
    pan: Axis,
    tilt: Axis,
    motors_on: bool,
    /// Position stored by `HA`, recalled by `HP`.
    halt_position: Position,
    presets: [Position; PRESETS],
    /// Time of the last `advance`, milliseconds.
    last: u64,
}

impl Default for Gimbal {
    fn default() -> Self {
        Self::new()
    }
}

impl Gimbal {
    pub const fn new() -> Self {
        Self {
            pan: Axis::new(PAN_LIMIT),
            tilt: Axis::new(TILT_LIMIT),
            motors_on: true,
            halt_position: Position::new(Angle(0), Angle(0)),
            presets: [Position::new(Angle(0), Angle(0)); PRESETS],
            last: 0,
        }
    }

    /// Brings the motion model up to `now` (milliseconds).
    pub fn advance(&mut self, now: u64) {
        let dt = now.saturating_sub(self.last);
        self.last = now;
        if dt > 0 && self.motors_on {
            self.pan.advance(dt);
            self.tilt.advance(dt);
        }
    }

    pub fn position(&self) -> Position {
        Position::new(self.pan.angle(), self.tilt.angle())
    }

    fn go_to(&mut self, target: Position) {
        self.motors_on = true;
        self.pan.go_to(target.pan);
        self.tilt.go_to(target.tilt);
    }

    fn axis(&mut self, axis: WireAxis) -> &mut Axis {
        match axis {
            WireAxis::Pan => &mut self.pan,
            WireAxis::Tilt => &mut self.tilt,
        }
    }

    fn preset(&self, n: u8) -> Option<Position> {
        self.presets.get(usize::from(n)).copied()
    }

    /// Table 5: motors off, an error condition.
    fn awake_bits(&self) -> u8 {
        let mut bits = 0;
        if !self.motors_on {
            bits |= AwakeStatus::MOTORS_OFF;
        }
        if self.errors() != (ErrorCodes { pan: 0, tilt: 0 }) {
            bits |= AwakeStatus::ERROR;
        }
        bits
    }

    /// Table 6A. The model has no encoder, temperature or motor-current
    /// faults to report, so every error bit stays clear.
    fn errors(&self) -> ErrorCodes {
        ErrorCodes { pan: 0, tilt: 0 }
    }
}

impl DeviceHandler for Gimbal {
    /// The rows `handle` answers other than with NIC: the endpoint NICs the
    /// rest without reading their arguments (and links no parser for them).
    fn implements(row: Row) -> bool {
        matches!(
            row,
            Row::AwakeStatus
                | Row::Identify
                | Row::QueryErrors
                | Row::QueryStatusBits
                | Row::QueryMaxDataRate
                | Row::SetDataRate
                | Row::SetDeviceId
                | Row::QueryPosition
                | Row::GoTo
                | Row::Home
                | Row::PanLeft
                | Row::PanRight
                | Row::TiltDown
                | Row::TiltUp
                | Row::PanStop
                | Row::TiltStop
                | Row::StopMotion
                | Row::Halt
                | Row::MotorsStop
                | Row::Extended
                | Row::SetRate
                | Row::SetSpeed
                | Row::QueryRates
                | Row::QueryRate
                | Row::StorePreset
                | Row::GoToPreset
                | Row::QueryPreset
                | Row::QueryStoredPreset
        )
    }

    fn handle(&mut self, command: Command<'_>, reply_to: ReplyTo, now: u64) -> Response<'_> {
        self.advance(now);
        let position = |p: Position| Response::Reply(Reply::Position(p));
        match command {
            Command::AwakeStatus => match AwakeStatus::new(self.awake_bits()) {
                Ok(status) => Response::Reply(Reply::AwakeStatus(status)),
                Err(_) => Response::Nic,
            },
            // The responding device's own ID: the endpoint filled in its
            // address where the command had a wildcard.
            Command::Identify => match Identity::new(reply_to.dest.device, REVISION, NAME, SERIAL) {
                Ok(id) => Response::Reply(Reply::Identity(id)),
                Err(_) => Response::Nic,
            },
            Command::QueryErrors => Response::Reply(Reply::Errors(self.errors())),
            Command::QueryStatusBits => {
                let error = if self.awake_bits() & AwakeStatus::ERROR != 0 {
                    StatusBits::ERROR_PRESENT
                } else {
                    0
                };
                Response::Reply(Reply::StatusBits(StatusBits {
                    pan: self.pan.status | error,
                    tilt: self.tilt.status | error,
                }))
            }
            // The UART runs at the default 9600 bps only (1.5.1).
            Command::QueryMaxDataRate => Response::Reply(Reply::MaxDataRate(DataRate::Bps9600)),
            Command::SetDataRate(DataRate::Bps9600) => Response::Done,
            // The endpoint takes the new address once this says Done.
            Command::SetDeviceId(_) => Response::Done,

            Command::QueryPosition => position(self.position()),
            Command::GoTo(target) => {
                self.go_to(target);
                Response::Done
            }
            Command::Home => {
                self.go_to(Position::default());
                Response::Done
            }
            Command::PanLeft | Command::PanRight | Command::TiltDown | Command::TiltUp => {
                self.motors_on = true;
                match command {
                    Command::PanLeft => self.pan.slew(-1),
                    Command::PanRight => self.pan.slew(1),
                    Command::TiltDown => self.tilt.slew(-1),
                    _ => self.tilt.slew(1),
                }
                Response::Done
            }
            Command::PanStop => {
                self.pan.stop();
                Response::Done
            }
            Command::TiltStop => {
                self.tilt.stop();
                Response::Done
            }
            Command::StopMotion => {
                self.pan.stop();
                self.tilt.stop();
                Response::Done
            }
            Command::Halt | Command::MotorsStop => {
                if command == Command::Halt {
                    self.halt_position = self.position();
                }
                self.pan.stop();
                self.tilt.stop();
                self.motors_on = false;
                Response::Done
            }
            Command::Extended(Extended::GoToHaltPosition, []) => {
                self.go_to(self.halt_position);
                Response::Done
            }

            Command::SetRate(axis, Rate(rate)) => {
                self.axis(axis).rate = rate.min(MAX_RATE);
                Response::Done
            }
            Command::SetSpeed(axis, speed) => {
                // SP0..SPF: sixteen steps up to the fastest rate.
                self.axis(axis).rate = (u16::from(speed.get()) + 1) * (MAX_RATE / 16);
                Response::Done
            }
            Command::QueryRates => Response::Reply(Reply::Rates {
                pan: Rate(self.pan.rate),
                tilt: Rate(self.tilt.rate),
            }),
            Command::QueryRate(axis) => Response::Reply(Reply::Rate(Rate(self.axis(axis).rate))),

            Command::StorePreset(n) => match self.presets.get_mut(usize::from(n)) {
                Some(slot) => {
                    *slot = Position::new(self.pan.angle(), self.tilt.angle());
                    Response::Done
                }
                None => Response::Nic,
            },
            Command::GoToPreset(n) => match self.preset(n) {
                Some(target) => {
                    self.go_to(target);
                    Response::Done
                }
                None => Response::Nic,
            },
            Command::QueryPreset(n) | Command::QueryStoredPreset(n) => match self.preset(n) {
                Some(p) => position(p),
                None => Response::Nic,
            },
            _ => Response::Nic,
        }
    }
}
