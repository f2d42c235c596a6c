use super::*;
use proptest::prelude::*;

fn parse_all(protocol: Protocol, chunks: &[&[u8]]) -> Vec<Found> {
    let mut p = Parser::new(protocol);
    let mut out = Vec::new();
    for c in chunks {
        p.feed(c, |f| out.push(f));
    }
    p.finish(|f| out.push(f));
    out
}

/// `found` with adjacent skipped runs joined (a run may come in pieces,
/// one per read).
fn joined(found: Vec<Found>) -> Vec<Found> {
    let mut out: Vec<Found> = Vec::new();
    for f in found {
        match (out.last_mut(), f) {
            (
                Some(Found::Skipped { len, checksum, .. }),
                Found::Skipped {
                    len: more,
                    checksum: bad,
                    ..
                },
            ) => {
                *len += more;
                *checksum |= bad;
            }
            (_, f) => out.push(f),
        }
    }
    out
}

fn frames(found: &[Found]) -> Vec<(u64, Frame)> {
    found
        .iter()
        .filter_map(|f| match f {
            Found::Frame { at, frame } => Some((*at, *frame)),
            Found::Skipped { .. } => None,
        })
        .collect()
}

#[test]
fn pelco_d_frames_of_the_manual_are_read() {
    // "D" Protocol manual, "Example Messages": pan left at speed 0x20 to camera 1.
    let left = [0xFF, 0x01, 0x00, 0x04, 0x20, 0x00, 0x25];
    let found = parse_all(Protocol::D, &[&left]);
    assert_eq!(
        found,
        vec![Found::Frame {
            at: 0,
            frame: Frame {
                address: 1,
                body: [0x00, 0x04, 0x20, 0x00]
            }
        }]
    );
    assert_eq!(Protocol::D.encode(1, [0x00, 0x04, 0x20, 0x00]), left);
}

#[test]
fn pelco_p_check_byte_is_the_xor_of_bytes_1_to_7_or_of_2_to_6() {
    // Tilt up at speed 0x30 to camera 2 (wire address 01).
    let manual = Protocol::P.encode(1, [0x00, 0x08, 0x00, 0x30]);
    assert_eq!(manual, [0xA0, 0x01, 0x00, 0x08, 0x00, 0x30, 0xAF, 0x36]);
    let short = [0xA0, 0x01, 0x00, 0x08, 0x00, 0x30, 0xAF, 0x39];
    assert_eq!(frames(&parse_all(Protocol::P, &[&manual, &short])).len(), 2);
    let mut bad_etx = manual.clone();
    bad_etx[6] = 0xAE;
    assert!(frames(&parse_all(Protocol::P, &[&bad_etx])).is_empty());
}

#[test]
fn a_damaged_frame_costs_its_sync_byte_and_a_frame_inside_it_is_found() {
    let good = Protocol::D.encode(1, [0, 0, 0, 0]);
    // A frame cut after 3 bytes, then a whole one: the cut one's sync byte
    // starts a 7-byte run whose check byte is wrong.
    let mut stream = good[..3].to_vec();
    stream.extend_from_slice(&good);
    let found = parse_all(Protocol::D, &[&stream]);
    assert_eq!(
        found,
        vec![
            Found::Skipped {
                at: 0,
                len: 3,
                checksum: true
            },
            Found::Frame {
                at: 3,
                frame: Frame {
                    address: 1,
                    body: [0; 4]
                }
            },
        ]
    );
}

/// A frame whose only sync byte is its first: a false frame can then
/// start only in the garbage or at a real frame's sync byte.
fn frame(protocol: Protocol) -> impl Strategy<Value = Vec<u8>> {
    (any::<u8>(), any::<[u8; 4]>())
        .prop_map(move |(a, b)| protocol.encode(a, b))
        .prop_filter("one sync byte", move |f| !f[1..].contains(&protocol.sync()))
}

/// Splits `bytes` at the cut points `cuts` (positions modulo its length).
fn split<'a>(bytes: &'a [u8], cuts: &[usize]) -> Vec<&'a [u8]> {
    let mut at: Vec<usize> = cuts.iter().map(|c| c % (bytes.len() + 1)).collect();
    at.sort_unstable();
    let mut out = Vec::new();
    let mut from = 0;
    for c in at {
        out.push(&bytes[from..c]);
        from = c;
    }
    out.push(&bytes[from..]);
    out
}

