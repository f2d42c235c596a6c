//! A keyboard written here for what pyptzcontroller does not speak:
//! Pelco-P over TCP, Pelco-D over UDP, and damaged frames.

use super::*;

/// Pelco-P: tilt up (data 2 bit 3) at speed 20, held, then the stop; the
/// tilt query's answer (`5B`) is the gimbal's tilt as the bus has it.
#[test]
fn pelco_p_over_tcp_drives_stops_and_answers_the_tilt_query() {
    let stack = Stack::start();
    let mut kb = tcp_keyboard(stack.p_tcp);
    let start = stack.position();
    let up = pelco_p(0, [0x00, 0x08, 0x00, 0x20]);
    hold(&mut |f| send_tcp(&mut kb, f), &up, 1.0);
    let moved = stack.position();
    assert!(moved.1 > start.1 + 0.5, "tilt up: {start:?} -> {moved:?}");
    send_tcp(&mut kb, &pelco_p(0, [0; 4]));
    support::door::wait_for_stop(&stack.gcud, MAST, DOOR_GROUP, "TS");
    let (_, tilt) = stack.settled();
    send_tcp(&mut kb, &pelco_p(0, [0x00, 0x53, 0x00, 0x00]));
    let answer = read_answer(&mut kb, 8);
    assert_eq!(&answer[..4], &[0xA0, 0x00, 0x00, 0x5B], "{answer:02X?}");
    assert_eq!(answer[6], 0xAF);
    assert_eq!(
        answer[7],
        answer[..7].iter().fold(0, |x, b| x ^ b),
        "XOR of bytes 1 to 7"
    );
    let h = u16::from_be_bytes([answer[4], answer[5]]);
    let asked = if h > 18_000 {
        f64::from(36_000 - h) / 100.0
    } else {
        -f64::from(h) / 100.0
    };
    assert!((asked - tilt).abs() < 0.02, "answered {asked}, the bus has {tilt}");
    // A frame to another camera on the bus moves nothing.
    let other = pelco_p(4, [0x00, 0x08, 0x00, 0x20]);
    let at = stack.settled();
    hold(&mut |f| send_tcp(&mut kb, f), &other, 0.5);
    support::door::assert_still(&stack.gcud, MAST, at, "a frame to camera 5");
}

/// Pelco-D over UDP: pan left (command 2 bit 2) in turbo, held, then the
/// stop; the pan query's answer goes to the datagram's source.
#[test]
fn pelco_d_over_udp_drives_stops_and_answers_the_pan_query_to_its_source() {
    let stack = Stack::start();
    let kb = udp_keyboard();
    let door = ("127.0.0.1", stack.d_udp);
    let start = stack.position();
    let left = pelco_d(1, [0x00, 0x04, 0xFF, 0x00]);
    hold(&mut |f| drop(kb.send_to(f, door)), &left, 1.0);
    let moved = stack.position();
    assert!(moved.0 < start.0 - 1.0, "pan left: {start:?} -> {moved:?}");
    let frames = stack.door_frames();
    assert!(
        frames.iter().any(|p| p == "SPF"),
        "turbo is the fastest speed: {frames:?}"
    );
    kb.send_to(&pelco_d(1, [0; 4]), door).expect("send");
    support::door::wait_for_stop(&stack.gcud, MAST, DOOR_GROUP, "PS");
    let (pan, _) = stack.settled();
    kb.send_to(&pelco_d(1, [0x00, 0x51, 0x00, 0x00]), door).expect("send");
    let mut answer = [0u8; 16];
    let (n, from) = kb.recv_from(&mut answer).expect("an answer");
    assert_eq!(from.port(), stack.d_udp);
    assert_eq!(n, 7);
    assert_eq!(&answer[..4], &[0xFF, 0x01, 0x00, 0x59], "{:02X?}", &answer[..n]);
    let h = u16::from_be_bytes([answer[4], answer[5]]);
    let asked = f64::from(h) / 100.0;
    let want = if pan < 0.0 { pan + 360.0 } else { pan };
    assert!((asked - want).abs() < 0.02, "answered {asked}, the bus has {pan}");
}

/// Noise, a frame with a wrong check byte and a frame cut short move
/// nothing and are logged with their byte offsets; the frame after them is
/// carried out.
#[test]
fn damaged_frames_move_nothing_and_are_logged_with_their_offsets() {
    let stack = Stack::start();
    let mut kb = tcp_keyboard(stack.d_tcp);
    let at = stack.settled();
    let mut bad = pelco_d(1, [0x00, 0x02, 0x3F, 0x00]);
    bad[6] ^= 0x55;
    let mut stream = b"noise".to_vec();
    stream.extend_from_slice(&bad);
    stream.extend_from_slice(&pelco_d(1, [0x00, 0x02, 0x3F, 0x00])[..4]);
    for _ in 0..10 {
        send_tcp(&mut kb, &stream);
        std::thread::sleep(Duration::from_millis(50));
    }
    support::door::assert_still(&stack.gcud, MAST, at, "damaged frames");
    let line = support::wait_for_log_line(&stack.door.log_path(), "skipped");
    assert!(line.contains("at byte offset 0"), "{line}");
    // Then an intact query, found in the middle of the stream.
    send_tcp(&mut kb, &pelco_d(1, [0x00, 0x51, 0x00, 0x00]));
    let answer = read_answer(&mut kb, 7);
    assert_eq!(&answer[..4], &[0xFF, 0x01, 0x00, 0x59], "{answer:02X?}");
    assert!(
        !stack.door_frames().iter().any(|p| p == "PR"),
        "{:?}",
        stack.door_frames()
    );
}
