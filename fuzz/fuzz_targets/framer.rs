//! The framer on arbitrary bytes in arbitrary chunkings: no panic, every
//! byte accounted for (skipped + bytes of the events == input), nothing left
//! buffered after the silence hook, and `feed` and `push`/`next_event` agree.
#![no_main]

use libfuzzer_sys::fuzz_target;
use sagebrush_protocol::{BadChecksum, Event, Framer};

#[derive(Debug, PartialEq)]
enum Seen {
    Frame([u8; 4], Vec<u8>),
    Ack,
    Nak,
    Nic,
    Bad(BadChecksum),
}

impl Seen {
    fn of(event: &Event<'_>) -> Self {
        match event {
            Event::Frame(f) => Seen::Frame(
                [f.dest.group, f.dest.port, f.dest.device, f.source],
                f.payload().to_vec(),
            ),
            Event::Ack => Seen::Ack,
            Event::Nak => Seen::Nak,
            Event::Nic => Seen::Nic,
            Event::BadChecksum(b) => Seen::Bad(*b),
        }
    }

    fn wire_len(&self) -> usize {
        match self {
            Seen::Frame(_, payload) => payload.len() + 7,
            Seen::Ack | Seen::Nak | Seen::Nic => 1,
            Seen::Bad(_) => 0,
        }
    }
}

/// Chunk lengths 1..=300 taken from the control bytes, cycled.
fn chunks<'d>(control: &[u8], mut data: &'d [u8]) -> Vec<&'d [u8]> {
    let mut out = Vec::new();
    let mut i = 0;
    while !data.is_empty() {
        let n = match control.get(i % control.len().max(1)) {
            Some(&c) => usize::from(c) + 1 + usize::from(c & 0x30),
            None => data.len(),
        }
        .min(data.len());
        out.push(&data[..n]);
        data = &data[n..];
        i += 1;
    }
    out
}

fuzz_target!(|input: &[u8]| {
    let split = usize::from(input.first().copied().unwrap_or(0) % 8);
    let (control, data) = input
        .get(1..)
        .unwrap_or(&[])
        .split_at(split.min(input.len().saturating_sub(1)));
    let pieces = chunks(control, data);

    // feed, zero copy.
    let mut framer: Framer = Framer::new();
    let mut fed = Vec::new();
    for piece in &pieces {
        framer.feed(piece, |e| fed.push(Seen::of(&e)));
    }
    framer.flush_idle(|e| fed.push(Seen::of(&e)));
    assert_eq!(framer.buffered(), 0, "the silence hook drains the buffer");
    let event_bytes: usize = fed.iter().map(Seen::wire_len).sum();
    assert_eq!(
        framer.skipped_bytes() as usize + event_bytes,
        data.len(),
        "every byte accounted for"
    );
    assert_eq!(framer.stream_offset() as usize, data.len());

    // push + next_event, same chunks.
    let mut framer: Framer = Framer::new();
    let mut pushed = Vec::new();
    for piece in &pieces {
        let mut piece = *piece;
        while !piece.is_empty() {
            let n = framer.push(piece);
            assert!(n > 0, "a drained framer always takes bytes");
            piece = &piece[n..];
            while let Some(e) = framer.next_event() {
                pushed.push(Seen::of(&e));
            }
        }
    }
    framer.line_idle();
    while let Some(e) = framer.next_event() {
        pushed.push(Seen::of(&e));
    }
    assert_eq!(framer.buffered(), 0);
    assert_eq!(fed, pushed, "feed and push agree");
});
