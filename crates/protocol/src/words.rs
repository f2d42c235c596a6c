//! Commands, positions and delivery reports in words, for people: what a
//! log line or an error message says a command does, its arguments in their
//! units (degrees, degrees a second, preset numbers) read from the command
//! table's typed fields, and the rows without arguments in the words of
//! their description (the spec table's, [`Command::description`]). Never a
//! payload an operator must decode (`P2CEC0000`), never a Rust `Debug` form.

use core::fmt;

use crate::command::Command;
use crate::mount::MountEffect;
use crate::report::DeliveryReport;
use crate::units::{Angle, Axis, Position};

impl fmt::Display for Angle {
    /// Degrees with two decimals and the degree sign: `-10.50°` (Table 15's
    /// hundredths, written exactly, without rounding through a float).
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let centi = i32::from(self.0);
        let sign = if centi < 0 { "-" } else { "" };
        let abs = centi.unsigned_abs();
        write!(f, "{sign}{}.{:02}°", abs / 100, abs % 100)
    }
}

impl fmt::Display for Position {
    /// `pan 45.00° tilt -10.00°`.
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "pan {} tilt {}", self.pan, self.tilt)
    }
}

impl fmt::Display for Axis {
    /// `pan` or `tilt`.
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.pick("pan", "tilt"))
    }
}

/// A command in words ([`Command::in_words`]).
#[derive(Clone, Copy, Debug)]
pub struct InWords<'c, 'a>(&'c Command<'a>);

impl<'a> Command<'a> {
    /// What the command does, in words with its arguments in their units:
    /// `go to pan 115.00° tilt 0.00°`, `pan speed 7 of 15`, `stop motion`.
    pub fn in_words(&self) -> InWords<'_, 'a> {
        InWords(self)
    }
}

impl fmt::Display for InWords<'_, '_> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        use Command as C;
        match *self.0 {
            C::GoTo(p) => write!(f, "go to {p}"),
            C::Home => write!(f, "go home ({})", Position::ZERO),
            C::GoToPreset(n) => write!(f, "go to preset {n}"),
            C::StorePreset(n) => write!(f, "store the position as preset {n}"),
            C::QueryPreset(n) | C::QueryStoredPreset(n) => write!(f, "read the position of preset {n}"),
            C::SetSpeed(axis, s) => write!(f, "{axis} speed {} of 15", s.get()),
            C::SetRate(axis, r) => write!(f, "{axis} rate {:.2}°/s", r.degrees_per_second()),
            C::QueryRate(axis) => write!(f, "read the {axis} rate"),
            C::SetAcceleration(axis, a) => write!(f, "{axis} acceleration {:.2}°/s²", a.degrees_per_second_squared()),
            C::QueryAcceleration(axis) => write!(f, "read the {axis} acceleration"),
            C::SetRateGain(axis, g) => write!(f, "{axis} rate gain {}.{}", g.get() / 10, g.get() % 10),
            C::SetLimits(l) => write!(
                f,
                "set software limits (Table 10: pan {}..{}, tilt {}..{})",
                l.pan_cw.get(),
                l.pan_ccw.get(),
                l.tilt_cw.get(),
                l.tilt_ccw.get()
            ),
            C::LensGoTo(l) => write!(f, "lens to zoom {} focus {}", l.zoom.get(), l.focus.get()),
            C::FocusSpeed(s) => write!(f, "focus speed {} of 9", s.get()),
            C::ZoomSpeed(s) => write!(f, "zoom speed {} of 9", s.get()),
            C::DigitalZoom(z) => write!(f, "digital zoom step {:X}", z.get()),
            C::SetDeviceId(id) => write!(f, "set the device address to {}", id.get()),
            C::SetDataRate(r) => match r.bits_per_second() {
                Some(bps) => write!(f, "switch the line to {bps} bit/s"),
                None => write!(f, "switch the line to reserved rate C{:X}", r.code()),
            },
            C::OpenRelay(r) => write!(f, "open relay {}", r.get()),
            C::CloseRelay(r) => write!(f, "close relay {}", r.get()),
            C::SetVectorMode(on) => write!(f, "vector motion {}", if on { "on" } else { "off" }),
            C::AuxConfigure(p, c) => write!(
                f,
                "configure auxiliary port {} ({} bit/s, {} data bits, {} stop bits)",
                p.get(),
                c.baud(),
                c.data_bits(),
                c.stop_bits()
            ),
            C::AuxTransmit(p, data) => write!(f, "send {} byte(s) on auxiliary port {}", data.bytes().len(), p.get()),
            C::AuxReceive(p, n) => write!(f, "read up to {} byte(s) from auxiliary port {}", n.get(), p.get()),
            C::AuxCount(p) => write!(f, "count the bytes waiting on auxiliary port {}", p.get()),
            C::AuxFlush(p) => write!(f, "flush auxiliary port {}", p.get()),
            C::Extended(ext, args) => {
                plain(f, ext.description())?;
                match args.len() {
                    0 => Ok(()),
                    n => write!(f, " ({n} byte(s) of arguments)"),
                }
            }
            C::Unknown(bytes) => write!(f, "a command no row of the protocol takes ({} byte(s))", bytes.len()),
            // The rows without arguments: their description says it.
            ref other => {
                if matches!(other.mount(), MountEffect::Reads(_)) {
                    f.write_str("read ")?;
                }
                plain(f, other.description())
            }
        }
    }
}

