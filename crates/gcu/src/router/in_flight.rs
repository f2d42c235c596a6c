//! What the router keeps about a command in flight, under its id: one
//! record from the command's acceptance until it finished and its origin
//! was told whether it was delivered (ARCHITECTURE "Delivery contract").

use sagebrush_protocol::Undelivered;

use crate::command::ReadCommand;
use crate::types::{CommandOutcome, DropReason, LinkId, Origin};

/// Rounds of a dead-man stop (each with the port's retries) before the
/// router gives up on a device that never acknowledges it.
const DEAD_MAN_ROUNDS: u8 = 5;

/// Progress of one accepted command executed on local ports (one job per
/// port; a port-255 command has one per configured port).
#[derive(Debug)]
pub(super) struct Progress {
    pub(super) remaining: usize,
    pub(super) results: usize,
    pub(super) nics: usize,
    pub(super) completed: usize,
    pub(super) no_result: usize,
    pub(super) unreachable: usize,
    /// Why a result or `?` could not be handed to the origin, or a job was dropped.
    pub(super) dropped: Option<DropReason>,
    /// Why a job's device did not acknowledge it.
    pub(super) failure: Option<Undelivered>,
    /// Ports whose job was neither acknowledged nor ended yet: the origin
    /// is told delivered once none is left and a device acknowledged.
    pub(super) undecided: PortSet,
    /// A device acknowledged one of the jobs.
    pub(super) acknowledged: bool,
}

impl Progress {
    pub(super) fn new(jobs: usize, ports: PortSet) -> Self {
        Self {
            remaining: jobs,
            results: 0,
            nics: 0,
            completed: 0,
            no_result: 0,
            unreachable: 0,
            dropped: None,
            failure: None,
            undecided: ports,
            acknowledged: false,
        }
    }

    /// The job on `port` was acknowledged (`acked`) or ended without that:
    /// whether this decided the last undecided job and one was acknowledged
    /// (the command is delivered: ARCHITECTURE "Delivery contract").
    pub(super) fn decide(&mut self, port: u8, acked: bool) -> bool {
        if !self.undecided.remove(port) {
            return false;
        }
        self.acknowledged |= acked;
        self.undecided.is_empty() && self.acknowledged
    }

    /// The one outcome of all jobs: any result relayed wins; then a NIC when
    /// nothing completed (one `?` is relayed); then completed, no result,
    /// unreachable, dropped.
    pub(super) fn outcome(&self) -> CommandOutcome {
        if self.results > 0 {
            CommandOutcome::Result
        } else if self.nics > 0 && self.completed == 0 {
            CommandOutcome::Nic
        } else if self.completed > 0 {
            CommandOutcome::Completed
        } else if self.no_result > 0 {
            CommandOutcome::NoResult
        } else if self.unreachable > 0 {
            CommandOutcome::Unreachable
        } else {
            CommandOutcome::Dropped(self.dropped.unwrap_or(DropReason::UnknownPort))
        }
    }

    /// Whether the jobs' outcome means the command reached a device.
    pub(super) fn delivery(&self, outcome: CommandOutcome) -> Result<(), Undelivered> {
        match outcome {
            CommandOutcome::Result
            | CommandOutcome::Nic
            | CommandOutcome::Completed
            | CommandOutcome::NoResult
            | CommandOutcome::Forwarded(_) => Ok(()),
            CommandOutcome::Unreachable => Err(self.failure.unwrap_or(Undelivered::DeviceSilent)),
            CommandOutcome::Dropped(reason) => Err(reason.undelivered()),
        }
    }
}

/// A set of port numbers, without an allocation.
#[derive(Clone, Copy, Debug, Default)]
pub(super) struct PortSet([u64; 4]);

impl PortSet {
    pub(super) fn insert(&mut self, port: u8) {
        self.0[usize::from(port / 64)] |= 1 << (port % 64);
    }

    /// Removes `port`: whether it was in the set.
    fn remove(&mut self, port: u8) -> bool {
        let (word, bit) = (usize::from(port / 64), 1u64 << (port % 64));
        let was = self.0[word] & bit != 0;
        self.0[word] &= !bit;
        was
    }

    fn is_empty(&self) -> bool {
        self.0 == [0; 4]
    }
}

