//! `cargo bench --bench mavlink`: gimbal-mavlink measured with real
//! processes on 127.0.0.1 (issue 25's figures): `gimbalsim --tcp` <- a
//! relay that watches the bus bytes <- gcud (the relay is its `tcp` port)
//! <- gimbal-mavlink <- MAVLink 2 over UDP (written with the `mavlink`
//! crate):
//! 1. MAV_CMD_DO_GIMBAL_MANAGER_PITCHYAW with a yaw rate (its size
//!    changing every move): from the datagram's send to the first byte of
//!    the direction command that runs the pan at that rate
//!    (`door::pan_at_speed`), p50/p99 of `MAVLINK_BENCH_MOVES` moves
//!    (default 100), each followed by a zero rate (a stop), timed to its
//!    pan stop's first byte; then the same on a bus paced at 9600 and at
//!    115200 bit/s (`MAVLINK_BENCH_PACED_MOVES`, default 50), beside the
//!    line-time limit of the bytes needed (issue 35);
//! 2. GIMBAL_DEVICE_ATTITUDE_STATUS: the rate and the jitter (gaps between
//!    arrivals, p50/p99/max against the configured 200 ms) over
//!    `MAVLINK_BENCH_SECONDS` (default 10).
//!
//! Figures are printed, never asserted: the machines are shared and noisy.

#[path = "support/door.rs"]
mod door;
#[allow(dead_code)] // TRANSACTION_BYTES is for the bus benchmarks
mod support;

use std::net::UdpSocket;
use std::sync::mpsc;
use std::time::{Duration, Instant};

use door::{MOTION_BYTES, STOP_BYTES, addr_in, env_count, log_line, report};
use mavlink::dialects::common::{COMMAND_LONG_DATA, HEARTBEAT_DATA, MavCmd, MavMessage, MavResult};
use mavlink::{MavHeader, MavlinkVersion};
use support::percentile;

/// A ground station: sends as system 255, component 190.
struct Gcs {
    socket: UdpSocket,
    to: String,
    sequence: u8,
}

impl Gcs {
    fn send(&mut self, message: &MavMessage) {
        let header = MavHeader {
            system_id: 255,
            component_id: 190,
            sequence: self.sequence,
        };
        self.sequence = self.sequence.wrapping_add(1);
        let mut bytes = Vec::new();
        mavlink::write_versioned_msg(&mut bytes, MavlinkVersion::V2, header, message).expect("encode");
        self.socket.send_to(&bytes, &self.to).expect("send");
    }

    fn yaw_rate(&mut self, dps: f32) {
        self.send(&MavMessage::COMMAND_LONG(COMMAND_LONG_DATA {
            param1: f32::NAN,
            param2: f32::NAN,
            param3: f32::NAN,
            param4: dps,
            param5: 0.0,
            param6: 0.0,
            param7: 0.0,
            command: MavCmd::MAV_CMD_DO_GIMBAL_MANAGER_PITCHYAW,
            target_system: 1,
            target_component: 154,
            confirmation: 0,
        }));
    }
}

/// What arrives, with its arrival time.
fn receive(socket: UdpSocket, out: mpsc::Sender<(Instant, MavMessage)>) {
    let mut buf = [0u8; 2048];
    while let Ok(n) = socket.recv(&mut buf) {
        let at = Instant::now();
        let mut reader = mavlink::MavlinkReader::new(&buf[..n]);
        while let Ok((_, m)) = reader.read_any_message::<MavMessage>() {
            if out.send((at, m)).is_err() {
                return;
            }
        }
    }
}

/// gimbal-mavlink in front of `stack`'s gcud, a ground station talking to
/// it and what it receives, once the first attitude status came.
fn door(stack: &mut door::Stack) -> (Gcs, mpsc::Receiver<(Instant, MavMessage)>) {
    let clients = stack.clients.clone();
    let log = stack.door(
        env!("CARGO_BIN_EXE_gimbal-mavlink"),
        "gimbal-mavlink",
        &format!(
            "gcud = \"{clients}\"\nsystem_id = 1\nlease_ms = 60000\n[[endpoint]]\nudp_listen = \"127.0.0.1:0\"\n\
             [[gimbal]]\nname = \"bench\"\naddress = \"5.1.1\"\ncomponent_id = 154\n"
        ),
    );
    let to = addr_in(&log_line(&log, "MAVLink UDP endpoint bound"));
    let socket = UdpSocket::bind("127.0.0.1:0").expect("bind");
    let (in_tx, incoming) = mpsc::channel();
    let reader = socket.try_clone().expect("clone");
    std::thread::spawn(move || receive(reader, in_tx));
    let mut gcs = Gcs {
        socket,
        to,
        sequence: 0,
    };
    gcs.send(&MavMessage::HEARTBEAT(HEARTBEAT_DATA::default()));
    // Warm up: the first attitude status means gcud answered a poll.
    loop {
        let (_, m) = incoming.recv_timeout(Duration::from_secs(30)).expect("attitude status");
        if matches!(m, MavMessage::GIMBAL_DEVICE_ATTITUDE_STATUS(_)) {
            break;
        }
    }
    (gcs, incoming)
}

