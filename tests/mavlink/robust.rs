//! Stops, bad input, and the byte streams (TCP, a serial line).

use serde_json::json;

use super::*;

#[test]
fn sigkill_of_gimbal_mavlink_mid_slew_and_the_gimbal_stops() {
    if !client_available() {
        return;
    }
    // A 60 s lease: however long a busy machine takes to kill
    // gimbal-mavlink, only gcud's dead-man can stop the 30 °/s slew.
    let mut stack = Stack::start_with_lease(60_000);
    let r = stack.gcs("pitchyaw", GCS, json!({ "yaw_rate": 30.0 }));
    assert_eq!(r["result"], ACCEPTED, "{r}");
    stack.wait_moving((0.0, 0.0));
    let status = stack.signal(nix::sys::signal::Signal::SIGKILL);
    assert!(!status.success());
    support::door::assert_dead_man_stopped(&stack.gcud, MAST);
}

#[test]
fn sigterm_stops_the_slew_gimbal_mavlink_started() {
    if !client_available() {
        return;
    }
    let mut stack = Stack::start_with_lease(60_000);
    // A 60 s lease: only gimbal-mavlink's own stop at SIGTERM ends it early.
    let r = stack.gcs("pitchyaw", GCS, json!({ "pitch_rate": 20.0 }));
    assert_eq!(r["result"], ACCEPTED, "{r}");
    stack.wait_moving((0.0, 0.0));
    let status = stack.signal(nix::sys::signal::Signal::SIGTERM);
    assert!(status.success(), "{status:?}");
    // gimbal-mavlink stopped it itself, on the bus: its TS after the TU,
    // and nothing from gcud's group (its dead-man) once its connection closed.
    support::door::wait_for_stop(&stack.gcud, MAST, DOOR_GROUP, "TS");
    support::door::assert_no_stop_from_gcud(&stack.gcud, MAST);
    // Where that TS put it, by the bus's clock, not the test's, at the
    // speed the bus shows (20 °/s asked: speed 2, 22.5 °/s; the end of
    // travel, 90°, 4 s away).
    let (_, tilt) = stack.gcud.settled_position(MAST);
    let log = stack.gcud.log();
    let moving = support::door::seconds_moving(&log, MAST, "TU", DOOR_GROUP, "TS");
    let dps = support::door::speed_on_bus(&log, MAST, "TU");
    support::door::assert_rests_where_stopped(tilt, dps, moving, 90.0, "gimbal-mavlink's stop at SIGTERM");
    assert!(
        stack.log().contains("stopping what this service started"),
        "{}",
        stack.log()
    );
    assert!(!stack.gcud.log().contains("dead-man"), "{}", stack.gcud.log());
}

#[test]
fn bad_input_is_counted_and_refused_never_a_panic_and_nothing_moves() {
    if !client_available() {
        return;
    }
    let mut stack = Stack::start();
    let r = stack.gcs("garbage", GCS, json!({}));
    assert_eq!(r["nan"], DENIED, "{r}");
    assert_eq!(r["out_of_travel"], DENIED, "{r}");
    assert_eq!(r["bad_configure"], DENIED, "{r}");
    assert_eq!(r["alive"], true, "{r}");
    // Random datagrams straight at the endpoint, fuzz style (a fixed seed).
    let socket = std::net::UdpSocket::bind("127.0.0.1:0").expect("bind");
    let mut x: u64 = 0x9E37_79B9_7F4A_7C15;
    for i in 0..500 {
        x ^= x << 13;
        x ^= x >> 7;
        x ^= x << 17;
        let len = (x % 300) as usize;
        let mut bytes: Vec<u8> = (0..len).map(|k| (x >> (k % 56)) as u8 ^ k as u8).collect();
        if i % 2 == 0 && !bytes.is_empty() {
            bytes[0] = 0xFD; // a MAVLink 2 marker, the rest noise
        }
        socket.send_to(&bytes, ("127.0.0.1", stack.port)).expect("send");
        if i % 10 == 0 {
            // Paced, so that few are lost to the socket's receive buffer.
            std::thread::sleep(Duration::from_millis(2));
        }
    }
    assert_still(&stack, (0.0, 0.0), "after bad input");
    let alive = stack.gcs("heartbeat", GCS, json!({}));
    assert_eq!(alive["heartbeat"]["type"], 26, "{alive}");
    let status = stack.signal(nix::sys::signal::Signal::SIGTERM);
    assert!(status.success(), "{status:?}\n{}", stack.log());
    let log = stack.log();
    assert!(!log.contains("panicked"), "{log}");
    let (summary, counter) = counters(&log);
    // 21 damaged heartbeats, noise, a frame of no dialect, and the random
    // datagrams (none has a valid CRC; UDP may lose a few of them).
    assert!(counter("damaged") >= 23 + 400, "{summary}");
    assert!(counter("refused") >= 3, "{summary}");
    assert!(counter("ignored") >= 1, "PARAM_REQUEST_LIST: {summary}");
}

