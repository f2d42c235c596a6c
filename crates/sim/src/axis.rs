//! One pan or tilt axis: position, velocity and the move in progress, with
//! trapezoidal velocity profiles (Table 11 moves, Table 12 rates and
//! accelerations) and the travel range that software limits (Table 10) and
//! the mechanical hard stops (Table 6B bits 5, 6) allow.
//!
//! Units are those of the wire: hundredths of a degree, hundredths of a
//! degree per second and per second squared. Time advances in fixed steps
//! of [`STEP_MS`], so a run is deterministic whatever the caller's clock.

/// Integration step in milliseconds.
pub const STEP_MS: u64 = 1;
const DT: f64 = STEP_MS as f64 / 1000.0;
/// A move ends when it is this close (hundredths of a degree) to its target.
const ARRIVED: f64 = 0.5;

/// What the axis is doing.
#[derive(Clone, Copy, Debug, PartialEq)]
enum Mode {
    /// Holding still (motors on) or parked (motors off).
    Hold,
    /// Moving to `target` with peak `rate` and `accel` (a go-to, home, preset or vector move).
    GoTo { target: f64, rate: f64, accel: f64 },
    /// Continuous slew in direction `dir` (+1 counter-clockwise, -1 clockwise) until stopped.
    Slew { dir: f64, rate: f64, accel: f64 },
    /// Decelerating to a stop (`PS`, `TS`, `PT`).
    Stopping { accel: f64 },
}

/// Which mechanical end of travel the axis rests against (Table 6B bits 5, 6).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum HardStop {
    Positive,
    Negative,
}

/// The motion state of one axis.
#[derive(Clone, Debug)]
pub struct Axis {
    pos: f64,
    vel: f64,
    mode: Mode,
    /// Mechanical travel, hundredths of a degree (min, max).
    mechanical: (f64, f64),
    /// Software limits, hundredths of a degree (cw/min, ccw/max), inside the mechanical range.
    soft: (f64, f64),
    hard_stop: Option<HardStop>,
}

impl Axis {
    /// An axis at rest at `pos` within mechanical travel `min..=max` (hundredths of a degree).
    pub fn new(pos: i16, min: i16, max: i16) -> Self {
        let mechanical = (f64::from(min), f64::from(max));
        Self {
            pos: f64::from(pos).clamp(mechanical.0, mechanical.1),
            vel: 0.0,
            mode: Mode::Hold,
            mechanical,
            soft: mechanical,
            hard_stop: None,
        }
    }

    /// Position rounded to the wire's hundredths of a degree.
    pub fn position(&self) -> i16 {
        self.pos.round().clamp(f64::from(i16::MIN), f64::from(i16::MAX)) as i16
    }

    /// Velocity, hundredths of a degree per second (signed, + = counter-clockwise).
    pub fn velocity(&self) -> f64 {
        self.vel
    }

    /// Whether a move, slew or stop is in progress.
    pub fn is_moving(&self) -> bool {
        self.mode != Mode::Hold
    }

    /// Which hard stop the axis rests against, if any.
    pub fn hard_stop(&self) -> Option<HardStop> {
        self.hard_stop
    }

    /// The travel allowed now: software limits within the mechanical range.
    pub fn travel(&self) -> (f64, f64) {
        self.soft
    }

    /// Sets software limits (hundredths of a degree; `cw` <= 0 <= `ccw` is not
    /// required). They are narrowed to the mechanical range; the axis is pulled
    /// inside at once if it lies outside (Table 10 "clamp").
    pub fn set_soft_limits(&mut self, cw: f64, ccw: f64) {
        let lo = cw.min(ccw).max(self.mechanical.0);
        let hi = ccw.max(cw).min(self.mechanical.1);
        self.soft = if lo <= hi { (lo, hi) } else { (hi, hi) };
        if let Mode::GoTo { target, rate, accel } = self.mode {
            self.mode = Mode::GoTo {
                target: target.clamp(self.soft.0, self.soft.1),
                rate,
                accel,
            };
        }
    }

    /// Removes the software limits (`LC`): the mechanical range remains.
    pub fn clear_soft_limits(&mut self) {
        self.soft = self.mechanical;
    }

    /// Starts a move to `target` (clamped to the travel); returns the clamped target.
    pub fn go_to(&mut self, target: i16, rate: f64, accel: f64) -> i16 {
        let target = f64::from(target).clamp(self.soft.0, self.soft.1);
        self.mode = Mode::GoTo {
            target,
            rate: rate.max(1.0),
            accel: accel.max(1.0),
        };
        target.round() as i16
    }

    /// Starts a continuous slew (+1 counter-clockwise, -1 clockwise).
    pub fn slew(&mut self, dir: f64, rate: f64, accel: f64) {
        self.mode = Mode::Slew {
            dir: dir.signum(),
            rate: rate.max(1.0),
            accel: accel.max(1.0),
        };
    }

    /// Decelerates to a stop at `accel`.
    pub fn stop(&mut self, accel: f64) {
        if self.mode != Mode::Hold {
            self.mode = Mode::Stopping { accel: accel.max(1.0) };
        }
    }

    /// Stops dead (halt, motors off, initialisation).
    pub fn halt(&mut self) {
        self.vel = 0.0;
        self.mode = Mode::Hold;
    }

    /// Puts the axis at `pos` at rest (end of the initialisation sequence).
    pub fn place(&mut self, pos: i16) {
        self.halt();
        self.pos = f64::from(pos).clamp(self.soft.0, self.soft.1);
        self.hard_stop = None;
    }