/// A row's description as plain words: without its `` `XY`: `` name, the
/// table it comes from and the backticks (`` `PL`: pan left (CW) until `PS`
/// (Table 11). `` becomes `pan left (CW) until PS`).
fn plain(f: &mut fmt::Formatter<'_>, description: &str) -> fmt::Result {
    let text = match description.strip_prefix('`').and_then(|t| t.split_once("`: ")) {
        Some((_, rest)) => rest,
        None => description,
    };
    let text = text.split(" (Table").next().unwrap_or(text);
    let text = text.split(". ").next().unwrap_or(text).trim_end_matches('.');
    for part in text.split('`') {
        f.write_str(part)?;
    }
    Ok(())
}

impl fmt::Display for DeliveryReport {
    /// `delivered to 5.2.1`, or `not delivered to 5.2.1 (at GCU 5):
    /// another link of equal or higher priority controls the gimbal`.
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self.failure {
            None => write!(f, "delivered to {} (reported by GCU {})", self.dest, self.at_group),
            Some(failure) if failure.is_refusal() => write!(
                f,
                "refused by GCU {} for {}: {}",
                self.at_group,
                self.dest,
                failure.describe()
            ),
            Some(failure) => write!(
                f,
                "not delivered to {} (reported by GCU {}): {}",
                self.dest,
                self.at_group,
                failure.describe()
            ),
        }
    }
}

#[cfg(test)]
mod tests {
    extern crate std;
    use std::string::{String, ToString};

    use super::*;
    use crate::units::{Rate, Speed};
    use crate::{Address, Undelivered};

    fn words(c: &Command<'_>) -> String {
        c.in_words().to_string()
    }

    #[test]
    fn arguments_in_their_units() {
        let goto = Command::parse_strict(b"P2CEC0000").expect("goto");
        assert_eq!(words(&goto), "go to pan 115.00° tilt 0.00°");
        let back = Command::GoTo(Position::new(Angle(-1050), Angle(5)));
        assert_eq!(words(&back), "go to pan -10.50° tilt 0.05°");
        assert_eq!(words(&Command::Home), "go home (pan 0.00° tilt 0.00°)");
        let speed = Command::SetSpeed(Axis::Pan, Speed::new(7).expect("speed"));
        assert_eq!(words(&speed), "pan speed 7 of 15");
        assert_eq!(words(&Command::SetRate(Axis::Tilt, Rate(1250))), "tilt rate 12.50°/s");
        assert_eq!(words(&Command::GoToPreset(3)), "go to preset 3");
    }

    #[test]
    fn rows_without_arguments_in_their_descriptions_words() {
        assert_eq!(words(&Command::PanLeft), "pan left (CW) until PS");
        assert_eq!(words(&Command::StopMotion), "stop motion");
        assert_eq!(words(&Command::QueryPosition), "read current position");
        assert_eq!(words(&Command::MotorsStop), "stop, motors off");
        let hp = Command::parse_strict(b"HP").expect("HP");
        assert_eq!(words(&hp), "go to the gimbal position saved by HA");
        for (_, row) in Command::FIXED {
            let text = words(row);
            assert!(
                !text.is_empty() && !text.contains('`') && !text.contains("Table"),
                "{text}"
            );
        }
    }

    #[test]
    fn delivery_reports_in_words() {
        let report = DeliveryReport {
            failure: Some(Undelivered::NotInControl),
            dest: Address::new(5, 2, 1),
            command_checksum: 0xE5,
            at_group: 5,
        };
        assert_eq!(
            report.to_string(),
            "refused by GCU 5 for 5.2.1: another link of equal or higher priority controls the gimbal"
        );
        let silent = DeliveryReport {
            failure: Some(Undelivered::DeviceSilent),
            ..report
        };
        assert_eq!(
            silent.to_string(),
            "not delivered to 5.2.1 (reported by GCU 5): the device did not acknowledge it (silent after all retries)"
        );
        assert_eq!(Angle(-5).to_string(), "-0.05°");
    }
}