#[test]
fn bytes_without_an_intact_frame_on_tcp_are_counted_to_the_byte() {
    if !client_available() {
        return;
    }
    let mut stack = Stack::start();
    let tcp = format!("tcp:127.0.0.1:{}", stack.tcp_port);
    let r = stack.gcs_over(&tcp, "garbage", GCS, json!({}));
    assert_eq!(r["nan"], DENIED, "{r}");
    assert_eq!(r["out_of_travel"], DENIED, "{r}");
    assert_eq!(r["alive"], true, "{r}");
    assert_still(&stack, (0.0, 0.0), "after bad input over TCP");
    let status = stack.signal(nix::sys::signal::Signal::SIGTERM);
    assert!(status.success(), "{status:?}\n{}", stack.log());
    let (summary, counter) = counters(&stack.log());
    // TCP loses nothing: every byte written that is no intact frame is
    // counted, and none of the intact frames around them.
    let written = r["garbage_bytes"].as_u64().expect("garbage_bytes");
    assert!(written > 400, "{r}");
    assert_eq!(counter("damaged_bytes"), written, "{summary}");
    assert!(counter("damaged") >= 1, "{summary}");
    assert!(counter("ignored") >= 1, "PARAM_REQUEST_LIST: {summary}");
}

#[test]
fn a_ground_station_on_a_serial_line_points_the_gimbal() {
    if !client_available() {
        return;
    }
    let cable = support::door::NullModem::new();
    let stack = Stack::start_with(
        1000,
        &format!("[[endpoint]]\nserial = \"{}\"\nbaud = 115200", cable.ends.0.display()),
    );
    support::wait_for_log_line(&stack.log_path(), "MAVLink serial line open");
    let serial = cable.ends.1.display().to_string();
    let hb = stack.gcs_over(&serial, "heartbeat", GCS, json!({}));
    assert_eq!(hb["heartbeat"]["type"], 26, "{hb}");
    let r = stack.gcs_over(&serial, "pitchyaw", GCS, json!({ "pitch": 12.0, "yaw": -30.0 }));
    assert_eq!(r["result"], ACCEPTED, "{r}");
    let (pan, tilt) = stack.gcud.settled_position(MAST);
    assert!(
        (pan + 30.0).abs() <= 0.5 && (tilt - 12.0).abs() <= 0.5,
        "bus at {pan}, {tilt}"
    );
}

#[test]
fn a_serial_line_plugged_in_while_tcp_peers_fill_their_limit_still_opens() {
    if !client_available() {
        return;
    }
    let cable = support::door::NullModem::new();
    // The radio's device node appears only after the TCP peers connected.
    let plug = tempfile::tempdir().expect("temp dir");
    let radio = plug.path().join("radio");
    let stack = Stack::start_with(
        1000,
        &format!("[[endpoint]]\nserial = \"{}\"\nbaud = 115200", radio.display()),
    );
    // As many TCP peers as gimbal-mavlink serves (stream::MAX_CONNECTIONS).
    let peers: Vec<std::net::TcpStream> = (0..8)
        .map(|_| std::net::TcpStream::connect(("127.0.0.1", stack.tcp_port)).expect("connect"))
        .collect();
    eventually("the 8 TCP peers to be accepted", || {
        std::thread::sleep(Duration::from_millis(50));
        stack.log().matches("MAVLink TCP connection accepted").count() == 8
    });
    std::os::unix::fs::symlink(&cable.ends.0, &radio).expect("plug the radio in");
    support::wait_for_log_line(&stack.log_path(), "MAVLink serial line open");
    let serial = cable.ends.1.display().to_string();
    let hb = stack.gcs_over(&serial, "heartbeat", GCS, json!({}));
    assert_eq!(hb["heartbeat"]["type"], 26, "{hb}\n{}", stack.log());
    let r = stack.gcs_over(&serial, "pitchyaw", GCS, json!({ "pitch": 0.0, "yaw": 15.0 }));
    assert_eq!(r["result"], ACCEPTED, "{r}");
    let (pan, _) = stack.gcud.settled_position(MAST);
    assert!((pan - 15.0).abs() <= 0.5, "bus at {pan}");
    assert!(!stack.log().contains("refused"), "{}", stack.log());
    drop(peers);
}
