//! Property tests: codec identities, bit-flip detection, framer chunking
//! invariance, resynchronisation and robustness.

mod common;

use common::{Owned, feed_all};
use proptest::prelude::*;
use proptest::strategy::ValueTree;
use proptest::test_runner::TestRunner;
use sagebrush_protocol::*;

proptest! {
    #![proptest_config(ProptestConfig::with_cases(512))]

    #[test]
    fn frame_encode_parse_identity(
        dest in common::address(),
        source in any::<u8>(),
        payload in proptest::collection::vec(any::<u8>(), 1..=256),
        trailing in proptest::collection::vec(any::<u8>(), 0..4),
    ) {
        let frame = Frame::new(dest, source, &payload).unwrap();
        let mut buf = [0u8; MAX_FRAME_LEN];
        let wire = frame.encode(&mut buf).unwrap().to_vec();
        prop_assert_eq!(wire.len(), frame.wire_len());
        prop_assert_eq!(wire[5], payload.len() as u8);
        let mut with_rest = wire.clone();
        with_rest.extend_from_slice(&trailing);
        let (parsed, rest) = Frame::parse(&with_rest).unwrap();
        prop_assert_eq!(parsed, frame);
        prop_assert_eq!(rest, &trailing[..]);
        let owned = FrameBuf::from_frame(&frame);
        prop_assert_eq!(owned.as_bytes(), &wire[..]);
        prop_assert_eq!(owned.frame(), frame);
    }

    /// `OwnedEvent` keeps exactly what the borrowed event said, frames included.
    #[test]
    fn owned_events_match_borrowed(stream in common::stream(), chunk in 1usize..300) {
        let mut framer: Framer = Framer::new();
        let (mut owned, mut reference) = (Vec::new(), Vec::new());
        let mut record = |e: Event<'_>| {
            owned.push(OwnedEvent::from(e));
            reference.push(Owned::of(&e));
        };
        for piece in stream.chunks(chunk) {
            framer.feed(piece, &mut record);
        }
        framer.flush_idle(&mut record);
        prop_assert_eq!(owned.len(), reference.len());
        for (o, r) in owned.iter().zip(&reference) {
            prop_assert_eq!(&Owned::of(&o.as_event()), r);
            prop_assert_eq!(o, &o.as_event().to_owned());
        }
    }

    #[test]
    fn command_encode_parse_identity(command in common::command()) {
        let mut buf = [0u8; MAX_PAYLOAD];
        let payload = command.encode(&mut buf).unwrap();
        prop_assert!(!payload.is_empty() && payload.len() <= MAX_PAYLOAD);
        prop_assert_eq!(Command::parse(payload), command);
        match command {
            Command::Unknown(_) => prop_assert!(Command::parse_strict(payload).is_err()),
            _ => prop_assert_eq!(Command::parse_strict(payload), Ok(command)),
        }
        // Encoding a parsed command gives back the same bytes (canonical).
        let mut again = [0u8; MAX_PAYLOAD];
        prop_assert_eq!(Command::parse(payload).encode(&mut again).unwrap(), payload);
    }

    #[test]
    fn reply_encode_parse_identity((command, reply) in common::command_and_reply()) {
        prop_assert!(reply.answers(&command));
        let mut buf = [0u8; MAX_PAYLOAD];
        let payload = reply.encode(&mut buf).unwrap();
        prop_assert_eq!(Reply::parse(&command, payload), Ok(reply));
        // It also travels in a frame.
        let frame = FrameBuf::new(Address::new(2, 1, 12), 5, payload).unwrap();
        prop_assert_eq!(Reply::parse(&command, frame.frame().payload()), Ok(reply));
    }

    /// Any payload that parses as a command re-encodes to a payload that
    /// parses to the same command (lenient forms become canonical).
    #[test]
    fn parsed_commands_reencode(payload in proptest::collection::vec(any::<u8>(), 1..12), prefix in 0usize..24) {
        let prefixes: [&[u8]; 24] = [b"", b"#", b"A", b"AP", b"C", b"G", b"GRP", b"L", b"LS", b"P", b"P?", b"R",
            b"S", b"S?", b"V", b"VM", b"Z", b"*x0", b"*x1c,", b"*x0r", b"F", b"H", b"T", b"*s"];
        let payload = [prefixes[prefix], &payload[..]].concat();
        let command = Command::parse(&payload);
        let mut buf = [0u8; MAX_PAYLOAD];
        let encoded = command.encode(&mut buf).unwrap();
        prop_assert_eq!(Command::parse(encoded), command);
    }

    /// Arbitrary payloads never panic the reply parser; whatever parses
    /// re-encodes and parses again to the same reply (random bytes are
    /// nearly always `Raw` or refused: structured replies are
    /// `near_replies_parse_to_what_they_re_encode_to`'s).
    #[test]
    fn arbitrary_replies((command, _) in common::command_and_reply(),
                         payload in proptest::collection::vec(any::<u8>(), 0..64)) {
        if let Ok(reply) = Reply::parse(&command, &payload) {
            prop_assert!(reply.answers(&command));
            let mut buf = [0u8; MAX_PAYLOAD];
            let encoded = reply.encode(&mut buf).unwrap();
            prop_assert_eq!(Reply::parse(&command, encoded), Ok(reply));
        }
    }
}

