//! The task that keeps each gimbal's earth-frame aim (module `aim`) as
//! the vehicle turns or moves: at most every [`REAIM_EVERY`] per gimbal,
//! and only when the pan or tilt changed by `REAIM_STEP` or more.

use std::sync::Arc;

use tracing::{info, warn};

use crate::earth::aim::{REAIM_EVERY, Target, moved};
use crate::earth::vehicle::Vehicle;
use crate::routing::handle::{Handle, Job, Work};
use crate::routing::motion::Request;

/// Re-aims the aims in force for ever (the module's rules).
pub async fn run(handles: Vec<Handle>, vehicle: Arc<Vehicle>) {
    let mut tick = tokio::time::interval(REAIM_EVERY);
    tick.set_missed_tick_behavior(tokio::time::MissedTickBehavior::Delay);
    // Per gimbal: the target last seen and the request last aimed for it.
    let mut last: Vec<Option<(Target, Request)>> = vec![None; handles.len()];
    loop {
        tick.tick().await;
        for (h, last) in handles.iter().zip(last.iter_mut()) {
            let Some(target) = h.aim() else {
                *last = None;
                continue;
            };
            let request = match target.aim.request(&h.config, &vehicle) {
                Ok(r) => r,
                Err(why) => {
                    warn!(gimbal = %h.config.name, aim = %target.aim, why, "earth-frame aim lapsed: the gimbal stays where it points");
                    h.clear_aim(target);
                    *last = None;
                    continue;
                }
            };
            match last {
                // The request that set it aimed there already.
                None => *last = Some((target, request)),
                Some((seen, _)) if *seen != target => *last = Some((target, request)),
                Some((_, aimed)) if !moved(aimed, &request) => {}
                Some(_) => {
                    info!(gimbal = %h.config.name, pan = request.pan_deg, tilt = request.tilt_deg, "re-aimed: the vehicle turned or moved");
                    let job = Job {
                        from: target.from,
                        work: Work::Move {
                            request,
                            ack: None,
                            aim: Some(target.aim),
                        },
                    };
                    if h.jobs.try_send(job).is_ok() {
                        *last = Some((target, request));
                    }
                }
            }
        }
    }
}
