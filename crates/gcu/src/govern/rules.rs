//! What gcud governs each gimbal by (ARCHITECTURE "Governance"): the hold
//! time of control, link priorities (on [`crate::LinkConfig`]), travel
//! limits, keep-out zones, park, and tours. Angles are in hundredths of a
//! degree, as on the wire (Table 15); times in ticks.

use sagebrush_protocol::Position;

/// A link's priority when its configuration names none.
pub const DEFAULT_PRIORITY: u8 = 50;
/// The highest priority a link may have.
pub const MAX_PRIORITY: u8 = 100;
/// Default [`Governance::hold`]: 10 s.
pub const HOLD_MS: u64 = 10_000;

/// The rules of every gimbal and the tours.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Governance {
    /// A link keeps control of a gimbal this long after its last command
    /// that moves or changes it.
    pub hold: u64,
    /// Rules per gimbal (one entry per local port and device).
    pub gimbals: Vec<GimbalRules>,
    /// Tours gcud can run.
    pub tours: Vec<TourConfig>,
    /// The lowest link priority that may start or stop a tour (`~T`);
    /// `None`: any link (gcud sets the highest of its links' priorities).
    pub tours_min_priority: Option<u8>,
    /// The persons and tools gcud knows (`[[principal]]`): a door's user
    /// of this name is governed as it (ARCHITECTURE "Principals").
    pub principals: Vec<crate::principal::Principal>,
}

impl Default for Governance {
    fn default() -> Self {
        Self {
            hold: HOLD_MS,
            gimbals: Vec::new(),
            tours: Vec::new(),
            tours_min_priority: None,
            principals: Vec::new(),
        }
    }
}

/// An interval of one axis, in hundredths of a degree, `lo <= hi`, both ends included.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Span {
    pub lo: i32,
    pub hi: i32,
}

impl Span {
    pub const fn new(lo: i32, hi: i32) -> Self {
        Self { lo, hi }
    }

    /// Whether `v` lies within (ends included).
    pub const fn contains(&self, v: i32) -> bool {
        self.lo <= v && v <= self.hi
    }

    /// Whether the two spans share a point.
    pub const fn meets(&self, other: &Span) -> bool {
        self.lo <= other.hi && other.lo <= self.hi
    }

    /// The smallest span holding both.
    pub fn join(&self, other: &Span) -> Span {
        Span::new(self.lo.min(other.lo), self.hi.max(other.hi))
    }

    /// The span of one value.
    pub const fn at(v: i32) -> Span {
        Span::new(v, v)
    }
}

/// A pan/tilt rectangle no motion may enter (its edges included).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Zone {
    pub pan: Span,
    pub tilt: Span,
}

/// Park: recall `preset` once, `after` ticks after control lapsed with
/// nobody taking it.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Park {
    pub preset: u8,
    pub after: u64,
}

/// The rules of one gimbal (a device on a local port).
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct GimbalRules {
    pub port: u8,
    pub device: u8,
    /// Pan travel no command may leave.
    pub pan_limits: Option<Span>,
    /// Tilt travel no command may leave.
    pub tilt_limits: Option<Span>,
    pub keep_out: Vec<Zone>,
    pub park: Option<Park>,
    /// The fastest the gimbal slews, per axis (pan, tilt), hundredths of a
    /// degree per second: when set, slews are followed with it instead of
    /// the rate the gimbal answers to `R?` (Table 13).
    pub slew_rate: Option<[u32; 2]>,
    /// Its acceleration per axis, hundredths of a degree per second
    /// squared: when set, instead of what it answers to `A?`.
    pub acceleration: Option<[u32; 2]>,
    /// Commands the governance would refuse here (their row's mount effect
    /// is unbounded, identity or dynamics) that its operator lets through
    /// by name: a row's mnemonic (`*mp`, `IX`, `LS`, `#NN`) or script name
    /// (`set_device_id`, `unknown`). What they do is the operator's to bound.
    pub allow: Vec<String>,
}

impl GimbalRules {
    /// A gimbal with no rules yet.
    pub fn new(port: u8, device: u8) -> Self {
        Self {
            port,
            device,
            pan_limits: None,
            tilt_limits: None,
            keep_out: Vec::new(),
            park: None,
            slew_rate: None,
            acceleration: None,
            allow: Vec::new(),
        }
    }

    /// Whether the gimbal is governed by these rules (limits, zones or
    /// park): what its row marks unbounded, identity or dynamics is
    /// refused unless [`GimbalRules::allow`] names it.
    pub fn governs(&self) -> bool {
        self.bounds_travel() || self.park.is_some()
    }

    /// Whether [`GimbalRules::allow`] names the command.
    pub(crate) fn allows(&self, facts: &crate::command::CommandFacts) -> bool {
        let names = [facts.reply.mnemonic(), facts.row.script_name()];
        self.allow.iter().any(|a| names.contains(&a.as_str()))
    }

    /// Whether the gimbal has travel limits or keep-out zones (motions are then followed).
    pub fn bounds_travel(&self) -> bool {
        self.pan_limits.is_some() || self.tilt_limits.is_some() || !self.keep_out.is_empty()
    }
}

/// Where a tour step goes.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum TourTarget {
    /// A preset the gimbal stored (`Pnn`).
    Preset(u8),
    /// A position (`Paaaaeeee`).
    Position(Position),
}

/// One step of a tour: go there, then stay `dwell` ticks once arrived.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct TourStep {
    pub to: TourTarget,
    pub dwell: u64,
}

/// A tour: steps gcud runs in order, cycling until stopped.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct TourConfig {
    /// 1..=32 of `A-Z a-z 0-9 _ -` (it travels in GCU commands).
    pub name: String,
    pub port: u8,
    pub device: u8,
    pub steps: Vec<TourStep>,
}
