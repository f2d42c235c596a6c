//! What an exchange teaches about its device (ARCHITECTURE "Device registry
//! and status"; spec Tables 15 and 17) and the rate changes it makes
//! ("Routing semantics").
//!
//! - The registry holds, per device, whether it answers, its last error and
//!   the position or lens position it answered to `P?` or `V?`. A NIC to
//!   gcud's own query (a preset it asks for) is no error of the device's.
//! - A `C0`..`C7` rate change acknowledged by every device of the port
//!   (configured list, or the devices that answered since the port opened),
//!   or broadcast to device 255, switches the port's own line rate.
//!   Reserved rates `C8`..`CF` never do (protocol-notes E15).

use sagebrush_protocol::{DataRate, FrameBuf, Outcome, Reply, TxFailure, WILDCARD};

use crate::stats::{DeviceError, DeviceStats};
use crate::types::{Origin, RouterEvent};

use super::{Job, Port, PortOut};

impl Port {
    /// The registry's entry of `device`, made on first use; none for the
    /// wildcard (a broadcast), which is no device (gcud's /status would
    /// list it as an offline gimbal).
    pub(super) fn device(&mut self, device: u8) -> Option<&mut DeviceStats> {
        (device != WILDCARD).then(|| self.device_stats.entry(device).or_default())
    }

    /// A change of `device`'s answering (the registry's `online`) since
    /// `before` (online, answered since the port opened), as one
    /// [`RouterEvent::DeviceState`].
    pub(super) fn tell_device_state(&self, device: u8, before: (bool, bool), out: &mut Vec<PortOut>) {
        let online = self.device_stats.get(&device).is_some_and(|d| d.online);
        let (was_online, answered_before) = before;
        if online != was_online {
            out.push(PortOut::Event(RouterEvent::DeviceState {
                port: self.config.id,
                device,
                online,
                first: !answered_before,
            }));
        }
    }

    /// What an exchange tells about its device (the device registry):
    /// whether it answers, its last error, and the position or lens
    /// position it answered to `P?` (Table 15) or `V?` (Table 17).
    pub(super) fn learn(&mut self, now: u64, device: u8, job: &Job, outcome: Outcome, result: Option<&FrameBuf>) {
        self.learn_motion(now, device, job, outcome);
        let Some(d) = self.device(device) else { return };
        let error = match outcome {
            Outcome::Broadcast => return,
            Outcome::Failed(TxFailure::NoAck) => Some(DeviceError::Silent),
            Outcome::Failed(TxFailure::Nak) => Some(DeviceError::Nak),
            Outcome::NoResult => Some(DeviceError::NoResult),
            // A NIC to gcud's own query (the presets it asks for a park
            // or a tour) says the device lacks that row, not that it
            // failed anyone: never its last error.
            Outcome::Nic if job.origin == Origin::Internal => None,
            Outcome::Nic => Some(DeviceError::Nic),
            Outcome::Result | Outcome::Acknowledged => None,
        };
        d.online = error != Some(DeviceError::Silent);
        if let Some(error) = error {
            d.last_error = Some((now, error));
        }

        let Some(result) = result.filter(|_| job.facts.registry) else {
            return;
        };
        match Reply::parse_expected(&job.facts.reply, result.frame().payload()) {
            Ok(Reply::Position(p)) => {
                d.position = Some((now, p));
                d.moved = None;
            }
            Ok(Reply::Lens(l)) => d.lens = Some((now, l)),
            _ => {}
        }
    }

    /// A motion that went out (acknowledged, or broadcast to device 255,
    /// which moves every device of the port) leaves each position it
    /// reaches stale until the next `P?` answer: the registry says since
    /// when, so that a status never shows a place the gimbal has left as
    /// where it is.
    fn learn_motion(&mut self, now: u64, device: u8, job: &Job, outcome: Outcome) {
        let went_out = matches!(outcome, Outcome::Broadcast | Outcome::Acknowledged | Outcome::Result);
        if !(went_out && job.facts.moves()) {
            return;
        }
        if device == WILDCARD {
            for d in self.device_stats.values_mut() {
                d.moved = Some(now);
            }
        } else if let Some(d) = self.device(device) {
            d.moved = Some(now);
        }
    }

    pub(super) fn rate_acknowledged(&mut self, device: u8, rate: Option<DataRate>, out: &mut Vec<PortOut>) {
        let Some(rate) = rate.filter(|r| r.bits_per_second().is_some()) else {
            return;
        };
        self.acked_rates.insert(device, rate);
        let everyone = match &self.devices {
            Some(list) => list.to_vec(),
            None => self.seen.iter().copied().collect(),
        };
        if !everyone.is_empty() && everyone.iter().all(|d| self.acked_rates.get(d) == Some(&rate)) {
            self.switch_rate(rate, out);
        }
    }

    pub(super) fn switch_rate(&mut self, rate: DataRate, out: &mut Vec<PortOut>) {
        let Some(bps) = rate.bits_per_second() else { return };
        self.acked_rates.clear();
        if self.rate == rate {
            return;
        }
        self.rate = rate;
        self.stats.bps = bps;
        self.stats.rate_switches += 1;
        self.line.reset();
        out.push(PortOut::SetRate(bps));
        out.push(PortOut::Event(RouterEvent::RateSwitched { port: self.id, bps }));
    }
}
