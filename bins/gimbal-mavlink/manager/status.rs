//! What every gimbal component says on its own: HEARTBEAT (1 Hz, type
//! gimbal), GIMBAL_MANAGER_STATUS (5 Hz, with the control owners, or the
//! manager itself while gcud says another link holds the gimbal, which a
//! STATUSTEXT names once when it changes) and
//! GIMBAL_DEVICE_ATTITUDE_STATUS (at the configured rate, from the last
//! `P?`, as a quaternion in MAVLink's frame: see `frames`). The two status
//! streams of each gimbal run at the interval MAV_CMD_SET_MESSAGE_INTERVAL
//! set for it ([`Rate`]; for every asker, as the streams go to every
//! peer), each on its own schedule so that the mean interval is the one
//! asked for. Five times a second it also ends the control of an owner
//! silent for `control_lapse_ms` (so the status shows who holds control
//! now) and writes the summaries of the throttled warnings.

use std::sync::Arc;
use std::time::Duration;

use mavlink::dialects::common::{
    GIMBAL_DEVICE_ATTITUDE_STATUS_DATA, GIMBAL_MANAGER_STATUS_DATA, GimbalDeviceErrorFlags, GimbalDeviceFlags,
    GimbalManagerFlags, HEARTBEAT_DATA, MavAutopilot, MavMessage, MavModeFlag, MavSeverity, MavState, MavType,
};
use sagebrush_client::governance::Controller;
use tokio::time::{Instant, MissedTickBehavior};
use tracing::info;

use crate::earth::frames;
use crate::earth::vehicle::{Heading, Vehicle};
use crate::routing::answers::{holder_text, statustext};
use crate::routing::control::Sender;
use crate::routing::handle::Handle;
use crate::stats;
use crate::transport::link::Outbox;

pub const HEARTBEAT: Duration = Duration::from_secs(1);
pub const MANAGER_STATUS: Duration = Duration::from_millis(200);
/// How late a new rate is noticed at most.
const RECHECK: Duration = Duration::from_millis(50);

fn heartbeat() -> MavMessage {
    MavMessage::HEARTBEAT(HEARTBEAT_DATA {
        custom_mode: 0,
        mavtype: MavType::MAV_TYPE_GIMBAL,
        autopilot: MavAutopilot::MAV_AUTOPILOT_INVALID,
        base_mode: MavModeFlag::empty(),
        system_status: MavState::MAV_STATE_ACTIVE,
        mavlink_version: 3,
    })
}

/// The manager's status: MAVLink's control owners; while gcud says a
/// link other than this door's own (or a tour, or park) holds the gimbal,
/// the manager itself (this door's system id and the gimbal's component
/// id) as primary and nobody as secondary: no MAVLink component commands
/// it then, and a ground station shows "controlled by another".
/// Its flags say the yaw's frame: the earth frame (YAW_LOCK and
/// YAW_IN_EARTH_FRAME) while an earth-frame aim is in force (`aim`), else
/// the vehicle frame.
fn manager_status(h: &Handle, system_id: u8, time_boot_ms: u32) -> MavMessage {
    let shared = h.shared();
    let control = shared.control;
    let ((ps, pc), (ss, sc)) = match shared.held_elsewhere() {
        Some(_) => ((system_id, h.config.component_id), (0, 0)),
        None => (control.primary.unwrap_or((0, 0)), control.secondary.unwrap_or((0, 0))),
    };
    MavMessage::GIMBAL_MANAGER_STATUS(GIMBAL_MANAGER_STATUS_DATA {
        time_boot_ms,
        flags: match shared.aim {
            Some(_) => {
                GimbalManagerFlags::GIMBAL_MANAGER_FLAGS_YAW_LOCK
                    | GimbalManagerFlags::GIMBAL_MANAGER_FLAGS_YAW_IN_EARTH_FRAME
            }
            None => GimbalManagerFlags::GIMBAL_MANAGER_FLAGS_YAW_IN_VEHICLE_FRAME,
        },
        gimbal_device_id: h.config.component_id,
        primary_control_sysid: ps,
        primary_control_compid: pc,
        secondary_control_sysid: ss,
        secondary_control_compid: sc,
    })
}

/// The attitude status of the last `P?`; for a gimbal that never answered
/// one, an unknown attitude (a NaN quaternion) with COMMS_ERROR, once a
/// poll found it silent; nothing before its first poll. The quaternion is
/// always in the vehicle frame (what the gimbal measures); `delta_yaw` and
/// `delta_yaw_velocity` (common.xml: "q_earth = q_delta_yaw * q_vehicle")
/// carry the `heading` when it is known, NaN when not.
pub fn attitude_status(h: &Handle, time_boot_ms: u32, heading: Option<Heading>) -> Option<MavMessage> {
    let shared = h.shared();
    let q = match shared.position {
        Some(p) => {
            let (yaw, pitch) = frames::yaw_pitch_rad(f64::from(p.pan.degrees()), f64::from(p.tilt.degrees()));
            frames::quaternion(pitch, yaw)
        }
        None if shared.unreachable => [f32::NAN; 4],
        None => return None,
    };
    Some(MavMessage::GIMBAL_DEVICE_ATTITUDE_STATUS(
        GIMBAL_DEVICE_ATTITUDE_STATUS_DATA {
            time_boot_ms,
            q,
            angular_velocity_x: f32::NAN,
            angular_velocity_y: f32::NAN,
            angular_velocity_z: f32::NAN,
            failure_flags: if shared.unreachable {
                GimbalDeviceErrorFlags::GIMBAL_DEVICE_ERROR_FLAGS_COMMS_ERROR
            } else {
                GimbalDeviceErrorFlags::empty()
            },
            flags: GimbalDeviceFlags::GIMBAL_DEVICE_FLAGS_YAW_IN_VEHICLE_FRAME,
            target_system: 0,
            target_component: 0,
            delta_yaw: heading.map_or(f32::NAN, |h| h.deg.to_radians() as f32),
            delta_yaw_velocity: heading.map_or(f32::NAN, |h| h.rate_dps.to_radians() as f32),
            gimbal_device_id: 0,
        },
    ))
}

