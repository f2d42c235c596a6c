//! What a simulated gimbal does with each command: the guards (motion
//! refused while `IX` runs, lens commands while the camera is off), then
//! one function per table (4, 11, 16 with the auxiliary ports), and the
//! rev 1.9 list (1.2, protocol-notes E13).

use sagebrush_protocol::{
    Acceleration, AuxReadLen, AwakeStatus, Axis as AxisName, Command, Extended, Identity, Position, Rate, RateGains,
    Reply, ReplyTo, Response, StatusBits,
};

use super::{Gimbal, Init};

impl Gimbal {
    /// Commands that move the mount are refused while `IX` runs.
    fn moves_mount(command: &Command<'_>) -> bool {
        use Command as C;
        matches!(
            command,
            C::GoTo(_)
                | C::GoToPreset(_)
                | C::Home
                | C::PanLeft
                | C::PanRight
                | C::TiltUp
                | C::TiltDown
                | C::Extended(Extended::GoToHaltPosition, _)
        )
    }

    /// Commands that need camera and lens power (`CN`).
    fn needs_lens_power(command: &Command<'_>) -> bool {
        use Command as C;
        matches!(
            command,
            C::FocusSpeed(_)
                | C::FocusFar
                | C::FocusNear
                | C::FocusStop
                | C::ZoomSpeed(_)
                | C::ZoomIn
                | C::ZoomOut
                | C::ZoomStop
                | C::LensGoTo(_)
                | C::Extended(Extended::LensGoToHaltPosition, _)
        )
    }

    /// A command after the guards of `IX` (motion refused) and of the
    /// camera's power (lens commands refused), by its table: Table 4
    /// ([`Gimbal::device_command`]), Table 11 ([`Gimbal::motion_command`]),
    /// Table 16 and the auxiliary ports ([`Gimbal::lens_command`]); the
    /// results that borrow the gimbal's bytes (`D?`, `*xprnnn`, the rev 1.9
    /// list) each have their own function.
    pub(super) fn execute(&mut self, command: Command<'_>, reply_to: ReplyTo) -> Response<'_> {
        if self.initializing() && Self::moves_mount(&command) {
            return Response::Nic;
        }
        if !self.camera_on && Self::needs_lens_power(&command) {
            return Response::Nic;
        }
        use Command as C;
        match command {
            // The results that borrow the gimbal's own bytes.
            C::Identify => self.identify(),
            C::AuxReceive(port, n) => self.aux_receive(usize::from(port.get()), n),
            C::Extended(ext, args) => self.extended(ext, args),
            other => self
                .device_command(other, reply_to)
                .or_else(|other| self.motion_command(other))
                .unwrap_or_else(|other| self.lens_command(other)),
        }
    }

    /// `D?` (Table 4): the unit's identity.
    fn identify(&self) -> Response<'_> {
        match Identity::new(
            self.device,
            self.config.revision,
            self.config.name.as_bytes(),
            self.config.serial.as_bytes(),
        ) {
            Ok(id) => Response::Reply(Reply::Identity(id)),
            Err(_) => Response::Nic,
        }
    }

