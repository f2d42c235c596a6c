//! One simulated gimbal: the state behind every command of Tables 4, 11 and
//! 16 and the rev 1.9 list, as a [`DeviceHandler`] for the protocol crate's
//! [`sagebrush_protocol::DeviceEndpoint`].
//!
//! Choices where the document leaves the maker free (each documented on the
//! command it concerns): proportional speed n is `max_rate * (n+1) / 16`;
//! Table 10 limits count [`GimbalConfig::limit_unit`] hundredths of a degree
//! from the centre (cleared = `FFF`); `VS` answers `C<power>L<relays>`;
//! `F?`/`Z?` answer the speed digit; what a unit would not implement (`FA`,
//! `FX`, `ZA..ZF`, `C?`, `*d..`, `*m..`, `*s..`) answers NIC, as do motion
//! commands while `IX` runs and lens commands while the camera is off.

use sagebrush_protocol::{
    Angle, AwakeStatus, Axis as AxisName, Command, DataRate, DeviceHandler, ErrorCodes, HomeStatus, InitResults,
    LensPosition, Limits, Position, RateGain, Reply, ReplyTo, Response, StatusBits, U12,
};

use crate::aux::AuxSerial;
use crate::axis::{Axis, HardStop, STEP_MS};
use crate::config::GimbalConfig;
use crate::lens::LensDrive;

mod commands;

/// Table 9: centre switch detected and limit switch hit, no hard limit.
const INIT_GOOD: u16 = InitResults::CENTER_SWITCH_DETECTED | InitResults::LIMIT_SWITCH_HIT;
/// Table 6A: initialisation error.
const ERROR_INIT: u8 = ErrorCodes::INITIALIZATION;
/// Table 6A: centre reference error.
const ERROR_CENTER: u8 = ErrorCodes::CENTER_REFERENCE;
/// Every Table 10 field at its maximum: "no software limit".
const NO_LIMIT: u16 = 0xFFF;
/// Half width of the centre switch, hundredths of a degree (Table 14 "on centre switch").
const CENTER_SWITCH: i16 = 50;

/// Per-axis motion settings (Table 12).
#[derive(Clone, Copy, Debug)]
struct Drive {
    rate: u16,
    accel: u16,
    gain: RateGain,
}

/// The `IX` sequence (Table 9).
#[derive(Clone, Copy, Debug)]
enum Init {
    Idle,
    Running { until: u64, reply: Option<ReplyTo> },
}

/// A result the gimbal owes after the exchange that asked for it (the
/// deferred `IX` result), for the bus to send through the gimbal's
/// `DeviceEndpoint::send_reply`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct DeferredResult {
    pub reply_to: ReplyTo,
    pub results: InitResults,
    /// When it became due.
    pub at: u64,
}

/// A simulated gimbal.
#[derive(Debug)]
pub struct Gimbal {
    config: GimbalConfig,
    device: u8,
    now: u64,
    pan: Axis,
    tilt: Axis,
    pan_drive: Drive,
    tilt_drive: Drive,
    vector: bool,
    motors_on: bool,
    initialized: bool,
    init: Init,
    errors: ErrorCodes,
    /// Each implemented preset's place; `None` until stored when the
    /// configuration's `unset_presets_nic` says so (it then answers NIC).
    presets: Vec<Option<Position>>,
    halt_position: Option<Position>,
    halt_lens: Option<LensPosition>,
    limits: Limits,
    relays: u8,
    camera_on: bool,
    zoom: LensDrive,
    focus: LensDrive,
    data_rate: DataRate,
    pending_rate: Option<DataRate>,
    aux: [AuxSerial; 2],
    finished: Vec<DeferredResult>,
    scratch: Vec<u8>,
}

fn u12(v: u16) -> U12 {
    U12::new(v.min(NO_LIMIT)).unwrap_or_else(|_| unreachable!("clamped to 12 bits"))
}

