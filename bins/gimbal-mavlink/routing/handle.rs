//! What the door's other parts hand one gimbal's task and read from it
//! (module `gimbal`): the requests ([`Job`], [`Work`]), where a message
//! goes ([`Route`]), and the [`Handle`] with the state the status streams
//! report ([`Shared`]).

use std::sync::{Arc, Mutex};

use mavlink::dialects::common::{MavCmd, MavResult};
use sagebrush_client::connection::Control as GcudControl;
use sagebrush_client::governance::Controller;
use sagebrush_client::session::GimbalSession;
use sagebrush_protocol::Position;
use tokio::sync::mpsc;

use crate::config;
use crate::earth::aim::{Aim, Target};
use crate::routing::control::{Control, Sender};
use crate::routing::motion;
use crate::routing::rates::{self, Rate, Rates};

/// What the emitter reports.
#[derive(Clone, Debug, Default)]
pub struct Shared {
    pub position: Option<Position>,
    /// The last poll failed.
    pub unreachable: bool,
    pub control: Control,
    /// The status streams' rates (MAV_CMD_SET_MESSAGE_INTERVAL).
    pub rates: Rates,
    /// Who gcud says controls the gimbal (`~C`), when it said.
    pub gcud: Option<GcudControl>,
    /// The pointing held in the earth frame (`aim`).
    pub aim: Option<Target>,
}

impl Shared {
    /// The holder of the gimbal in gcud when it is not this door's own link
    /// (another link, a tour, park): MAVLink's control owners then command
    /// nothing, and GIMBAL_MANAGER_STATUS says so.
    pub fn held_elsewhere(&self) -> Option<&Controller> {
        self.gcud
            .as_ref()
            .filter(|c| !c.ours && c.holder != Controller::Nobody)
            .map(|c| &c.holder)
    }
}

/// Where a message goes.
#[derive(Debug)]
pub enum Route {
    /// To gimbal number `usize` (index into the handles).
    Gimbal(usize, Job),
    /// A command for one of our components that no gimbal takes: answer
    /// it with this result.
    Answer(u8, MavCmd, MavResult),
    /// For gimbal number `usize`, but refused for its content (no answer
    /// message exists for it): why.
    Refused(usize, &'static str),
    /// Not for us, or nothing to do.
    Ignore,
}

/// A request for one gimbal.
#[derive(Clone, Debug)]
pub enum Work {
    /// Pitch/yaw (GIMBAL_MANAGER_SET_PITCHYAW, _SET_ATTITUDE, or the
    /// command, which `ack` names).
    Move {
        request: motion::Request,
        ack: Option<MavCmd>,
        /// The earth-frame aim this motion holds (None: any held ends).
        aim: Option<Aim>,
    },
    /// MAV_CMD_DO_GIMBAL_MANAGER_CONFIGURE params 1..4.
    Configure([f32; 4]),
    /// MAV_CMD_REQUEST_MESSAGE for a message id.
    Information(u32),
    /// The program stops: stop the slew in force, then end the task.
    Shutdown,
}

#[derive(Clone, Debug)]
pub struct Job {
    pub from: Sender,
    pub work: Work,
}

/// The handle the receivers use.
#[derive(Debug, Clone)]
pub struct Handle {
    pub config: config::Gimbal,
    /// Who controls the gimbal.
    pub shared: Arc<Mutex<Shared>>,
    pub session: Arc<GimbalSession>,
    pub jobs: mpsc::Sender<Job>,
}

impl Handle {
    /// The control, with the position and reachability the session polled.
    pub fn shared(&self) -> Shared {
        let status = self.session.status();
        let (control, rates, aim) = {
            let shared = self.shared.lock().unwrap_or_else(|p| p.into_inner());
            (shared.control, shared.rates, shared.aim)
        };
        Shared {
            position: status.position,
            unreachable: status.error.is_some(),
            control,
            rates,
            gcud: status.control,
            aim,
        }
    }

    /// The earth-frame aim in force.
    pub fn aim(&self) -> Option<Target> {
        self.shared.lock().unwrap_or_else(|p| p.into_inner()).aim
    }

    /// Ends `target` if it is still the aim in force.
    pub fn clear_aim(&self, target: Target) {
        let aim = &mut self.shared.lock().unwrap_or_else(|p| p.into_inner()).aim;
        if *aim == Some(target) {
            *aim = None;
        }
    }

    /// The status streams' rates.
    pub fn rates(&self) -> Rates {
        self.shared.lock().unwrap_or_else(|p| p.into_inner()).rates
    }

    /// Sets the rate of status message `id` (GIMBAL_MANAGER_STATUS or
    /// GIMBAL_DEVICE_ATTITUDE_STATUS).
    pub fn set_rate(&self, id: u32, rate: Rate) {
        let rates = &mut self.shared.lock().unwrap_or_else(|p| p.into_inner()).rates;
        if id == rates::MANAGER_STATUS_ID {
            rates.manager = rate;
        } else {
            rates.attitude = rate;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn seen(holder: Controller, ours: bool) -> Shared {
        Shared {
            gcud: Some(GcudControl { holder, ours }),
            ..Shared::default()
        }
    }

    #[test]
    fn only_a_holder_other_than_this_doors_link_is_elsewhere() {
        let ops = Controller::Link {
            name: "operators".into(),
            priority: 80,
            via: None,
            yours: false,
        };
        assert_eq!(seen(ops.clone(), false).held_elsewhere(), Some(&ops));
        assert_eq!(seen(ops.clone(), true).held_elsewhere(), None, "this door's own link");
        assert_eq!(seen(Controller::Nobody, false).held_elsewhere(), None);
        assert_eq!(
            seen(Controller::Tour("north".into()), false).held_elsewhere(),
            Some(&Controller::Tour("north".into()))
        );
        assert_eq!(Shared::default().held_elsewhere(), None, "gcud said nothing");
    }
}