    /// Table 4: device settings and queries, relays, limits, `IX`; any
    /// other command is handed back.
    fn device_command<'c>(
        &mut self,
        command: Command<'c>,
        reply_to: ReplyTo,
    ) -> Result<Response<'static>, Command<'c>> {
        use Command as C;
        Ok(match command {
            // Table 4.
            C::SetDeviceId(id) => {
                self.device = id.get();
                Response::Done
            }
            C::AwakeStatus => match AwakeStatus::new(self.awake_status()) {
                Ok(status) => Response::Reply(Reply::AwakeStatus(status)),
                Err(_) => Response::Nic,
            },
            C::QueryMaxDataRate => Response::Reply(Reply::MaxDataRate(self.config.max_data_rate)),
            C::SetDataRate(rate) => {
                let max = self.config.max_data_rate.bits_per_second().unwrap_or(0);
                match rate.bits_per_second() {
                    Some(bps) if bps <= max => {
                        self.data_rate = rate;
                        self.pending_rate = Some(rate);
                        Response::Done
                    }
                    // Reserved codes and rates above the unit's maximum.
                    _ => Response::Nic,
                }
            }
            C::QueryErrors => Response::Reply(Reply::Errors(self.errors)),
            C::QueryStatusBits => Response::Reply(Reply::StatusBits(StatusBits {
                pan: self.status_bits(&self.pan, self.errors.pan),
                tilt: self.status_bits(&self.tilt, self.errors.tilt),
            })),
            C::SetRateGain(axis, gain) => {
                self.drive(axis).gain = gain;
                Response::Done
            }
            C::QueryRateGains => Response::Reply(Reply::RateGains(RateGains {
                pan: self.pan_drive.gain,
                tilt: self.tilt_drive.gain,
            })),
            C::Initialize => {
                if self.initializing() {
                    return Ok(Response::Nic);
                }
                self.motors_on = true;
                self.initialized = false;
                let (rate, accel) = (f64::from(self.config.max_rate), f64::from(self.pan_drive.accel));
                self.pan.go_to(0, rate, accel);
                self.tilt.go_to(0, rate, accel);
                self.init = Init::Running {
                    until: self.now + self.config.init_ms,
                    // A broadcast on a shared bus is not answered: no result is owed.
                    reply: reply_to.answered.then_some(reply_to),
                };
                Response::Deferred
            }
            C::OpenRelay(r) => {
                self.relays &= !(1 << r.get());
                Response::Done
            }
            C::CloseRelay(r) => {
                self.relays |= 1 << r.get();
                Response::Done
            }
            C::QueryRelays => Response::Reply(Reply::Relays(self.relays)),
            C::ClearLimits => {
                self.clear_limits();
                Response::Done
            }
            C::SetLimits(limits) => {
                self.apply_limits(limits);
                Response::Done
            }
            C::QueryLimits => Response::Reply(Reply::Limits(self.limits)),
            other => return Err(other),
        })
    }

    /// Table 11: rates, speeds, accelerations, positioning and slews; any
    /// other command is handed back.
    fn motion_command<'c>(&mut self, command: Command<'c>) -> Result<Response<'static>, Command<'c>> {
        use Command as C;
        Ok(match command {
            // Table 11.
            C::SetAcceleration(axis, a) => {
                self.drive(axis).accel = a.0.max(1);
                Response::Done
            }
            C::QueryAccelerations => Response::Reply(Reply::Accelerations {
                pan: Acceleration(self.pan_drive.accel),
                tilt: Acceleration(self.tilt_drive.accel),
            }),
            C::QueryAcceleration(axis) => Response::Reply(Reply::Acceleration(Acceleration(self.drive(axis).accel))),
            C::Halt => {
                self.halt_position = Some(self.position());
                self.halt_lens = Some(self.lens());
                self.motors_off();
                Response::Done
            }
            C::MotorsStop => {
                self.motors_off();
                Response::Done
            }
            C::VerifyHome => Response::Reply(Reply::VerifyHome(self.home_status())),
            C::Home => {
                self.move_to(Position::default());
                Response::Done
            }
            C::QueryPosition => Response::Reply(Reply::Position(self.position())),
            C::GoTo(p) => {
                self.move_to(p);
                Response::Done
            }
            C::PanLeft => {
                self.slew(AxisName::Pan, -1.0);
                Response::Done
            }
            C::PanRight => {
                self.slew(AxisName::Pan, 1.0);
                Response::Done
            }
            C::PanStop => {
                self.stop_axis(AxisName::Pan);
                Response::Done
            }
            C::TiltDown => {
                self.slew(AxisName::Tilt, -1.0);
                Response::Done
            }
            C::TiltUp => {
                self.slew(AxisName::Tilt, 1.0);
                Response::Done
            }
            C::TiltStop => {
                self.stop_axis(AxisName::Tilt);
                Response::Done
            }
            C::StopMotion => {
                self.stop_axis(AxisName::Pan);
                self.stop_axis(AxisName::Tilt);
                Response::Done
            }
            C::GoToPreset(n) => match self.preset_index(n).and_then(|i| self.presets[i]) {
                Some(target) => {
                    self.move_to(target);
                    Response::Done
                }
                None => Response::Nic,
            },
            C::QueryPreset(n) | C::QueryStoredPreset(n) => match self.preset_index(n).and_then(|i| self.presets[i]) {
                Some(place) => Response::Reply(Reply::Position(place)),
                None => Response::Nic,
            },
            C::StorePreset(n) => match self.preset_index(n) {
                Some(i) => {
                    self.presets[i] = Some(self.position());
                    Response::Done
                }
                None => Response::Nic,
            },
            C::SetRate(axis, r) => {
                let max = self.config.max_rate;
                self.drive(axis).rate = r.0.clamp(1, max);
                Response::Done
            }
            C::QueryRates => Response::Reply(Reply::Rates {
                pan: Rate(self.pan_drive.rate),
                tilt: Rate(self.tilt_drive.rate),
            }),
            C::QueryRate(axis) => Response::Reply(Reply::Rate(Rate(self.drive(axis).rate))),
            C::SetSpeed(axis, speed) => {
                let rate = self.proportional_rate(speed.get());
                self.drive(axis).rate = rate;
                Response::Done
            }
            C::SetVectorMode(on) => {
                self.vector = on;
                Response::Done
            }
            other => return Err(other),
        })
    }

    /// Table 16 (camera, focus, zoom, lens) and the auxiliary ports but
    /// `*xprnnn`; what no table has is NIC.
    fn lens_command(&mut self, command: Command<'_>) -> Response<'static> {
        use Command as C;
        match command {
            // Table 16.
            C::CameraOn => {
                self.camera_on = true;
                Response::Done
            }
            C::CameraOff => {
                self.camera_on = false;
                self.zoom.stop();
                self.focus.stop();
                Response::Done
            }
            C::FocusSpeed(s) => {
                self.focus.set_speed(s.get());
                Response::Done
            }
            C::ZoomSpeed(s) => {
                self.zoom.set_speed(s.get());
                Response::Done
            }
            C::FocusFar => {
                self.focus.run(1.0);
                Response::Done
            }
            C::FocusNear => {
                self.focus.run(-1.0);
                Response::Done
            }
            C::FocusStop => {
                self.focus.stop();
                Response::Done
            }
            C::ZoomIn => {
                self.zoom.run(1.0);
                Response::Done
            }
            C::ZoomOut => {
                self.zoom.run(-1.0);
                Response::Done
            }
            C::ZoomStop => {
                self.zoom.stop();
                Response::Done
            }
            C::LensGoTo(lens) => {
                self.zoom.go_to(lens.zoom.get());
                self.focus.go_to(lens.focus.get());
                Response::Done
            }
            C::QueryLens => Response::Reply(Reply::Lens(self.lens())),
            // "Not Implemented" in Table 16.
            C::AutoFocusOn | C::AutoFocusOff | C::DigitalZoom(_) => Response::Nic,
            C::AuxConfigure(port, config) => {
                self.aux[usize::from(port.get())].configure(config);
                Response::Done
            }
            C::AuxTransmit(port, data) => {
                self.aux[usize::from(port.get())].transmit(data.bytes());
                Response::Done
            }
            C::AuxCount(port) => {
                let n = self.aux[usize::from(port.get())].available();
                Response::Reply(Reply::AuxCount(n.min(usize::from(u16::MAX)) as u16))
            }
            C::AuxFlush(port) => {
                self.aux[usize::from(port.get())].flush();
                Response::Done
            }
            // Unknown, and what was handled before this (Tables 4 and 11,
            // the results that borrow).
            _ => Response::Nic,
        }
    }

    /// `*xprnnn`: a result carries 1..=256 bytes, so an empty buffer has no
    /// result to give: NIC ("non-applicable", 1.4.2).
    fn aux_receive(&mut self, port: usize, n: AuxReadLen) -> Response<'_> {
        let data = self.aux[port].receive(usize::from(n.get()));
        if data.is_empty() {
            return Response::Nic;
        }
        self.scratch = data;
        Response::Reply(Reply::AuxData(&self.scratch))
    }

    /// The rev 1.9 commands (1.2, protocol-notes E13).
    fn extended(&mut self, ext: Extended, args: &[u8]) -> Response<'_> {
        if !args.is_empty() {
            return Response::Nic;
        }
        match ext {
            // HP: go to the position saved by HA; nothing saved -> NIC.
            Extended::GoToHaltPosition => match self.halt_position {
                Some(p) => {
                    self.move_to(p);
                    Response::Done
                }
                None => Response::Nic,
            },
            // VP: lens to the position saved by HA.
            Extended::LensGoToHaltPosition => match self.halt_lens {
                Some(l) => {
                    self.zoom.go_to(l.zoom.get());
                    self.focus.go_to(l.focus.get());
                    Response::Done
                }
                None => Response::Nic,
            },
            // VS: the simulator's layout: `C` + power digit, `L` + relay digit (Table 4A style).
            Extended::CameraRelayStatus => {
                let status = [b'C', b'0' + u8::from(self.camera_on), b'L', hex_digit(self.relays)];
                self.raw(&status)
            }
            Extended::FocusSpeedQuery => {
                let digit = [b'0' + self.focus.speed()];
                self.raw(&digit)
            }
            Extended::ZoomSpeedQuery => {
                let digit = [b'0' + self.zoom.speed()];
                self.raw(&digit)
            }
            // No published layout, and servo internals the simulator does not model.
            Extended::LensLimitsQuery
            | Extended::AnalogInputs
            | Extended::DigitalInputs
            | Extended::DigitalOutputs
            | Extended::StatusMessages
            | Extended::LoopMode
            | Extended::RateCommand
            | Extended::EncoderPosition
            | Extended::FloatPosition
            | Extended::UserParameters
            | Extended::InertialGain
            | Extended::RateGainFloat
            | Extended::PositionGainFloat
            | Extended::RateLimits => Response::Nic,
        }
    }
}

pub(super) fn hex_digit(v: u8) -> u8 {
    b"0123456789ABCDEF"[usize::from(v & 0x0F)]
}
