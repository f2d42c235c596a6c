//! How close a followed slew comes to a travel limit, and what following
//! costs the bus (issue 32's figures): for each line rate and proportional
//! speed, a simulated gimbal (60 deg/s at `SP7`, 120 deg/s at `SPF`, 120
//! deg/s^2) slews from rest toward a pan limit 90 degrees away; the table
//! gives where it came to rest (on the bus side) short of the limit, and
//! the share of the bus the position polls took while it moved.
//!
//! `cargo bench -p sagebrush-gcu --bench follow`

#[path = "../tests/rig/mod.rs"]
mod rig;

use rig::{ONE, PORT, Rig, gimbal};
use sagebrush_gcu::{GimbalRules, Span};
use sagebrush_protocol::link::wire_ms;
use sagebrush_protocol::{Axis, Command, Speed};

fn main() {
    println!("line bit/s | speed | top deg/s | rests short of the limit (deg) | polls | bus busy polling while moving");
    for bps in [9600u32, 19_200, 38_400, 115_200] {
        for speed in [3u8, 7, 11, 15] {
            let mut r = Rig::new(bps, vec![gimbal(1)], |c| {
                let mut rules = GimbalRules::new(PORT, 1);
                rules.pan_limits = Some(Span::new(-9000, 9000));
                c.governance.gimbals.push(rules);
            });
            r.client(ONE, "bench", 50);
            r.run(5000);
            r.send(ONE, 1, &Command::SetSpeed(Axis::Pan, Speed::new(speed).expect("speed")));
            r.run(500);
            let polls_before = r.router.governance_stats().follow_polls;
            let start = r.now;
            r.send(ONE, 1, &Command::PanRight);
            let mut farthest = i32::MIN;
            let mut moving_ms = 0u64;
            r.run_with(20_000, 1, |r| {
                farthest = farthest.max(r.position(1)[0]);
                if r.moving(1) {
                    moving_ms += 1;
                }
            });
            let polls = r.router.governance_stats().follow_polls - polls_before;
            // A poll: `P?` out, ACK and result back.
            let per_poll = wire_ms(8, bps) + wire_ms(1, bps) + wire_ms(15, bps);
            let busy = 100.0 * (polls * per_poll) as f64 / moving_ms.max(1) as f64;
            let _ = start;
            println!(
                "{bps:>10} | SP{speed:X}   | {:>9.1} | {:>30.2} | {polls:>5} | {busy:>5.1} %",
                f64::from(12000 * (u32::from(speed) + 1) / 16) / 100.0,
                f64::from(9000 - farthest) / 100.0,
            );
        }
    }
}