    /// Time in seconds a trapezoidal move of `distance` takes at peak `rate` and `accel`.
    pub fn move_time(distance: f64, rate: f64, accel: f64) -> f64 {
        let (d, v, a) = (distance.abs(), rate.max(1.0), accel.max(1.0));
        if d >= v * v / a {
            d / v + v / a
        } else {
            2.0 * (d / a).sqrt()
        }
    }

    /// Distance from the current position to `target` after clamping to the travel.
    pub fn distance_to(&self, target: i16) -> f64 {
        f64::from(target).clamp(self.soft.0, self.soft.1) - self.pos
    }

    /// Advances one integration step.
    pub fn step(&mut self) {
        match self.mode {
            Mode::Hold => self.vel = 0.0,
            Mode::GoTo { target, rate, accel } => {
                let d = target - self.pos;
                if d.abs() < ARRIVED && self.vel.abs() <= accel * DT * 2.0 {
                    self.pos = target;
                    self.halt();
                } else {
                    let stop_speed = (2.0 * accel * d.abs()).sqrt().min(rate);
                    self.vel = approach(self.vel, stop_speed * d.signum(), accel * DT);
                    self.pos += self.vel * DT;
                    if (target - self.pos).signum() != d.signum() {
                        self.pos = target;
                        self.halt();
                    }
                }
            }
            Mode::Slew { dir, rate, accel } => {
                self.vel = approach(self.vel, dir * rate, accel * DT);
                self.pos += self.vel * DT;
            }
            Mode::Stopping { accel } => {
                self.vel = approach(self.vel, 0.0, accel * DT);
                self.pos += self.vel * DT;
                if self.vel == 0.0 {
                    self.mode = Mode::Hold;
                }
            }
        }
        self.enforce_travel();
    }

    /// Clamps to the travel; a clamped axis stops (software limits, hard stops).
    fn enforce_travel(&mut self) {
        let (lo, hi) = self.soft;
        if self.pos > hi || self.pos < lo {
            self.pos = self.pos.clamp(lo, hi);
            self.halt();
        }
        self.hard_stop = if self.pos >= self.mechanical.1 {
            Some(HardStop::Positive)
        } else if self.pos <= self.mechanical.0 {
            Some(HardStop::Negative)
        } else {
            None
        };
    }
}

/// `current` moved toward `goal` by at most `max_change`.
fn approach(current: f64, goal: f64, max_change: f64) -> f64 {
    if (goal - current).abs() <= max_change {
        goal
    } else {
        current + max_change * (goal - current).signum()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn run(axis: &mut Axis, ms: u64) {
        for _ in 0..ms / STEP_MS {
            axis.step();
        }
    }

    #[test]
    fn goto_follows_a_trapezoid_and_arrives() {
        let mut a = Axis::new(0, -18000, 18000);
        a.go_to(9000, 6000.0, 12000.0);
        run(&mut a, 250);
        // Still accelerating at 0.25 s: v = a t = 3000.
        assert!((a.velocity() - 3000.0).abs() < 20.0, "{}", a.velocity());
        let expected = Axis::move_time(9000.0, 6000.0, 12000.0);
        run(&mut a, (expected * 1000.0) as u64);
        assert!(a.is_moving() || a.position() == 9000);
        run(&mut a, 50);
        assert_eq!(a.position(), 9000);
        assert!(!a.is_moving());
    }

    #[test]
    fn short_move_is_triangular_and_does_not_overshoot() {
        let mut a = Axis::new(0, -18000, 18000);
        a.go_to(-100, 6000.0, 12000.0);
        let mut min = 0;
        for _ in 0..2000 {
            a.step();
            min = min.min(a.position());
        }
        assert_eq!(a.position(), -100);
        assert!(min >= -101);
    }

    #[test]
    fn slew_stops_at_soft_limit_and_hard_stop() {
        let mut a = Axis::new(0, -18000, 18000);
        a.set_soft_limits(-1000.0, 1500.0);
        a.slew(1.0, 6000.0, 12000.0);
        run(&mut a, 2000);
        assert_eq!(a.position(), 1500);
        assert!(!a.is_moving());
        assert_eq!(a.hard_stop(), None);
        a.clear_soft_limits();
        a.slew(-1.0, 6000.0, 60000.0);
        run(&mut a, 10_000);
        assert_eq!(a.position(), -18000);
        assert_eq!(a.hard_stop(), Some(HardStop::Negative));
    }

    #[test]
    fn stop_decelerates() {
        let mut a = Axis::new(0, -18000, 18000);
        a.slew(1.0, 6000.0, 12000.0);
        run(&mut a, 1000);
        let at_stop = a.position();
        a.stop(12000.0);
        run(&mut a, 1000);
        let after = a.position();
        // v = 6000 at the stop; braking distance v^2 / 2a = 1500.
        assert!((after - at_stop - 1500).abs() < 20, "{at_stop} -> {after}");
        assert!(!a.is_moving());
    }

    #[test]
    fn goto_target_is_clamped_by_limits() {
        let mut a = Axis::new(0, -9000, 9000);
        a.set_soft_limits(-500.0, 500.0);
        assert_eq!(a.go_to(4000, 6000.0, 12000.0), 500);
        run(&mut a, 3000);
        assert_eq!(a.position(), 500);
    }
}