/// Waits for the ACCEPTED COMMAND_ACK.
fn ack(incoming: &mpsc::Receiver<(Instant, MavMessage)>) {
    loop {
        let (_, m) = incoming.recv_timeout(Duration::from_secs(30)).expect("COMMAND_ACK");
        if let MavMessage::COMMAND_ACK(a) = m {
            assert_eq!(a.result, MavResult::MAV_RESULT_ACCEPTED, "{a:?}");
            return;
        }
    }
}

/// `moves` yaw rates, each followed by a zero rate: from the rate's
/// datagram to the direction at that rate on the bus, and from the zero
/// rate's to the pan stop.
fn moves(
    stack: &door::Stack,
    gcs: &mut Gcs,
    incoming: &mpsc::Receiver<(Instant, MavMessage)>,
    moves: usize,
) -> (Vec<Duration>, Vec<Duration>) {
    let (mut to_motion, mut to_stop) = (Vec::with_capacity(moves), Vec::with_capacity(moves));
    let quiet = Duration::from_millis(300);
    for i in 0..moves {
        stack.drain();
        while incoming.try_recv().is_ok() {}
        let sent = Instant::now();
        gcs.yaw_rate(if i % 2 == 0 { 30.0 } else { -50.0 });
        let heard = stack.heard(quiet);
        let at = door::pan_at_speed(&heard).unwrap_or_else(|| panic!("no pan motion on the bus: {heard:?}"));
        to_motion.push(at.saturating_duration_since(sent));
        ack(incoming);
        let sent = Instant::now();
        gcs.yaw_rate(0.0);
        let heard = stack.heard(quiet);
        let at = door::pan_stop(&heard).unwrap_or_else(|| panic!("no pan stop on the bus: {heard:?}"));
        to_stop.push(at.saturating_duration_since(sent));
        ack(incoming);
    }
    (to_motion, to_stop)
}

fn main() {
    let mut stack = door::Stack::start(env!("CARGO_BIN_EXE_gimbalsim"), env!("CARGO_BIN_EXE_gcud"));
    let (mut gcs, incoming) = door(&mut stack);
    println!("1. to the first byte on the bus, gcud's port a TCP device server (gimbalsim):");
    let (to_motion, to_stop) = moves(&stack, &mut gcs, &incoming, env_count("MAVLINK_BENCH_MOVES", 100));
    report(
        "PITCHYAW yaw rate -> first byte at speed",
        None,
        MOTION_BYTES,
        to_motion,
    );
    report("zero rate -> first pan stop byte", None, STOP_BYTES, to_stop);
    for baud in [9600, 115_200] {
        let mut paced = door::Stack::paced(env!("CARGO_BIN_EXE_gcud"), baud);
        let (mut paced_gcs, paced_incoming) = door(&mut paced);
        println!("   on a bus paced at {baud} bit/s:");
        let n = env_count("MAVLINK_BENCH_PACED_MOVES", 50);
        let (to_motion, to_stop) = moves(&paced, &mut paced_gcs, &paced_incoming, n);
        report(
            "PITCHYAW yaw rate -> first byte at speed",
            Some(baud),
            MOTION_BYTES,
            to_motion,
        );
        report("zero rate -> first pan stop byte", Some(baud), STOP_BYTES, to_stop);
    }

    let window = Duration::from_secs(env_count("MAVLINK_BENCH_SECONDS", 10) as u64);
    // What arrived while the paced runs went is not this window's.
    while incoming.try_recv().is_ok() {}
    let started = Instant::now();
    let mut arrivals = Vec::new();
    while started.elapsed() < window {
        if let Ok((at, MavMessage::GIMBAL_DEVICE_ATTITUDE_STATUS(_))) =
            incoming.recv_timeout(Duration::from_millis(100))
        {
            arrivals.push(at);
        }
        if arrivals.len() % 5 == 0 {
            // Stay a heard peer (a ground station sends its heartbeat).
            gcs.send(&MavMessage::HEARTBEAT(HEARTBEAT_DATA::default()));
        }
    }
    let mut gaps: Vec<Duration> = arrivals.windows(2).map(|w| w[1] - w[0]).collect();
    gaps.sort();
    let nominal = 0.2;
    let worst = gaps
        .iter()
        .map(|g| (g.as_secs_f64() - nominal).abs())
        .fold(0.0, f64::max);
    println!(
        "GIMBAL_DEVICE_ATTITUDE_STATUS ({} s, configured 5 Hz): {:.2} Hz; gaps p50 {:.1} ms, p99 {:.1} ms, largest deviation from 200 ms {:.1} ms",
        window.as_secs(),
        arrivals.len() as f64 / started.elapsed().as_secs_f64(),
        percentile(&gaps, 0.5).as_secs_f64() * 1e3,
        percentile(&gaps, 0.99).as_secs_f64() * 1e3,
        worst * 1e3
    );
}
