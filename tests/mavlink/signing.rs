//! MAVLink 2 message signing (issue 49): with `[signing]`, a ground station
//! of pymavlink signing with the door's key (`tests/mavlink/signed.py`,
//! pymavlink's own `setup_signing`) points the gimbal and gets signed
//! answers; unsigned frames, frames signed with another key, a signed
//! command's bytes sent again and signed frames with old timestamps are
//! refused, and the bus shows that nothing moved.

use serde_json::{Value, json};

use super::*;

/// The door's key (64 hexadecimal digits, as the key file holds it).
const KEY: &str = "5b0c6d1e7f2a8b3c9d4e0f516273849506a7b8c9dae0f1e2d3c4b5a697887766";
/// Another key.
const THIEF: &str = "0f1e2d3c4b5a69788796a5b4c3d2e1f00f1e2d3c4b5a69788796a5b4c3d2e1f0";
/// How long a refused command's ACK is waited for.
const REFUSED_WAIT_S: f64 = 2.0;

/// The stack with `[signing]` on a key file holding [`KEY`] (in the
/// returned folder), and the key file's path.
fn start_signed() -> (Stack, tempfile::TempDir, String) {
    let dir = tempfile::tempdir().expect("temp dir");
    let key_file = dir.path().join("mavlink.key");
    std::fs::write(&key_file, format!("{KEY}\n")).expect("write the key");
    let key_file = key_file.display().to_string();
    let stack = Stack::start_with(1000, &format!("[signing]\nkey_file = {key_file:?}\n"));
    (stack, dir, key_file)
}

impl Stack {
    /// One step of the signing ground station (`signed.py`) as `who` over
    /// `connection` (a UDP port, or `tcp:HOST:PORT`).
    fn signed(&self, connection: &str, step: &str, who: (u8, u8), args: Value) -> Value {
        let (system, component, args) = (who.0.to_string(), who.1.to_string(), args.to_string());
        support::door::python_step(
            "tests/mavlink/signed.py",
            step,
            &[connection, &system, &component, &args],
            || self.log(),
        )
    }

    /// What the door's source group sent the mast gimbal but queries.
    fn door_commands(&self) -> Vec<String> {
        self.gcud
            .received(MAST)
            .into_iter()
            .filter(|(source, p)| *source == DOOR_GROUP && !p.ends_with('?'))
            .map(|(_, p)| p)
            .collect()
    }
}

/// A signed pitchyaw accepted, with a signed ACK, and reached on the bus.
fn signed_pitchyaw(stack: &Stack, connection: &str, key_file: &str, (pitch, yaw): (f64, f64)) -> Value {
    let args = json!({ "key_file": key_file, "pitch": pitch, "yaw": yaw });
    let r = stack.signed(connection, "pitchyaw", GCS, args);
    assert_eq!(r["result"], ACCEPTED, "{r}");
    assert_eq!(r["ack_signed"], true, "the door signs its answers: {r}");
    let (pan, tilt) = stack.gcud.settled_position(MAST);
    assert!(
        (pan - yaw).abs() <= 0.5 && (tilt - pitch).abs() <= 0.5,
        "bus at {pan}, {tilt}"
    );
    r
}

/// Each of `attempts` (step, args) is refused: no ACK; then the gimbal has
/// not moved from `at` and the door sent nothing but queries since `sent`.
fn assert_refused(stack: &Stack, connection: &str, at: (f64, f64), attempts: &[(&str, Value)]) {
    let sent = stack.door_commands();
    for (step, args) in attempts {
        let r = stack.signed(connection, step, GCS, args.clone());
        assert_eq!(r["result"], Value::Null, "{step} {args}: answered {r}");
        assert_eq!(stack.gcud.position(MAST), at, "{step} {args}: the gimbal moved");
    }
    assert_still(stack, at, "after the refused frames");
    assert_eq!(stack.door_commands(), sent, "the door sent a command to the bus");
}

#[test]
fn only_frames_signed_with_the_key_move_the_gimbal_and_replays_are_refused() {
    if !client_available() {
        return;
    }
    let (mut stack, _dir, key_file) = start_signed();
    let udp = stack.port.to_string();
    let first = signed_pitchyaw(&stack, &udp, &key_file, (10.0, 20.0));
    signed_pitchyaw(&stack, &udp, &key_file, (0.0, -30.0));
    let at = stack.gcud.settled_position(MAST);
    let refused = |extra: Value| {
        let mut args = json!({ "pitch": 40.0, "yaw": 60.0, "wait_s": REFUSED_WAIT_S });
        args.as_object_mut().unwrap().extend(extra.as_object().unwrap().clone());
        args
    };
    assert_refused(
        &stack,
        &udp,
        at,
        &[
            // A ground station without a key.
            ("pitchyaw", refused(json!({}))),
            ("set_pitchyaw", refused(json!({}))),
            // Another key.
            ("pitchyaw", refused(json!({ "key": THIEF }))),
            // The first command's bytes as they went out (its target is
            // not where the gimbal is now), from a ground station without the key.
            ("replay", json!({ "bytes": first["sent"], "wait_s": REFUSED_WAIT_S })),
            // The key, but timestamps older than the stream's last, and a
            // new stream (link id 9) two minutes old.
            ("pitchyaw", refused(json!({ "key_file": key_file, "age_s": 30.0 }))),
            (
                "pitchyaw",
                refused(json!({ "key_file": key_file, "age_s": 120.0, "link_id": 9 })),
            ),
        ],
    );
    // Still the key's: the signing ground station moves it again.
    signed_pitchyaw(&stack, &udp, &key_file, (5.0, 15.0));
    stack.signal(nix::sys::signal::Signal::SIGTERM);
    let log = stack.log();
    let (summary, counter) = counters(&log);
    assert!(counter("unsigned") >= 2, "{summary}");
    assert!(counter("bad_signature") >= 1, "{summary}");
    assert!(counter("stale_signature") >= 3, "{summary}");
    // Logged once per peer address (all 127.0.0.1 here) in 10 s, not per frame.
    let lines = log.matches("MAVLink message refused: signing is on").count() as u64;
    let total = counter("unsigned") + counter("bad_signature") + counter("stale_signature");
    assert!(
        lines >= 1 && lines * 3 <= total,
        "{lines} lines for {total} refusals:\n{log}"
    );
}

#[test]
fn over_tcp_an_unsigned_ground_station_is_refused_and_a_signed_one_obeyed() {
    if !client_available() {
        return;
    }
    let (stack, _dir, key_file) = start_signed();
    let tcp = format!("tcp:127.0.0.1:{}", stack.tcp_port);
    signed_pitchyaw(&stack, &tcp, &key_file, (-10.0, 35.0));
    let at = stack.gcud.settled_position(MAST);
    let args = json!({ "pitch": 30.0, "yaw": -45.0, "wait_s": REFUSED_WAIT_S });
    assert_refused(&stack, &tcp, at, &[("pitchyaw", args.clone())]);
    let mut thief = args;
    thief["key"] = json!(THIEF);
    assert_refused(&stack, &tcp, at, &[("pitchyaw", thief)]);
}