impl Gimbal {
    /// A gimbal at rest at home, at time `now`. The configuration must have
    /// passed [`GimbalConfig::validate`].
    pub fn new(config: GimbalConfig, now: u64) -> Self {
        let drive = Drive {
            rate: config.rate.min(config.max_rate),
            accel: config.accel,
            gain: RateGain::new(10).unwrap_or_else(|_| unreachable!("1.0 is a valid gain")),
        };
        let no_limit = u12(NO_LIMIT);
        let initialized = config.start_initialized;
        Self {
            device: config.device,
            now,
            pan: Axis::new(0, config.pan_range.0, config.pan_range.1),
            tilt: Axis::new(0, config.tilt_range.0, config.tilt_range.1),
            pan_drive: drive,
            tilt_drive: drive,
            vector: false,
            motors_on: true,
            initialized,
            init: Init::Idle,
            errors: ErrorCodes::default(),
            presets: vec![(!config.unset_presets_nic).then(Position::default); usize::from(config.presets)],
            halt_position: None,
            halt_lens: None,
            limits: Limits {
                pan_ccw: no_limit,
                pan_cw: no_limit,
                tilt_ccw: no_limit,
                tilt_cw: no_limit,
            },
            relays: 0,
            camera_on: config.camera_on,
            zoom: LensDrive::new(0, 5, config.lens_travel_ms),
            focus: LensDrive::new(0, 5, config.lens_travel_ms),
            data_rate: DataRate::Bps9600,
            pending_rate: None,
            aux: [AuxSerial::default(), AuxSerial::default()],
            finished: Vec::new(),
            scratch: Vec::new(),
            config,
        }
    }

    pub fn config(&self) -> &GimbalConfig {
        &self.config
    }

    /// Current device address (changed by `#NN`).
    pub fn device(&self) -> u8 {
        self.device
    }

    pub fn position(&self) -> Position {
        Position::new(Angle(self.pan.position()), Angle(self.tilt.position()))
    }

    pub fn lens(&self) -> LensPosition {
        LensPosition {
            zoom: u12(self.zoom.position()),
            focus: u12(self.focus.position()),
        }
    }

    /// How fast each axis (pan, tilt) moves, hundredths of a degree per
    /// millisecond (signed).
    pub fn velocities(&self) -> [f64; 2] {
        [self.pan.velocity(), self.tilt.velocity()]
    }

    /// Whether either axis or a lens function is moving.
    pub fn is_moving(&self) -> bool {
        self.pan.is_moving() || self.tilt.is_moving() || self.zoom.is_moving() || self.focus.is_moving()
    }

    pub fn is_initialized(&self) -> bool {
        self.initialized
    }

    pub fn motors_on(&self) -> bool {
        self.motors_on
    }

    pub fn relays(&self) -> u8 {
        self.relays
    }

    pub fn camera_on(&self) -> bool {
        self.camera_on
    }

    pub fn data_rate(&self) -> DataRate {
        self.data_rate
    }

    /// Table 10 limits as last set (all `FFF` when cleared).
    pub fn limits(&self) -> Limits {
        self.limits
    }

    /// Bytes lost to a full auxiliary receive buffer, per port.
    pub fn aux_overruns(&self) -> [u64; 2] {
        [self.aux[0].overruns(), self.aux[1].overruns()]
    }

    /// A data-rate change (`C0..C7`) accepted since the last call: the line
    /// switches after the ACK has gone out.
    pub fn take_rate_change(&mut self) -> Option<DataRate> {
        self.pending_rate.take()
    }

    /// Deferred results that have become due (the `IX` result of Table 9).
    pub fn take_finished(&mut self) -> Vec<DeferredResult> {
        std::mem::take(&mut self.finished)
    }

    /// When the model next has something to report by itself.
    pub fn next_deadline(&self) -> Option<u64> {
        match self.init {
            Init::Running { until, .. } => Some(until),
            Init::Idle => None,
        }
    }

    /// Advances the physics to `now` (milliseconds; time never runs back).
    pub fn advance_to(&mut self, now: u64) {
        if let Init::Running { until, reply } = self.init {
            if until <= now {
                self.run_until(until);
                self.finish_init(reply, until);
            }
        }
        self.run_until(now);
    }