/// One command in flight, from its acceptance until it finished and its
/// origin was told whether it was delivered: everything the router keeps
/// about it, under its id.
#[derive(Debug)]
pub(super) struct InFlight {
    pub(super) origin: Origin,
    /// Who sent it, as its link said when it was accepted (a door may act
    /// for another user by the time a waiting command is decided).
    pub(super) who: Option<crate::principal::Actor>,
    /// The command frame as accepted (a report names its checksum; a
    /// client's retransmission is byte-identical) and its facts, read then.
    pub(super) command: ReadCommand,
    /// Its origin link has not yet been told whether it was delivered
    /// (ARCHITECTURE "Delivery contract").
    pub(super) delivery: Option<Delivery>,
    /// Executed on local ports: its jobs, until they all ended.
    pub(super) jobs: Option<Progress>,
    /// A stop the GCU issued itself: whose motion it ends, why, and its round.
    pub(super) issued_stop: Option<IssuedStop>,
    /// Its [`crate::RouterEvent::Finished`] was sent.
    pub(super) finished: bool,
    /// Its origin was told it was not delivered (a delivery report, e.g.
    /// `0B not confirmed`), or its link went down: no answer of it is owed
    /// any more. Its device may still answer, but a bare `?` names no
    /// command (1.4.2) and a result only its Table 3 header (1.4.3), and
    /// the origin would take either for the command it awaits now: neither
    /// is relayed (ARCHITECTURE "Delivery contract").
    pub(super) disowned: bool,
    /// A group-255 command also flooded to other GCUs: delivered when
    /// delivered anywhere.
    pub(super) spread: Option<Spread>,
    /// What the governance keeps of it until it ends (module `govern`).
    pub(super) note: crate::govern::CommandNote,
}

impl InFlight {
    /// Nothing is left to do or tell about it.
    pub(super) fn done(&self) -> bool {
        self.finished && self.delivery.is_none()
    }

    /// A stop the GCU issued itself that ended `outcome`: its next round,
    /// when no device acknowledged it and rounds are left (the motion it
    /// ends goes on until one does).
    pub(super) fn stop_again(&self, outcome: CommandOutcome) -> Option<StopRound> {
        let issued = self.issued_stop?;
        (outcome == CommandOutcome::Unreachable && issued.round < DEAD_MAN_ROUNDS).then(|| StopRound {
            stop: self.command.clone(),
            issued: IssuedStop {
                round: issued.round + 1,
                ..issued
            },
        })
    }
}

/// A group-255 command this GCU executed and also flooded to other GCUs
/// (ARCHITECTURE "Routing semantics": every GCU's, delivered when delivered
/// anywhere): a part's failure is told only once no part is left that may
/// still deliver it.
#[derive(Clone, Copy, Debug)]
pub(super) struct Spread {
    /// Parts not settled yet: its execution here and each copy flooded.
    pub(super) unsettled: u16,
    /// The link of its first copy.
    pub(super) via: LinkId,
    /// What to tell if no part delivers it, and the group where it failed.
    pub(super) failure: Option<(Undelivered, u8)>,
}

impl Spread {
    /// A part failed with `failure` at `group`: the failure to tell, once
    /// this was the last part. A port one GCU lacks says less than a
    /// failure where the port is, and gives way to it.
    pub(super) fn failed(&mut self, failure: Undelivered, group: u8) -> Option<(Undelivered, u8)> {
        let keep = match self.failure {
            None => true,
            Some((kept, _)) => kept == Undelivered::NoSuchPort && failure != Undelivered::NoSuchPort,
        };
        if keep {
            self.failure = Some((failure, group));
        }
        self.unsettled = self.unsettled.saturating_sub(1);
        self.failure.filter(|_| self.unsettled == 0)
    }
}

/// What the origin link of a command in flight awaits.
#[derive(Clone, Copy, Debug)]
pub(super) enum Delivery {
    /// A client link: the withheld ACK, or a report when undelivered, by
    /// `deadline` at the latest (`delivery_timeout`).
    Client { deadline: u64 },
    /// A link to another GCU: a report either way.
    Gcu,
}

impl Delivery {
    /// When the origin must be told at the latest, if there is a limit.
    pub(super) fn deadline(self) -> Option<u64> {
        match self {
            Delivery::Client { deadline } => Some(deadline),
            Delivery::Gcu => None,
        }
    }
}

/// A stop the GCU issued itself (ARCHITECTURE "Safety").
#[derive(Clone, Copy, Debug)]
pub(super) struct IssuedStop {
    /// The link whose motion it ends (`None`: the governance's own stop of
    /// whatever moves, a boundary's or a gimbal found moving).
    pub(super) link: Option<LinkId>,
    pub(super) cause: crate::types::StopCause,
    /// Which round of sending it this is, from 1 (at most `DEAD_MAN_ROUNDS`).
    pub(super) round: u8,
}

/// The next round of a stop the GCU issued itself.
#[derive(Debug)]
pub(super) struct StopRound {
    pub(super) stop: ReadCommand,
    pub(super) issued: IssuedStop,
}
