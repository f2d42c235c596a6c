//! What every gimbal component says on its own: HEARTBEAT (1 Hz, type
//! gimbal), GIMBAL_MANAGER_STATUS (5 Hz, with the control owners) and
//! GIMBAL_DEVICE_ATTITUDE_STATUS (at the configured rate, from the last
//! `P?`, as a quaternion in MAVLink's frame: see `frames`). At each
//! manager status it also ends the control of an owner silent for
//! `control_lapse_ms` (so the status shows who holds control now) and writes
//! the summaries of the throttled warnings.

use std::sync::Arc;
use std::time::Duration;

use mavlink::dialects::common::{
    GIMBAL_DEVICE_ATTITUDE_STATUS_DATA, GIMBAL_MANAGER_STATUS_DATA, GimbalDeviceErrorFlags, GimbalDeviceFlags,
    GimbalManagerFlags, HEARTBEAT_DATA, MavAutopilot, MavMessage, MavModeFlag, MavState, MavType,
};
use tokio::time::MissedTickBehavior;
use tracing::info;

use crate::control::Sender;
use crate::frames;
use crate::gimbal::Handle;
use crate::link::Outbox;
use crate::stats;

pub const HEARTBEAT: Duration = Duration::from_secs(1);
pub const MANAGER_STATUS: Duration = Duration::from_millis(200);

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

fn manager_status(h: &Handle, time_boot_ms: u32) -> MavMessage {
    let control = h.shared().control;
    let (ps, pc) = control.primary.unwrap_or((0, 0));
    let (ss, sc) = control.secondary.unwrap_or((0, 0));
    MavMessage::GIMBAL_MANAGER_STATUS(GIMBAL_MANAGER_STATUS_DATA {
        time_boot_ms,
        flags: GimbalManagerFlags::GIMBAL_MANAGER_FLAGS_YAW_IN_VEHICLE_FRAME,
        gimbal_device_id: h.config.component_id,
        primary_control_sysid: ps,
        primary_control_compid: pc,
        secondary_control_sysid: ss,
        secondary_control_compid: sc,
    })
}

/// The attitude status of the last `P?`; for a gimbal that never answered
/// one, an unknown attitude (a NaN quaternion) with COMMS_ERROR, once a
/// poll found it silent; nothing before its first poll.
pub fn attitude_status(h: &Handle, time_boot_ms: u32) -> Option<MavMessage> {
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
            delta_yaw: f32::NAN,
            delta_yaw_velocity: f32::NAN,
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
        info!(gimbal = %h.config.name, ?owner, lapse_ms = after.as_millis() as u64, "control lapsed: its owner was not heard");
    }
}

/// Sends the three streams for ever.
/// `lapse`: a control owner not heard for this long loses control.
pub async fn run(outbox: Arc<Outbox>, handles: Vec<Handle>, attitude: Duration, lapse_after: Duration) {
    outbox.net.set_components(handles.iter().map(|h| h.config.component_id));
    let tick = |d| {
        let mut i = tokio::time::interval(d);
        i.set_missed_tick_behavior(MissedTickBehavior::Delay);
        i
    };
    let (mut hb, mut ms, mut at) = (tick(HEARTBEAT), tick(MANAGER_STATUS), tick(attitude));
    loop {
        tokio::select! {
            _ = hb.tick() => for h in &handles {
                outbox.send(h.config.component_id, &heartbeat()).await;
            },
            _ = ms.tick() => {
                stats::flush_warnings();
                for h in &handles {
                    lapse(h, lapse_after, |who| outbox.net.heard_within(who, lapse_after));
                    outbox.send(h.config.component_id, &manager_status(h, outbox.boot_ms())).await;
                }
            },
            _ = at.tick() => for h in &handles {
                if let Some(m) = attitude_status(h, outbox.boot_ms()) {
                    outbox.send(h.config.component_id, &m).await;
                }
            },
        }
    }
}