    fn run_until(&mut self, now: u64) {
        if now <= self.now {
            return;
        }
        let elapsed = now - self.now;
        if self.pan.is_moving() || self.tilt.is_moving() {
            for _ in 0..elapsed / STEP_MS {
                self.pan.step();
                self.tilt.step();
                if !self.pan.is_moving() && !self.tilt.is_moving() {
                    break;
                }
            }
        }
        self.zoom.advance(elapsed);
        self.focus.advance(elapsed);
        self.now = now;
    }

    fn finish_init(&mut self, reply: Option<ReplyTo>, at: u64) {
        self.init = Init::Idle;
        self.pan.place(0);
        self.tilt.place(0);
        self.initialized = true;
        self.errors.pan &= !(ERROR_INIT | ERROR_CENTER);
        self.errors.tilt &= !(ERROR_INIT | ERROR_CENTER);
        if let Some(reply_to) = reply {
            self.finished.push(DeferredResult {
                reply_to,
                results: InitResults {
                    pan_ccw: INIT_GOOD,
                    pan_cw: INIT_GOOD,
                    tilt_ccw: INIT_GOOD,
                    tilt_cw: INIT_GOOD,
                },
                at,
            });
        }
    }

    /// `HA`/`HS` during `IX`: the sequence fails, motors off (1.5.9), and the
    /// result reports no switch found.
    fn abort_init(&mut self) {
        if let Init::Running { reply, .. } = self.init {
            self.init = Init::Idle;
            self.initialized = false;
            self.errors.pan |= ERROR_INIT | ERROR_CENTER;
            self.errors.tilt |= ERROR_INIT | ERROR_CENTER;
            if let Some(reply_to) = reply {
                self.finished.push(DeferredResult {
                    reply_to,
                    results: InitResults::default(),
                    at: self.now,
                });
            }
        }
    }

    fn initializing(&self) -> bool {
        matches!(self.init, Init::Running { .. })
    }

    fn drive(&mut self, axis: AxisName) -> &mut Drive {
        match axis {
            AxisName::Pan => &mut self.pan_drive,
            AxisName::Tilt => &mut self.tilt_drive,
        }
    }

    /// Proportional speed `SPn`/`STn` (Table 11): n = 0 slowest, F = `max_rate`.
    fn proportional_rate(&self, speed: u8) -> u16 {
        (u32::from(self.config.max_rate) * (u32::from(speed) + 1) / 16).max(1) as u16
    }

    /// Starts a move of both axes; with vector mode on (Table 11 `VMn`) the
    /// faster axis is slowed so both arrive together.
    fn move_to(&mut self, target: Position) {
        self.motors_on = true;
        let (pr, pa) = (f64::from(self.pan_drive.rate), f64::from(self.pan_drive.accel));
        let (tr, ta) = (f64::from(self.tilt_drive.rate), f64::from(self.tilt_drive.accel));
        let (mut pk, mut tk) = (1.0, 1.0);
        if self.vector {
            let tp = Axis::move_time(self.pan.distance_to(target.pan.0), pr, pa);
            let tt = Axis::move_time(self.tilt.distance_to(target.tilt.0), tr, ta);
            let total = tp.max(tt);
            if total > 0.0 {
                // Scaling rate by k and acceleration by k^2 stretches a trapezoid's time by 1/k.
                pk = tp / total;
                tk = tt / total;
            }
        }
        self.pan.go_to(target.pan.0, pr * pk, pa * pk * pk);
        self.tilt.go_to(target.tilt.0, tr * tk, ta * tk * tk);
    }

    fn slew(&mut self, axis: AxisName, dir: f64) {
        self.motors_on = true;
        let d = *self.drive(axis);
        let (rate, accel) = (f64::from(d.rate), f64::from(d.accel));
        match axis {
            AxisName::Pan => self.pan.slew(dir, rate, accel),
            AxisName::Tilt => self.tilt.slew(dir, rate, accel),
        }
    }