/// Ends the control of each owner of `h` that `heard_within` says was silent.
fn lapse(h: &Handle, after: Duration, heard_within: impl Fn(Sender) -> bool) {
    let lapsed = h
        .shared
        .lock()
        .unwrap_or_else(|p| p.into_inner())
        .control
        .lapse(heard_within);
    for owner in lapsed {
        info!(gimbal = %h.config.name, owner = crate::routing::control::sender_name(owner), lapse_ms = after.as_millis() as u64, "control lapsed: its owner was not heard");
    }
}

/// When a stream of one gimbal is next due.
#[derive(Clone, Copy, Debug)]
struct Schedule {
    /// The last send (its due time, so that the mean interval holds).
    last: Instant,
}

impl Schedule {
    /// Whether it is due at `now` for `interval` (None: off); if so, the
    /// send is booked.
    fn due(&mut self, interval: Option<Duration>, now: Instant) -> bool {
        let Some(interval) = interval else {
            self.last = now;
            return false;
        };
        if now < self.last + interval {
            return false;
        }
        // Behind by more than an interval (a stall): start again from now.
        self.last = if now - (self.last + interval) > interval {
            now
        } else {
            self.last + interval
        };
        true
    }

    fn next(&self, interval: Option<Duration>) -> Option<Instant> {
        interval.map(|i| self.last + i)
    }
}

/// Sends the three streams for ever.
/// `lapse`: a control owner not heard for this long loses control.
pub async fn run(
    outbox: Arc<Outbox>,
    handles: Vec<Handle>,
    vehicle: Arc<Vehicle>,
    attitude: Duration,
    lapse_after: Duration,
) {
    outbox.net.set_components(handles.iter().map(|h| h.config.component_id));
    let tick = |d| {
        let mut i = tokio::time::interval(d);
        i.set_missed_tick_behavior(MissedTickBehavior::Delay);
        i
    };
    let (mut hb, mut housekeeping) = (tick(HEARTBEAT), tick(MANAGER_STATUS));
    let start = Instant::now();
    // Per gimbal: the manager status, then the attitude status.
    let mut schedules = vec![[Schedule { last: start }, Schedule { last: start }]; handles.len()];
    // Per gimbal: the holder elsewhere last told in a STATUSTEXT.
    let mut holders: Vec<Option<Controller>> = vec![None; handles.len()];
    let intervals = |h: &Handle| {
        let rates = h.rates();
        [
            rates.manager.interval(MANAGER_STATUS),
            rates.attitude.interval(attitude),
        ]
    };
    loop {
        let now = Instant::now();
        let wake = handles
            .iter()
            .zip(&schedules)
            .flat_map(|(h, s)| {
                let [m, a] = intervals(h);
                [s[0].next(m), s[1].next(a)]
            })
            .flatten()
            .min()
            .map_or(now + RECHECK, |w| w.min(now + RECHECK));
        tokio::select! {
            _ = hb.tick() => for h in &handles {
                outbox.send(h.config.component_id, &heartbeat()).await;
            },
            _ = housekeeping.tick() => {
                stats::flush_warnings();
                for (h, told) in handles.iter().zip(holders.iter_mut()) {
                    lapse(h, lapse_after, |who| outbox.net.heard_within(who, lapse_after));
                    // A new holder elsewhere in gcud is told once, by name.
                    let now_held = h.shared().held_elsewhere().cloned();
                    if now_held != *told {
                        if let Some(holder) = &now_held {
                            info!(gimbal = %h.config.name, %holder, "gcud says another controls the gimbal");
                            let text = holder_text(holder);
                            let msg = statustext(MavSeverity::MAV_SEVERITY_NOTICE, &text);
                            outbox.broadcast(h.config.component_id, &msg).await;
                        }
                        *told = now_held;
                    }
                }
            },
            _ = tokio::time::sleep_until(wake) => {
                let now = Instant::now();
                for (h, s) in handles.iter().zip(schedules.iter_mut()) {
                    let [m, a] = intervals(h);
                    if s[0].due(m, now) {
                        let status = manager_status(h, outbox.net.system_id, outbox.boot_ms());
                        outbox.send(h.config.component_id, &status).await;
                    }
                    if s[1].due(a, now) {
                        if let Some(msg) = attitude_status(h, outbox.boot_ms(), vehicle.heading(&h.config)) {
                            outbox.send(h.config.component_id, &msg).await;
                        }
                    }
                }
            },
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_schedule_keeps_the_mean_interval_and_restarts_after_a_stall() {
        let t0 = Instant::now();
        let every = Some(Duration::from_millis(100));
        let mut s = Schedule { last: t0 };
        assert!(!s.due(every, t0 + Duration::from_millis(99)));
        // Woken 7 ms late: the next is still due 100 ms after the first's due time.
        assert!(s.due(every, t0 + Duration::from_millis(107)));
        assert_eq!(s.next(every), Some(t0 + Duration::from_millis(200)));
        assert!(s.due(every, t0 + Duration::from_millis(900)), "after a stall");
        assert_eq!(s.next(every), Some(t0 + Duration::from_millis(1000)));
        assert!(!s.due(None, t0 + Duration::from_secs(5)), "off");
    }
}