/// Bytes a reply parser sees from a real but imperfect device: the
/// encoding of a valid reply for `command`, then up to three edits
/// (replace, insert, delete a byte, or cut the tail) with bytes drawn
/// mostly from what replies are made of (hex digits of both cases, the
/// letters replies start with). Random bytes alone almost never form a
/// structured reply, so the re-encode identity would only meet `Raw`.
fn near_reply() -> impl Strategy<Value = (Command<'static>, Reply<'static>, Vec<u8>)> {
    const ALPHABET: &[u8] = b"0123456789ABCDEFabcdefPVCLNxX- \0\xFF";
    let edit = (0u8..4, any::<prop::sample::Index>(), prop::sample::select(ALPHABET));
    (common::command_and_reply(), proptest::collection::vec(edit, 0..=3)).prop_map(|((command, reply), edits)| {
        let mut buf = [0u8; MAX_PAYLOAD];
        let mut bytes = reply.encode(&mut buf).unwrap().to_vec();
        for (kind, at, byte) in edits {
            let i = at.index(bytes.len() + 1);
            match kind {
                0 if i < bytes.len() => bytes[i] = byte,
                1 if bytes.len() < MAX_PAYLOAD => bytes.insert(i, byte),
                2 if i < bytes.len() => {
                    bytes.remove(i);
                }
                3 => bytes.truncate(i),
                _ => {}
            }
        }
        (command, reply, bytes)
    })
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(2048))]

    /// Near-valid payloads never panic the reply parser; whatever parses
    /// answers its command and re-encodes to bytes that parse to the same
    /// reply; an unedited encoding parses back to the reply it came from.
    #[test]
    fn near_replies_parse_to_what_they_re_encode_to((command, reply, payload) in near_reply()) {
        let mut buf = [0u8; MAX_PAYLOAD];
        let original = reply.encode(&mut buf).unwrap().to_vec();
        if let Ok(parsed) = Reply::parse(&command, &payload) {
            prop_assert!(parsed.answers(&command));
            let mut buf = [0u8; MAX_PAYLOAD];
            let encoded = parsed.encode(&mut buf).unwrap();
            prop_assert_eq!(Reply::parse(&command, encoded), Ok(parsed));
        }
        if payload == original {
            prop_assert_eq!(Reply::parse(&command, &payload), Ok(reply));
        }
    }
}