    fn stop_axis(&mut self, axis: AxisName) {
        let accel = f64::from(self.drive(axis).accel);
        match axis {
            AxisName::Pan => self.pan.stop(accel),
            AxisName::Tilt => self.tilt.stop(accel),
        }
    }

    /// `HA` / `HS`: stop dead, motors off.
    fn motors_off(&mut self) {
        self.abort_init();
        self.pan.halt();
        self.tilt.halt();
        self.zoom.stop();
        self.focus.stop();
        self.motors_on = false;
    }

    /// Applies Table 10 limits: a count of `limit_unit` hundredths of a
    /// degree from the centre, counter-clockwise positive.
    fn apply_limits(&mut self, limits: Limits) {
        self.limits = limits;
        let unit = f64::from(self.config.limit_unit);
        self.pan.set_soft_limits(
            -f64::from(limits.pan_cw.get()) * unit,
            f64::from(limits.pan_ccw.get()) * unit,
        );
        self.tilt.set_soft_limits(
            -f64::from(limits.tilt_cw.get()) * unit,
            f64::from(limits.tilt_ccw.get()) * unit,
        );
        // A position outside the new travel is pulled in at the next step.
        self.pan.step();
        self.tilt.step();
    }

    fn clear_limits(&mut self) {
        let no_limit = u12(NO_LIMIT);
        self.limits = Limits {
            pan_ccw: no_limit,
            pan_cw: no_limit,
            tilt_ccw: no_limit,
            tilt_cw: no_limit,
        };
        self.pan.clear_soft_limits();
        self.tilt.clear_soft_limits();
    }

    /// Table 5.
    fn awake_status(&self) -> u8 {
        let mut bits = 0;
        if !self.initialized {
            bits |= AwakeStatus::PAN_NOT_INITIALIZED | AwakeStatus::TILT_NOT_INITIALIZED;
        }
        if !self.motors_on {
            bits |= AwakeStatus::MOTORS_OFF;
        }
        if self.errors.pan != 0 || self.errors.tilt != 0 {
            bits |= AwakeStatus::ERROR;
        }
        bits
    }

    /// Table 6B, one axis.
    fn status_bits(&self, axis: &Axis, errors: u8) -> u16 {
        let mut bits = 0u16;
        if self.initialized {
            // Limits and centre found from both sides by the initialisation.
            bits |= StatusBits::POSITIVE_LIMIT_FOUND
                | StatusBits::NEGATIVE_LIMIT_FOUND
                | StatusBits::POSITIVE_CENTER_FOUND
                | StatusBits::NEGATIVE_CENTER_FOUND;
        } else {
            bits |= StatusBits::NOT_INITIALIZED;
        }
        match axis.hard_stop() {
            Some(HardStop::Positive) => bits |= StatusBits::POSITIVE_HARD_STOP,
            Some(HardStop::Negative) => bits |= StatusBits::NEGATIVE_HARD_STOP,
            None => {}
        }
        if errors != 0 {
            bits |= StatusBits::ERROR_PRESENT;
        }
        bits
    }

    /// Table 14.
    fn home_status(&self) -> HomeStatus {
        let found = if self.initialized { 0b11 } else { 0 };
        let on_center = |a: &Axis| a.position().abs() <= CENTER_SWITCH;
        let count = if self.initialized {
            u8::from(on_center(&self.pan)) | (u8::from(on_center(&self.tilt)) << 1)
        } else {
            0
        };
        HomeStatus {
            limit_switches: found,
            center_switches: found,
            count_correct: count,
        }
    }

    fn preset_index(&self, n: u8) -> Option<usize> {
        let i = usize::from(n);
        (i < self.presets.len()).then_some(i)
    }

    fn raw(&mut self, bytes: &[u8]) -> Response<'_> {
        self.scratch.clear();
        self.scratch.extend_from_slice(bytes);
        Response::Reply(Reply::Raw(&self.scratch))
    }
}

impl DeviceHandler for Gimbal {
    fn handle(&mut self, command: Command<'_>, reply_to: ReplyTo, now: u64) -> Response<'_> {
        self.advance_to(now);
        self.execute(command, reply_to)
    }
}
