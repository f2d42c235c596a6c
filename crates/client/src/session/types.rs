//! The gimbal session's public vocabulary: an axis's drive, a velocity,
//! the axes a stop is for, the motion and status a door reads, and gcud's
//! reachability shared by a door's sessions (ARCHITECTURE "Front doors").

use super::*;

/// One axis's drive: stopped, or slewing forward (pan right `PR`, tilt up
/// `TU`, zoom in `ZI`) or back at a speed (Tables 11 and 16).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Drive<S> {
    Stop,
    Forward(S),
    Back(S),
}

impl<S: Copy> Drive<S> {
    /// The drive of a signed velocity or rate `v` (0 stops, positive is
    /// forward), at `speed(v)` (the door's mapping of |v| to Table 11/16).
    pub fn signed(v: f64, speed: impl FnOnce(f64) -> S) -> Self {
        if v == 0.0 {
            Drive::Stop
        } else if v > 0.0 {
            Drive::Forward(speed(v))
        } else {
            Drive::Back(speed(v))
        }
    }

    pub(super) fn speed(self) -> Option<S> {
        match self {
            Drive::Stop => None,
            Drive::Forward(s) | Drive::Back(s) => Some(s),
        }
    }
}

/// A velocity: each axis with `Some` is set, `None` left as it is.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Velocity {
    pub pan: Option<Drive<Speed>>,
    pub tilt: Option<Drive<Speed>>,
    pub zoom: Option<Drive<LensSpeed>>,
}

/// Which axes a stop is for.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Axes {
    pub pan: bool,
    pub tilt: bool,
    pub zoom: bool,
}

impl Axes {
    pub const PAN_TILT: Axes = Axes {
        pan: true,
        tilt: true,
        zoom: false,
    };
    pub const ALL: Axes = Axes {
        pan: true,
        tilt: true,
        zoom: true,
    };

    pub(super) fn any(self) -> bool {
        self.pan || self.tilt || self.zoom
    }

    pub(super) fn or(self, other: Axes) -> Axes {
        Axes {
            pan: self.pan || other.pan,
            tilt: self.tilt || other.tilt,
            zoom: self.zoom || other.zoom,
        }
    }

    /// The next stop command owed, in the order `PS`, `TS`, `ZS`.
    pub(super) fn first(self) -> Option<(Command<'static>, Axes)> {
        if self.pan {
            Some((
                Command::PanStop,
                Axes {
                    pan: true,
                    ..Axes::default()
                },
            ))
        } else if self.tilt {
            Some((
                Command::TiltStop,
                Axes {
                    tilt: true,
                    ..Axes::default()
                },
            ))
        } else if self.zoom {
            Some((
                Command::ZoomStop,
                Axes {
                    zoom: true,
                    ..Axes::default()
                },
            ))
        } else {
            None
        }
    }

    pub(super) fn without(self, other: Axes) -> Axes {
        Axes {
            pan: self.pan && !other.pan,
            tilt: self.tilt && !other.tilt,
            zoom: self.zoom && !other.zoom,
        }
    }
}

/// What a door reports of the motion (ONVIF MoveStatus).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Motion {
    #[default]
    Idle,
    Moving,
    /// A stop is owed that the bus has not confirmed (gcud unreachable):
    /// the gimbal may be moving or not.
    Unknown,
}

/// The session's picture of its gimbal, read by every door's status.
#[derive(Clone, Debug, Default)]
pub struct Status {
    /// The last `P?` answer.
    pub position: Option<Position>,
    /// The last `V?` answer (sessions with a lens).
    pub lens: Option<LensPosition>,
    /// Why the last poll failed, when it did.
    pub error: Option<String>,
    /// The position changed between the last two polls.
    pub changing: bool,
    pub motion: Motion,
    /// Who controls the gimbal, as gcud last answered `~C` (with a poll,
    /// or naming the holder of a refusal); `None` while unknown (a gcud
    /// that governs nothing answers NIC).
    pub control: Option<Control>,
    /// The controller that took the gimbal from this session (gcud stopped
    /// the session's motion when it took control) or refused its last
    /// move, while gcud names it as the holder.
    pub taken_by: Option<Controller>,
}

/// Whether gcud can be reached, shared by a door's sessions so that the
/// door logs each change once.
#[derive(Debug, Default)]
pub struct GcudReachability(AtomicU8);

// 0: not yet known.
pub(super) const REACH_UP: u8 = 1;
pub(super) const REACH_DOWN: u8 = 2;

impl GcudReachability {
    /// gcud at `gcud` answered (formatted only when this is news: this
    /// runs after every command).
    pub(super) fn up(&self, gcud: &sagebrush_host::tls::Endpoint) {
        if self.0.swap(REACH_UP, Ordering::Relaxed) == REACH_DOWN {
            info!(%gcud, "gcud can be reached again");
        }
    }

    pub(super) fn down(&self, gcud: &sagebrush_host::tls::Endpoint, error: &CommandError) {
        if self.0.swap(REACH_DOWN, Ordering::Relaxed) != REACH_DOWN {
            warn!(%gcud, %error, "gcud cannot be reached: stops are kept owed and sent first when it is back");
        }
    }
}