/// The near-reply strategy reaches what the identity is about: edited
/// payloads that still parse to structured (non-`Raw`) replies of most
/// variants, so `near_replies_parse_to_what_they_re_encode_to` checks
/// their re-encoding, not only raw bytes.
#[test]
fn near_replies_reach_structured_replies() {
    let mut runner = TestRunner::deterministic();
    let strategy = near_reply();
    let mut variants = [0u32; common::REPLY_VARIANTS];
    let mut edited_structured = 0;
    let cases = 4_000;
    for _ in 0..cases {
        let (command, reply, payload) = strategy.new_tree(&mut runner).unwrap().current();
        let mut buf = [0u8; MAX_PAYLOAD];
        let edited = reply.encode(&mut buf).unwrap() != payload.as_slice();
        if let Ok(parsed) = Reply::parse(&command, &payload) {
            if !matches!(parsed, Reply::Raw(_) | Reply::AuxData(_)) {
                variants[common::reply_index(&parsed)] += 1;
                edited_structured += u32::from(edited);
            }
        }
    }
    let reached = variants.iter().filter(|&&n| n > 0).count();
    // Raw and AuxData carry bytes as they came: every other variant is structured.
    assert!(
        reached >= common::REPLY_VARIANTS - 2,
        "structured variants reached: {variants:?}"
    );
    assert!(
        edited_structured >= cases / 20,
        "only {edited_structured} of {cases} edited payloads parsed as structured replies: {variants:?}"
    );
}

/// Every Command and Reply variant is produced by the strategies above.
#[test]
fn every_variant_is_generated() {
    let mut runner = TestRunner::deterministic();
    let mut commands = [false; common::COMMAND_VARIANTS];
    let strategy = common::command();
    for _ in 0..20_000 {
        let c = strategy.new_tree(&mut runner).unwrap().current();
        commands[common::command_index(&c)] = true;
    }
    let missing: Vec<_> = (0..common::COMMAND_VARIANTS).filter(|&i| !commands[i]).collect();
    assert!(missing.is_empty(), "command variants never generated: {missing:?}");

    let mut replies = [false; common::REPLY_VARIANTS];
    let strategy = common::command_and_reply();
    for _ in 0..5_000 {
        let (_, r) = strategy.new_tree(&mut runner).unwrap().current();
        replies[common::reply_index(&r)] = true;
    }
    let missing: Vec<_> = (0..common::REPLY_VARIANTS).filter(|&i| !replies[i]).collect();
    assert!(missing.is_empty(), "reply variants never generated: {missing:?}");
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(256))]

    /// A single bit flip anywhere in a frame is always detected: a bit flip
    /// changes the byte sum by +-2^k, never 0 mod 256, so with the span
    /// unchanged the checksum cannot hold. A flip in the length byte changes
    /// the span: the bytes then never parse as one frame over the whole
    /// input, and never as the original frame.
    #[test]
    fn single_bit_flips_are_detected(wire in common::frame_bytes(), bit in 0usize..8 * MAX_FRAME_LEN) {
        let bit = bit % (wire.len() * 8);
        let (original, _) = Frame::parse(&wire).unwrap();
        let mut flipped = wire.clone();
        flipped[bit / 8] ^= 1 << (bit % 8);
        let byte = bit / 8;
        match Frame::parse(&flipped) {
            Ok((frame, rest)) => {
                prop_assert_eq!(byte, 5, "only a length flip can give a frame at all");
                prop_assert!(!rest.is_empty(), "a shorter frame, never one spanning the input");
                prop_assert_ne!(frame, original);
            }
            Err(FrameError::BadStart { .. }) => prop_assert_eq!(byte, 0),
            Err(FrameError::BadChecksum { .. }) => prop_assert!(byte != 0),
            Err(FrameError::Incomplete { .. }) => prop_assert_eq!(byte, 5),
            Err(e) => prop_assert!(false, "{e:?}"),
        }
        // The framer never yields the original frame from the flipped bytes,
        // and for a flip outside the start and length bytes it reports the
        // candidate as a bad checksum first.
        let mut framer: Framer = Framer::new();
        let events = feed_all(&mut framer, &[&flipped]);
        let original = Owned::of(&Event::Frame(original));
        prop_assert!(!events.contains(&original));
        if byte != 0 && byte != 5 {
            prop_assert!(matches!(events.first(), Some(Owned::Bad(b)) if b.offset == 0), "{:?}", events);
        }
    }
}

/// Events and counters of one run.
#[derive(Debug, PartialEq)]
struct Run {
    events: Vec<Owned>,
    stats: FramerStats,
    offset: u64,
}

fn run_feed(stream: &[u8], chunk: usize) -> Run {
    let mut framer: Framer = Framer::new();
    let chunks: Vec<&[u8]> = stream.chunks(chunk).collect();
    let events = feed_all(&mut framer, &chunks);
    assert_eq!(framer.buffered(), 0);
    Run {
        events,
        stats: framer.stats(),
        offset: framer.stream_offset(),
    }
}

