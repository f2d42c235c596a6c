//! `cargo bench --bench mavlink`: gimbal-mavlink measured with real
//! processes on 127.0.0.1 (issue 25's figures): `gimbalsim --tcp` <- a
//! relay that watches the bus bytes <- gcud (the relay is its `tcp` port)
//! <- gimbal-mavlink <- MAVLink 2 over UDP (written with the `mavlink`
//! crate):
//! 1. MAV_CMD_DO_GIMBAL_MANAGER_PITCHYAW with a yaw rate: from the
//!    datagram's send to the first byte of its motion command (`PR`/`PL`)
//!    reaching the bus, p50/p99 of `MAVLINK_BENCH_MOVES` moves (default
//!    100), each followed by a zero rate (a stop) and its ACK;
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

use door::{addr_in, env_count, log_line};
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

fn main() {
    let mut stack = door::Stack::start(env!("CARGO_BIN_EXE_gimbalsim"), env!("CARGO_BIN_EXE_gcud"));
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
    let ack = |incoming: &mpsc::Receiver<(Instant, MavMessage)>| loop {
        let (_, m) = incoming.recv_timeout(Duration::from_secs(30)).expect("COMMAND_ACK");
        if let MavMessage::COMMAND_ACK(a) = m {
            assert_eq!(a.result, MavResult::MAV_RESULT_ACCEPTED, "{a:?}");
            return;
        }
    };

    let moves = env_count("MAVLINK_BENCH_MOVES", 100);
    let mut latencies = Vec::with_capacity(moves);
    for i in 0..moves {
        while stack.motions.try_recv().is_ok() {}
        while incoming.try_recv().is_ok() {}
        let sent = Instant::now();
        gcs.yaw_rate(if i % 2 == 0 { 30.0 } else { -30.0 });
        let on_bus = stack
            .motions
            .recv_timeout(Duration::from_secs(30))
            .expect("the motion on the bus");
        latencies.push(on_bus.saturating_duration_since(sent));
        ack(&incoming);
        gcs.yaw_rate(0.0);
        ack(&incoming);
    }
    latencies.sort();
    println!(
        "MAV_CMD_DO_GIMBAL_MANAGER_PITCHYAW (yaw rate) -> first motion byte on the bus ({moves} moves): p50 {:.2} ms, p99 {:.2} ms",
        percentile(&latencies, 0.5).as_secs_f64() * 1e3,
        percentile(&latencies, 0.99).as_secs_f64() * 1e3
    );

    let window = Duration::from_secs(env_count("MAVLINK_BENCH_SECONDS", 10) as u64);
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
