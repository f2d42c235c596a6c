//! Result parsing for every command that takes a result: no panic; what
//! parses encodes canonically and parses again to the same reply.
#![no_main]

use libfuzzer_sys::fuzz_target;
use sagebrush_protocol::{AuxPort, AuxReadLen, Axis, Command, Extended, MAX_PAYLOAD, Reply, ResultKind};

fn commands() -> Vec<Command<'static>> {
    let port = AuxPort::new(1).unwrap();
    let mut all = vec![
        Command::AwakeStatus,
        Command::QueryMaxDataRate,
        Command::Identify,
        Command::QueryErrors,
        Command::QueryStatusBits,
        Command::QueryRateGains,
        Command::Initialize,
        Command::QueryLimits,
        Command::QueryRelays,
        Command::QueryAccelerations,
        Command::QueryAcceleration(Axis::Pan),
        Command::QueryAcceleration(Axis::Tilt),
        Command::QueryRates,
        Command::QueryRate(Axis::Pan),
        Command::QueryRate(Axis::Tilt),
        Command::VerifyHome,
        Command::QueryPosition,
        Command::QueryPreset(0x0A),
        Command::QueryStoredPreset(0xF8),
        Command::QueryLens,
        Command::AuxCount(port),
        Command::AuxReceive(port, AuxReadLen::new(200).unwrap()),
    ];
    all.extend(
        Extended::ALL
            .iter()
            .filter(|e| e.result_kind() != ResultKind::None)
            .map(|&e| Command::Extended(e, b"")),
    );
    all
}

fuzz_target!(|payload: &[u8]| {
    for command in commands() {
        assert_ne!(command.result_kind(), ResultKind::None);
        let Ok(reply) = Reply::parse(&command, payload) else {
            continue;
        };
        assert!(reply.answers(&command), "{command:?} -> {reply:?}");
        // Lenient short forms grow (2+2 status bits -> 4+4); raw data may be
        // longer than a frame payload in a fuzz input.
        let mut buf = vec![0u8; payload.len().max(MAX_PAYLOAD) + 64];
        let encoded = reply.encode(&mut buf).expect("a parsed reply encodes");
        assert_eq!(Reply::parse(&command, encoded), Ok(reply), "{command:?}");
    }
});
