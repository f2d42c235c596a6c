//! What became of this process's commands to its gimbals, counted for a
//! door's metrics (`sagebrush_service::door_metrics`): every exchange
//! [`crate::GimbalConnection`] settles, by outcome (`delivered`, gcud's
//! refusal, a fault on the way or at the device), and gcud's refusals by
//! their rule (the delivery report's reason name, `Undelivered`). One set
//! per process, as a door has one registry; cheap beside a bus exchange.

use std::collections::BTreeMap;
use std::sync::Mutex;

use crate::CommandError;

/// Counts by name, in name order.
type Counts = BTreeMap<&'static str, u64>;

/// Exchanges by outcome and gcud's refusals by rule.
#[derive(Debug)]
pub struct OutcomeCounts {
    outcomes: Mutex<Counts>,
    refusals: Mutex<Counts>,
}

/// This process's counts: what [`crate::GimbalConnection`] settles.
pub static COUNTS: OutcomeCounts = OutcomeCounts::new();

/// The outcome label of an exchange's result.
pub fn outcome<T>(result: &Result<T, CommandError>) -> &'static str {
    match result {
        Ok(_) => "delivered",
        Err(CommandError::Refused(..)) => "refused",
        Err(CommandError::Undelivered(..)) => "undelivered",
        Err(CommandError::Io(_)) => "connection_failed",
        Err(CommandError::Usage(_)) => "not_encodable",
        Err(CommandError::Nak(_)) => "device_nak",
        Err(CommandError::NoAck(_)) => "device_silent",
        Err(CommandError::Nic(_)) => "device_nic",
        Err(CommandError::NoResult(_)) => "no_result",
        Err(CommandError::BadReply(_)) => "bad_reply",
    }
}

fn bump(counts: &Mutex<Counts>, name: &'static str) {
    let mut counts = counts.lock().unwrap_or_else(std::sync::PoisonError::into_inner);
    *counts.entry(name).or_default() += 1;
}

fn read(counts: &Mutex<Counts>) -> Vec<(&'static str, u64)> {
    let counts = counts.lock().unwrap_or_else(std::sync::PoisonError::into_inner);
    counts.iter().map(|(k, v)| (*k, *v)).collect()
}

impl OutcomeCounts {
    pub const fn new() -> Self {
        Self {
            outcomes: Mutex::new(BTreeMap::new()),
            refusals: Mutex::new(BTreeMap::new()),
        }
    }

    /// Counts `result`, one settled exchange.
    pub fn record<T>(&self, result: &Result<T, CommandError>) {
        bump(&self.outcomes, outcome(result));
        if let Err(CommandError::Refused(rule, _)) = result {
            bump(&self.refusals, rule.name());
        }
    }

    /// Exchanges settled so far, by outcome.
    pub fn by_outcome(&self) -> Vec<(&'static str, u64)> {
        read(&self.outcomes)
    }

    /// gcud's refusals so far, by rule.
    pub fn refusals(&self) -> Vec<(&'static str, u64)> {
        read(&self.refusals)
    }
}

impl Default for OutcomeCounts {
    fn default() -> Self {
        Self::new()
    }
}

/// This process's counts as a door's metrics
/// (`sagebrush_service::door_metrics`): `bus_outcomes_total{outcome}` and
/// `refusals_total{reason}`.
pub fn families() -> Vec<sagebrush_service::door_metrics::CountFamily> {
    use sagebrush_service::door_metrics::CountFamily;
    vec![
        CountFamily {
            name: "bus_outcomes",
            help: "The door's commands to its gimbals by what became of them: delivered, refused by gcud, or a fault on the way or at the device.",
            label: "outcome",
            read: || COUNTS.by_outcome(),
        },
        CountFamily {
            name: "refusals",
            help: "gcud's refusals of the door's commands, by its rule.",
            label: "reason",
            read: || COUNTS.refusals(),
        },
    ]
}

#[cfg(test)]
mod tests {
    use super::*;
    use sagebrush_protocol::report::Undelivered;

    #[test]
    fn a_refusal_counts_as_refused_and_by_its_rule() {
        let counts = OutcomeCounts::new();
        counts.record::<()>(&Err(CommandError::Refused(
            Undelivered::KeepOut,
            "refused by gcud".into(),
        )));
        counts.record::<()>(&Err(CommandError::NoAck("silent".into())));
        counts.record(&Ok(()));
        counts.record(&Ok(()));
        assert_eq!(
            counts.by_outcome(),
            [("delivered", 2), ("device_silent", 1), ("refused", 1)]
        );
        assert_eq!(counts.refusals(), [("keep_out", 1)]);
    }
}
