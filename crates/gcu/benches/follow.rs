//! How close a followed slew comes to a travel limit, and what following
//! and learning cost the bus (issues 32 and 48's figures): for each line
//! rate and proportional speed, a simulated gimbal (60 deg/s at `SP7`, 120
//! deg/s at `SPF`, 120 deg/s^2) is sent the everyday jog (`SPn`, then `PR`
//! at once) toward a pan limit 90 degrees away, with the bus losing no stop
//! frame and then one; the table gives where it came to rest (on the bus
//! side: negative is past the limit), how long the slew waited while gcud
//! learnt the new rate and the bus time that took, and the share of the bus
//! the position polls took while it moved.
//!
//! `cargo bench -p sagebrush-gcu --bench follow`

#[path = "../tests/rig/mod.rs"]
mod rig;

use rig::{ONE, PORT, Rig, gimbal};
use sagebrush_gcu::{GimbalRules, Span};
use sagebrush_protocol::link::wire_ms;
use sagebrush_protocol::{Axis, Command, Speed};

/// One jog at `speed` on a line at `bps`, the bus losing `lost` stop frames.
struct Run {
    rests_short: f64,
    waited_ms: u64,
    learning_ms: u64,
    polls: u64,
    busy: f64,
}

fn jog(bps: u32, speed: u8, lost: usize) -> Run {
    let mut r = Rig::new(bps, vec![gimbal(1)], |c| {
        let mut rules = GimbalRules::new(PORT, 1);
        rules.pan_limits = Some(Span::new(-9000, 9000));
        c.governance.gimbals.push(rules);
    });
    r.client(ONE, "bench", 50);
    r.run(5000);
    r.lose = vec![b"PS".to_vec(); lost];
    let polls_before = r.router.governance_stats().follow_polls;
    let start = r.now;
    r.send(ONE, 1, &Command::SetSpeed(Axis::Pan, Speed::new(speed).expect("speed")));
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
    // From the speed change on the bus to the slew on the bus: gcud's own
    // queries between them are what it learnt first.
    let log: Vec<(u64, String)> = r
        .bus_log
        .iter()
        .filter(|(t, _, _)| *t >= start)
        .map(|(t, _, p)| (*t, String::from_utf8_lossy(p).into_owned()))
        .collect();
    let sp = log.iter().find(|(_, p)| p.starts_with("SP")).map_or(start, |(t, _)| *t);
    let pr = log.iter().find(|(_, p)| p == "PR").map_or(sp, |(t, _)| *t);
    let learning_ms = log
        .iter()
        .filter(|(t, p)| *t > sp && *t < pr && p.ends_with('?'))
        .map(|(_, p)| wire_ms(7 + p.len(), bps) + wire_ms(1, bps) + wire_ms(15, bps))
        .sum();
    Run {
        rests_short: f64::from(9000 - farthest) / 100.0,
        waited_ms: pr - sp,
        learning_ms,
        polls,
        busy,
    }
}

fn main() {
    println!(
        "line bit/s | speed | top deg/s | rests short (deg) | one stop lost (deg) | slew waited (ms) | learning on the bus (ms) | polls | bus busy polling while moving"
    );
    for bps in [9600u32, 19_200, 38_400, 115_200] {
        for speed in [3u8, 7, 11, 15] {
            let clean = jog(bps, speed, 0);
            let lossy = jog(bps, speed, 1);
            println!(
                "{bps:>10} | SP{speed:X}   | {:>9.1} | {:>17.2} | {:>19.2} | {:>16} | {:>24} | {:>5} | {:>5.1} %",
                f64::from(12000 * (u32::from(speed) + 1) / 16) / 100.0,
                clean.rests_short,
                lossy.rests_short,
                clean.waited_ms,
                clean.learning_ms,
                clean.polls,
                clean.busy,
            );
        }
    }
}