fn drain<const N: usize>(framer: &mut Framer<N>, events: &mut Vec<Owned>) {
    while let Some(e) = framer.next_event() {
        events.push(Owned::of(&e));
    }
}

fn run_push<const N: usize>(stream: &[u8], chunk: usize) -> Run {
    let mut framer: Framer<N> = Framer::new();
    let mut events = Vec::new();
    for mut piece in stream.chunks(chunk) {
        while !piece.is_empty() {
            let n = framer.push(piece);
            piece = &piece[n..];
            drain(&mut framer, &mut events);
        }
    }
    framer.line_idle();
    drain(&mut framer, &mut events);
    assert_eq!(framer.buffered(), 0);
    Run {
        events,
        stats: framer.stats(),
        offset: framer.stream_offset(),
    }
}

fn run_dma(stream: &[u8], chunk: usize) -> Run {
    let mut framer: Framer = Framer::new();
    let mut events = Vec::new();
    let mut rest = stream;
    while !rest.is_empty() {
        let spare = framer.spare_capacity_mut();
        assert!(!spare.is_empty(), "a drained framer always has room");
        let n = spare.len().min(chunk).min(rest.len());
        spare[..n].copy_from_slice(&rest[..n]);
        framer.commit(n);
        rest = &rest[n..];
        drain(&mut framer, &mut events);
    }
    framer.flush_idle(|e| events.push(Owned::of(&e)));
    Run {
        events,
        stats: framer.stats(),
        offset: framer.stream_offset(),
    }
}

