//! Lens zoom and focus (Table 16, Table 17): 12-bit positions 0..=4095 that
//! move at the speed `Z0..Z9` / `F0..F9` sets, continuously (`ZI`, `ZO`,
//! `FF`, `FN` until `ZS` / `FS` or the end of travel) or to a target (`V`).

/// Largest 12-bit lens position (Table 17).
pub const LENS_MAX: f64 = 4095.0;

#[derive(Clone, Copy, Debug, PartialEq)]
enum Mode {
    Hold,
    Run { dir: f64 },
    GoTo { target: f64 },
}

/// One lens function (zoom or focus).
#[derive(Clone, Debug)]
pub struct LensDrive {
    pos: f64,
    mode: Mode,
    speed: u8,
    /// Milliseconds the full travel takes at the fastest speed (9).
    full_travel_ms: u64,
}

impl LensDrive {
    pub fn new(pos: u16, speed: u8, full_travel_ms: u64) -> Self {
        Self {
            pos: f64::from(pos).min(LENS_MAX),
            mode: Mode::Hold,
            speed: speed.min(9),
            full_travel_ms: full_travel_ms.max(1),
        }
    }

    /// Position, 0..=4095.
    pub fn position(&self) -> u16 {
        self.pos.round().clamp(0.0, LENS_MAX) as u16
    }

    /// Speed number 0..=9.
    pub fn speed(&self) -> u8 {
        self.speed
    }

    pub fn set_speed(&mut self, speed: u8) {
        self.speed = speed.min(9);
    }

    pub fn is_moving(&self) -> bool {
        self.mode != Mode::Hold
    }

    /// Units per millisecond at the current speed: speed 9 crosses the full
    /// travel in `full_travel_ms`, speed 0 takes ten times as long.
    fn units_per_ms(&self) -> f64 {
        LENS_MAX / self.full_travel_ms as f64 * f64::from(self.speed + 1) / 10.0
    }

    /// Runs toward the far end (+1: zoom in / focus far) or the near end (-1).
    pub fn run(&mut self, dir: f64) {
        self.mode = Mode::Run { dir: dir.signum() };
    }

    pub fn go_to(&mut self, target: u16) {
        self.mode = Mode::GoTo {
            target: f64::from(target).min(LENS_MAX),
        };
    }

    pub fn stop(&mut self) {
        self.mode = Mode::Hold;
    }

    /// Advances `ms` milliseconds.
    pub fn advance(&mut self, ms: u64) {
        let travel = self.units_per_ms() * ms as f64;
        match self.mode {
            Mode::Hold => {}
            Mode::Run { dir } => {
                self.pos = (self.pos + dir * travel).clamp(0.0, LENS_MAX);
                if self.pos == 0.0 || self.pos == LENS_MAX {
                    self.mode = Mode::Hold;
                }
            }
            Mode::GoTo { target } => {
                let d = target - self.pos;
                if d.abs() <= travel {
                    self.pos = target;
                    self.mode = Mode::Hold;
                } else {
                    self.pos += travel * d.signum();
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn runs_to_the_end_and_stops() {
        let mut z = LensDrive::new(0, 9, 1000);
        z.run(1.0);
        z.advance(500);
        assert!((i32::from(z.position()) - 2048).abs() <= 1);
        z.advance(600);
        assert_eq!(z.position(), 4095);
        assert!(!z.is_moving());
    }

    #[test]
    fn goto_arrives_at_slow_speed_later() {
        let mut f = LensDrive::new(4000, 0, 1000);
        f.go_to(3000);
        f.advance(1000);
        assert!(f.is_moving());
        f.advance(2000);
        assert_eq!(f.position(), 3000);
    }
}
