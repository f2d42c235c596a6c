//! How a command acts on the pan/tilt mount: the governance column of the
//! command table (Tables 4, 11, 16 and the rev 1.9 list, 1.2).
//!
//! Every row of `command_table!` and `extended_table!` states its
//! [`MountEffect`], so a router that keeps a gimbal within limits reads it
//! from the table, never from a list of its own: a command the table does
//! not know ([`crate::Command::Unknown`]) is [`MountEffect::Unbounded`], and
//! so is every rev 1.9 command whose layout the document does not give
//! (protocol-notes E13) but which may move the mount.

use crate::units::{Acceleration, Axis, Position, Rate, Speed};

/// What a command does to the pan/tilt mount (its row's governance fact).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum MountEffect {
    /// Changes nothing: a query, and what its answer describes.
    Reads(Describes),
    /// Stops these axes (`PS`, `TS`, `PT`; the lens stops `FS`, `ZS` stop neither).
    Stop {
        /// The pan axis stops.
        pan: bool,
        /// The tilt axis stops.
        tilt: bool,
    },
    /// Stops both axes and turns the motors off (`HS`); `HA` also stores
    /// the position that `HP` returns to (Table 11). A change of the
    /// gimbal: it needs control.
    Halt,
    /// A continuous slew of one axis until its stop (Table 11).
    Slew {
        /// The axis.
        axis: Axis,
        /// Toward positive angles: counter-clockwise (`PR`, `TU`; protocol-notes E12).
        positive: bool,
    },
    /// A goto of both axes (`Paaaaeeee`, `HO` to (0, 0)).
    GoTo(Position),
    /// A goto to a stored preset (`Pnn`).
    RecallPreset(u8),
    /// Stores the current position as a preset (`Snn`).
    StorePreset(u8),
    /// Changes an axis' speed (Table 11).
    Speed {
        /// The axis.
        axis: Axis,
        /// What it becomes.
        to: NewSpeed,
    },
    /// Changes an axis' acceleration (`APnnnn`, `ATnnnn`).
    Acceleration {
        /// The axis.
        axis: Axis,
        /// The new acceleration.
        acceleration: Acceleration,
    },
    /// Changes who the gimbal is or how it is reached: its address (`#NN`)
    /// or its line rate (`Cn`).
    Identity,
    /// Changes the gimbal's own limits or dynamics (`LS`, `LC`, rate gains,
    /// the rev 1.9 gains, limits, loop mode and user parameters, and vector
    /// mode `VMn`: a vector move scales an axis' rate and acceleration down
    /// so that both arrive together, so a goto begun while that axis moves
    /// brakes more slowly than the gimbal's acceleration says).
    Dynamics,
    /// Changes a setting that leaves the mount's travel bounded: the lens,
    /// camera power, relays, the auxiliary ports.
    Setting,
    /// Moves the mount where nobody can bound: `IX` (to its switches),
    /// `HP` (to the position `HA` saved), the rev 1.9 position and rate
    /// commands (`*mp`, `*me`, `*mr`), and any command the table does not know.
    Unbounded,
}

/// A speed an axis is set to (Table 11).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum NewSpeed {
    /// A discrete rate (`RPnnnn`, `RTnnnn`, Table 12).
    Rate(Rate),
    /// A proportional step 0..=15 whose rate only the gimbal knows (`SPn`,
    /// `STn`): 15 is its maximum, 0 the slowest or a time-dependent rate.
    Step(Speed),
}

/// What a query's answer describes.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Describes {
    /// The mount's current position (`P?`, Table 15).
    Position,
    /// The position stored at a preset (`P?nn`, `S?nn`, Table 15): never
    /// where the mount is.
    Preset(u8),
    /// The rates (`R?`: both axes; `RP?`, `RT?`: one; Table 13).
    Rates(Option<Axis>),
    /// The accelerations (`A?`: both axes; `AP?`, `AT?`: one; Table 13).
    Accelerations(Option<Axis>),
    /// Anything else (status, identity, limits, the lens, inputs).
    Other,
}

impl MountEffect {
    /// A query whose answer describes nothing the governance keeps.
    pub const READS: MountEffect = MountEffect::Reads(Describes::Other);

    /// Stops both axes.
    pub const STOP_BOTH: MountEffect = MountEffect::Stop { pan: true, tilt: true };

    /// A slew of `axis`, `positive` toward counter-clockwise angles.
    pub const fn slew(axis: Axis, positive: bool) -> MountEffect {
        MountEffect::Slew { axis, positive }
    }

    /// Whether it moves the mount or changes the gimbal (anything but a
    /// query and a stop of `PS`, `TS`, `PT`, `FS`, `ZS`): it needs control.
    pub const fn changes(&self) -> bool {
        !matches!(self, MountEffect::Reads(_) | MountEffect::Stop { .. })
    }

    /// Whether a gimbal kept within limits refuses it unless its
    /// configuration opts in by name: the mount's travel cannot be bounded
    /// through it, or it changes the gimbal's identity, line or dynamics.
    pub const fn is_ungoverned(&self) -> bool {
        matches!(
            self,
            MountEffect::Unbounded | MountEffect::Identity | MountEffect::Dynamics
        )
    }
}