proptest! {
    /// Whatever arrives: every byte is in exactly one frame or one skipped
    /// run, in stream order, every frame reported is intact where it says
    /// it starts, and how the stream was cut into reads changes nothing.
    #[test]
    fn every_byte_is_accounted_for_and_reads_do_not_matter(
        bytes in proptest::collection::vec(any::<u8>(), 0..200),
        cuts in proptest::collection::vec(any::<usize>(), 0..8),
        pelco_p in any::<bool>(),
    ) {
        let protocol = if pelco_p { Protocol::P } else { Protocol::D };
        let whole = joined(parse_all(protocol, &[&bytes]));
        prop_assert_eq!(&joined(parse_all(protocol, &split(&bytes, &cuts))), &whole);
        let mut next = 0u64;
        for f in &whole {
            match f {
                Found::Frame { at, frame } => {
                    prop_assert_eq!(*at, next);
                    let n = protocol.frame_len();
                    let raw = &bytes[*at as usize..*at as usize + n];
                    prop_assert!(protocol.intact(raw));
                    prop_assert_eq!(raw[1], frame.address);
                    next += n as u64;
                }
                Found::Skipped { at, len, .. } => {
                    prop_assert_eq!(*at, next);
                    prop_assert!(*len > 0);
                    next += len;
                }
            }
        }
        prop_assert_eq!(next, bytes.len() as u64);
    }

    /// A frame cut short costs only its own bytes: the intact frame that
    /// follows it is found where it starts.
    #[test]
    fn a_frame_cut_short_never_hides_the_next(
        d in proptest::collection::vec(frame(Protocol::D), 2..3),
        p in proptest::collection::vec(frame(Protocol::P), 2..3),
        cut in 1usize..7,
        pelco_p in any::<bool>(),
    ) {
        let (protocol, sent) = if pelco_p { (Protocol::P, p) } else { (Protocol::D, d) };
        let mut stream = sent[0][..cut].to_vec();
        stream.extend_from_slice(&sent[1]);
        // The head and the next frame's first bytes may by chance make an
        // intact frame (1 in 256): that is a frame, not a lost one.
        prop_assume!(!protocol.intact(&stream[..protocol.frame_len()]));
        let found = frames(&parse_all(protocol, &[&stream]));
        prop_assert_eq!(found.len(), 1, "{:?}", found);
        prop_assert_eq!(found[0].0, cut as u64);
        prop_assert_eq!(&found[0].1.body[..], &sent[1][2..6]);
    }

    /// Frames behind any garbage: every frame after the first is found at
    /// its offset (garbage may borrow the first one's head for a false
    /// frame, never more than a frame's length of it).
    #[test]
    fn frames_after_garbage_are_found_at_their_offsets(
        garbage in proptest::collection::vec(any::<u8>(), 0..40),
        d in proptest::collection::vec(frame(Protocol::D), 2..6),
        p in proptest::collection::vec(frame(Protocol::P), 2..6),
        pelco_p in any::<bool>(),
    ) {
        let (protocol, sent) = if pelco_p { (Protocol::P, p) } else { (Protocol::D, d) };
        let mut stream = garbage.clone();
        let mut offsets = Vec::new();
        for f in &sent {
            offsets.push(stream.len() as u64);
            stream.extend_from_slice(f);
        }
        let found = frames(&parse_all(protocol, &[&stream]));
        for (at, f) in offsets.iter().zip(&sent).skip(1) {
            prop_assert!(
                found.iter().any(|(o, fr)| o == at && fr.address == f[1] && fr.body[..] == f[2..6]),
                "frame at {} lost: {:?}", at, found
            );
        }
        // Without a sync byte in the garbage, the first one is found too.
        let sync = if pelco_p { 0xA0 } else { 0xFF };
        if !garbage.contains(&sync) {
            prop_assert_eq!(found.len(), sent.len());
            prop_assert_eq!(found[0].0, garbage.len() as u64);
        }
    }
}