/// skipped + bytes of the events = every byte of the stream.
fn accounts_for_every_byte(run: &Run, len: usize) {
    let event_bytes: usize = run.events.iter().map(Owned::wire_len).sum();
    assert_eq!(run.stats.skipped_bytes as usize + event_bytes, len, "{run:?}");
    assert_eq!(run.offset as usize, len);
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(48))]

    /// Every chunking from 1 to 300 bytes, through `feed`, `push` +
    /// `next_event` and `spare_capacity_mut` + `commit`, gives the same
    /// events and counters as the whole stream at once.
    #[test]
    fn framer_is_chunking_invariant(stream in common::stream()) {
        let reference = run_feed(&stream, stream.len().max(1));
        accounts_for_every_byte(&reference, stream.len());
        for chunk in 1..=300 {
            prop_assert_eq!(&run_feed(&stream, chunk), &reference, "feed, chunk {}", chunk);
            prop_assert_eq!(&run_push::<526>(&stream, chunk), &reference, "push, chunk {}", chunk);
            prop_assert_eq!(&run_dma(&stream, chunk), &reference, "dma, chunk {}", chunk);
        }
        // The smallest framer that holds one frame behaves the same.
        prop_assert_eq!(&run_push::<263>(&stream, 7), &reference);
        prop_assert_eq!(&run_push::<263>(&stream, 300), &reference);
    }
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(512))]

    /// A frame after garbage that holds no 0xF8 is always recovered.
    #[test]
    fn frame_after_garbage_is_recovered(
        garbage in proptest::collection::vec(any::<u8>().prop_filter("no start byte", |b| *b != START), 0..600),
        wire in common::frame_bytes(),
        chunk in 1usize..64,
    ) {
        let stream = [&garbage[..], &wire[..]].concat();
        let run = run_feed(&stream, chunk);
        let (frame, _) = Frame::parse(&wire).unwrap();
        let expected = Owned::of(&Event::Frame(frame));
        prop_assert_eq!(run.events.last(), Some(&expected));
        let bare = garbage.iter().filter(|b| [ACK, NAK, NIC].contains(b)).count();
        prop_assert_eq!(run.events.len(), bare + 1);
        prop_assert_eq!(run.stats.skipped_bytes as usize, garbage.len() - bare);
        prop_assert_eq!(run.stats.bad_checksums, 0);
    }

    /// Arbitrary bytes never panic or stall the framer: after them and the
    /// silence hook the buffer is empty, and the next frame is recovered.
    #[test]
    fn arbitrary_bytes_never_stall(
        noise in proptest::collection::vec(any::<u8>(), 0..1200),
        chunk in 1usize..300,
        wire in common::frame_bytes(),
    ) {
        let run = run_feed(&noise, chunk);
        accounts_for_every_byte(&run, noise.len());
        prop_assert_eq!(&run_push::<526>(&noise, chunk), &run);

        let mut framer: Framer = Framer::new();
        let chunks: Vec<&[u8]> = noise.chunks(chunk).collect();
        feed_all(&mut framer, &chunks);
        prop_assert_eq!(framer.buffered(), 0);
        let mut after = Vec::new();
        framer.feed(&wire, |e| after.push(Owned::of(&e)));
        let (frame, _) = Frame::parse(&wire).unwrap();
        prop_assert_eq!(after, vec![Owned::of(&Event::Frame(frame))]);
        prop_assert_eq!(framer.buffered(), 0);

        // The same through push/next_event.
        let mut framer: Framer = Framer::new();
        let mut events = Vec::new();
        for piece in noise.chunks(chunk) {
            let mut piece = piece;
            while !piece.is_empty() {
                let n = framer.push(piece);
                piece = &piece[n..];
                drain(&mut framer, &mut events);
            }
        }
        framer.line_idle();
        drain(&mut framer, &mut events);
        prop_assert_eq!(framer.buffered(), 0);
        events.clear();
        prop_assert_eq!(framer.push(&wire), wire.len());
        drain(&mut framer, &mut events);
        prop_assert_eq!(events, vec![Owned::of(&Event::Frame(frame))]);
    }

    /// Arbitrary payloads never panic the command parser, and every error
    /// points inside (or just past) the payload.
    #[test]
    fn arbitrary_commands_never_panic(payload in proptest::collection::vec(any::<u8>(), 0..300)) {
        match Command::parse_strict(&payload) {
            Ok(command) => {
                let mut buf = [0u8; 512];
                let encoded = command.encode(&mut buf).unwrap();
                prop_assert_eq!(Command::parse(encoded), command);
            }
            Err(CommandError::BadArgument { offset, found, .. }) => {
                prop_assert!(offset <= payload.len());
                prop_assert_eq!(found, payload.get(offset).copied());
            }
            Err(CommandError::OutOfRange { offset, .. }) => prop_assert!(offset <= payload.len()),
            Err(CommandError::Unknown { first, len }) => prop_assert_eq!((first, len), (payload[0], payload.len())),
            Err(CommandError::Empty) => prop_assert!(payload.is_empty()),
        }
    }
}

#[test]
fn reset_drops_and_counts() {
    let mut framer: Framer = Framer::new();
    framer.feed(&[0xF8, 1, 2, 3], |_| panic!("nothing complete"));
    assert_eq!(framer.buffered(), 4);
    framer.reset();
    assert_eq!(framer.buffered(), 0);
    assert_eq!(framer.stats().abandoned, 1);
    assert_eq!(framer.skipped_bytes(), 4);
    assert_eq!(framer.stream_offset(), 4);
    let mut got = 0;
    framer.feed(&[0x06], |e| {
        assert_eq!(e, Event::Ack);
        got += 1
    });
    assert_eq!(got, 1);
}

/// `line_idle` followed by new bytes through `feed` must not leave the
/// framer "idle": a partial frame fed afterwards waits for its rest.
#[test]
fn feed_after_idle_waits_for_the_rest() {
    let wire = [0xF8, 0x05, 0x01, 0x0C, 0x02, 0x02, 0x50, 0x3F, 0xA5];
    let mut framer: Framer = Framer::new();
    framer.flush_idle(|_| {});
    framer.feed(&wire[..4], |_| panic!("incomplete"));
    assert!(framer.next_event().is_none());
    assert_eq!(framer.buffered(), 4, "the partial frame is kept, not abandoned");
    let mut frames = 0;
    framer.feed(&wire[4..], |e| {
        assert!(matches!(e, Event::Frame(f) if f.payload() == b"P?"));
        frames += 1;
    });
    assert_eq!(frames, 1);
    assert_eq!(framer.stats().abandoned, 0);
}
