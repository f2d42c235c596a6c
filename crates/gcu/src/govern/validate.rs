//! The checks of a governance configuration before it is taken (module
//! [`super::rules`]): gimbals on configured ports, each once, spans the
//! right way round, tours with unique names and steps, and tour positions
//! inside the limits with no path between two of them entering a zone.

use super::rules::{Governance, Span, TourTarget};
use super::travel::{axes, check_goto};

/// Why a governance configuration is refused, in words naming the gimbal
/// or tour (the configuration reports it at its place in the file).
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct GovernanceError(pub String);

impl std::fmt::Display for GovernanceError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(&self.0)
    }
}

impl Governance {
    /// Checks what the governance relies on: gimbals on configured ports
    /// (`ports`: their ids), each once, spans the right way round, tours
    /// with unique names and steps, and tour steps (positions) inside the
    /// limits, with no path between two of them entering a zone.
    pub fn validate(&self, ports: &[u8]) -> Result<(), GovernanceError> {
        let bad = |what: String| Err(GovernanceError(what));
        for (i, g) in self.gimbals.iter().enumerate() {
            let name = format!("gimbal {}.{}", g.port, g.device);
            if !ports.contains(&g.port) || g.device == 0 || g.device == sagebrush_protocol::WILDCARD {
                return bad(format!("{name}: no such port, or device not 1..=254"));
            }
            if self.gimbals[..i]
                .iter()
                .any(|o| (o.port, o.device) == (g.port, g.device))
            {
                return bad(format!("{name}: configured twice"));
            }
            let spans = g.pan_limits.iter().chain(&g.tilt_limits);
            let zones = g.keep_out.iter().flat_map(|z| [&z.pan, &z.tilt]);
            if spans.chain(zones).any(|s| s.lo > s.hi) {
                return bad(format!("{name}: a span whose low end is above its high end"));
            }
            let rates = g.slew_rate.iter().chain(&g.acceleration).flatten();
            if rates.into_iter().any(|&r| r == 0) {
                return bad(format!("{name}: a slew rate or acceleration of 0"));
            }
        }
        for (i, t) in self.tours.iter().enumerate() {
            if !sagebrush_protocol::gcu::valid_name(t.name.as_bytes()) {
                return bad(format!("tour {:?}: a name is 1..=32 of A-Z a-z 0-9 _ -", t.name));
            }
            if self.tours[..i].iter().any(|o| o.name == t.name) {
                return bad(format!("tour {}: configured twice", t.name));
            }
            if t.steps.is_empty() {
                return bad(format!("tour {}: no steps", t.name));
            }
            if !ports.contains(&t.port) {
                return bad(format!("tour {}: no port {}", t.name, t.port));
            }
            let Some(rules) = self.gimbals.iter().find(|g| (g.port, g.device) == (t.port, t.device)) else {
                continue;
            };
            let positions: Vec<(usize, [i32; 2])> = t
                .steps
                .iter()
                .enumerate()
                .filter_map(|(n, s)| match s.to {
                    TourTarget::Position(p) => Some((n, axes(p))),
                    TourTarget::Preset(_) => None,
                })
                .collect();
            for (k, &(n, target)) in positions.iter().enumerate() {
                // The path from the step before (when it is a position too).
                let before = if n == 0 { t.steps.len() - 1 } else { n - 1 };
                let from = positions
                    .get(if k == 0 { positions.len() - 1 } else { k - 1 })
                    .filter(|(m, _)| *m == before)
                    .map(|&(_, p)| [Span::at(p[0]), Span::at(p[1])]);
                let from = from.unwrap_or([Span::at(target[0]), Span::at(target[1])]);
                if let Err(reason) = check_goto(rules, Some(from), target) {
                    let why = match reason {
                        crate::types::DropReason::KeepOut => "enters a keep-out zone",
                        _ => "lies outside the travel limits",
                    };
                    return bad(format!(
                        "tour {}: step {} {why} of gimbal {}.{}",
                        t.name,
                        n + 1,
                        t.port,
                        t.device
                    ));
                }
            }
        }
        Ok(())
    }
}
