//! Command parsing: no panic; what parses re-encodes to a payload that parses
//! to the same command; errors point inside the payload.
#![no_main]

use libfuzzer_sys::fuzz_target;
use sagebrush_protocol::{Command, CommandError, MAX_PAYLOAD};

fuzz_target!(|payload: &[u8]| {
    let command = Command::parse(payload);
    match Command::parse_strict(payload) {
        Ok(strict) => assert_eq!(strict, command),
        Err(CommandError::BadArgument { offset, found, .. }) => {
            assert!(offset <= payload.len());
            assert_eq!(found, payload.get(offset).copied());
        }
        Err(CommandError::OutOfRange { offset, .. }) => assert!(offset <= payload.len()),
        Err(CommandError::Unknown { first, len }) => {
            assert_eq!((Some(first), len), (payload.first().copied(), payload.len()))
        }
        Err(CommandError::Empty) => assert!(payload.is_empty()),
    }
    if let Command::Unknown(bytes) = command {
        assert_eq!(bytes, payload);
        return;
    }
    // Canonical forms are at most a few bytes longer (`*x0r5` -> `*x0r005`);
    // a fuzz input may be longer than any frame payload.
    let mut buf = vec![0u8; payload.len().max(MAX_PAYLOAD) + 16];
    let encoded = command.encode(&mut buf).expect("a parsed command encodes");
    assert_eq!(Command::parse(encoded), command);
    assert_eq!(Command::parse_strict(encoded), Ok(command));
});
