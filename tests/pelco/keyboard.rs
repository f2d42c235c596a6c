//! pyptzcontroller, a Pelco-D keyboard library from PyPI, on a serial line:
//! moves each way at speeds that grow with the one asked, the stop, the
//! motion lease, a stop after a joystick stream, presets, absolute
//! positions and the position queries.

use super::*;

/// The speed (Table 11, hex digit of `SPn`) of the door's last `SP` on the bus.
fn last_speed(stack: &Stack) -> u8 {
    let frames = stack.door_frames();
    let sp = frames
        .iter()
        .rev()
        .find_map(|p| p.strip_prefix("SP"))
        .unwrap_or_else(|| panic!("no SP from the door: {frames:?}"));
    u8::from_str_radix(sp, 16).unwrap_or_else(|_| panic!("SP{sp}"))
}

/// Holds `dir` at `speed` for `seconds` from rest: where the gimbal was
/// and where it is when the keyboard lets go.
fn hold_from_rest(stack: &Stack, dir: &str, speed: &str, seconds: &str) -> ((f64, f64), (f64, f64)) {
    let before = stack.settled();
    stack.keyboard("hold", &[dir, speed, seconds]);
    (before, stack.position())
}

#[test]
fn a_keyboard_on_a_serial_line_moves_each_way_at_a_speed_that_grows_with_the_one_asked_and_stops() {
    if !client_available() {
        return;
    }
    let stack = Stack::start();
    let (start, right) = hold_from_rest(&stack, "right", "63", "1.0");
    let fast = last_speed(&stack);
    assert!(right.0 > start.0 + 1.0, "pan right: {start:?} -> {right:?}");
    stack.keyboard("hold", &["right", "8", "0.6"]);
    let slow = last_speed(&stack);
    assert!(slow < fast, "speed 8 is slower than 63: SP{slow:X} against SP{fast:X}");
    stack.keyboard("stop", &[]);
    support::door::wait_for_stop(&stack.gcud, MAST, DOOR_GROUP, "PS");
    let stopped = stack.settled();
    support::door::assert_still(&stack.gcud, MAST, stopped, "after the stop");
    let (before, left) = hold_from_rest(&stack, "left", "40", "0.8");
    assert!(left.0 < before.0 - 0.5, "pan left: {before:?} -> {left:?}");
    // Up at once after left: the pan this keyboard moved is stopped.
    stack.keyboard("hold", &["up", "40", "0.8"]);
    let frames = stack.door_frames();
    let last_left = frames.iter().rposition(|p| p == "PL").expect("PL");
    assert!(
        frames[last_left..].iter().any(|p| p == "PS"),
        "the pan went on: {frames:?}"
    );
    stack.keyboard("stop", &[]);
    support::door::wait_for_stop(&stack.gcud, MAST, DOOR_GROUP, "TS");
    let (before, up) = hold_from_rest(&stack, "up", "40", "0.8");
    assert!(up.1 > before.1 + 0.5, "tilt up: {before:?} -> {up:?}");
    stack.keyboard("stop", &[]);
    support::door::wait_for_stop(&stack.gcud, MAST, DOOR_GROUP, "TS");
    let (before, down) = hold_from_rest(&stack, "down", "40", "0.8");
    assert!(down.1 < before.1 - 0.5, "tilt down: {before:?} -> {down:?}");
    stack.keyboard("stop", &[]);
    support::door::wait_for_stop(&stack.gcud, MAST, DOOR_GROUP, "TS");
    support::door::assert_no_stop_from_gcud(&stack.gcud, MAST);
    // An idle keyboard's repeated stops cost the bus nothing.
    let before = stack.door_frames().iter().filter(|p| !p.ends_with('?')).count();
    for _ in 0..3 {
        stack.keyboard("stop", &[]);
    }
    std::thread::sleep(Duration::from_millis(300));
    let after = stack.door_frames().iter().filter(|p| !p.ends_with('?')).count();
    assert_eq!(before, after, "repeated stops sent: {:?}", stack.door_frames());
}

#[test]
fn a_drive_never_repeated_is_stopped_by_the_door_within_its_lease() {
    if !client_available() {
        return;
    }
    let stack = Stack::start_with(500, "");
    let start = stack.position();
    stack.keyboard("once", &["right", "30"]);
    support::door::wait_moving(&stack.gcud, MAST, start);
    support::door::wait_for_stop(&stack.gcud, MAST, DOOR_GROUP, "PS");
    let at = stack.settled();
    support::door::assert_still(&stack.gcud, MAST, at, "after the lease");
    support::door::assert_no_stop_from_gcud(&stack.gcud, MAST);
}

#[test]
fn a_stop_after_a_joystick_stream_overtakes_its_drives() {
    if !client_available() {
        return;
    }
    let stack = Stack::start();
    let r = stack.keyboard("joystick", &["2.0"]);
    assert!(r["sent"].as_u64().unwrap() >= 10, "{r}");
    support::door::wait_for_stop(&stack.gcud, MAST, DOOR_GROUP, "PS");
    let at = stack.settled();
    support::door::assert_still(&stack.gcud, MAST, at, "after the stop");
    // Nothing of the stream reached the bus after the stop.
    let frames = stack.door_frames();
    let stop = frames.iter().rposition(|p| p == "PS").expect("PS");
    assert!(
        !frames[stop..].iter().any(|p| p == "PR" || p.starts_with("SP")),
        "a drive after the stop: {frames:?}"
    );
}

#[test]
fn presets_absolute_positions_and_position_queries() {
    if !client_available() {
        return;
    }
    let stack = Stack::start();
    stack.keyboard("move_to", &["30", "10"]);
    let (pan, tilt) = stack.settled();
    assert!(
        (pan - 30.0).abs() < 0.2 && (tilt - 10.0).abs() < 0.2,
        "at {pan}, {tilt}"
    );
    let asked = stack.keyboard("position", &[]);
    let (qp, qt) = (asked["pan"].as_f64().unwrap(), asked["tilt"].as_f64().unwrap());
    assert!(
        (qp - pan).abs() < 0.02 && (qt - tilt).abs() < 0.02,
        "{asked} against {pan}, {tilt}"
    );
    stack.keyboard("set_preset", &["5"]);
    support::eventually("S05 on the bus", || stack.door_frames().iter().any(|p| p == "S05"));
    // 340 degrees is the gimbal's -20; pyptzcontroller's tilt -5 is 5 down.
    stack.keyboard("move_to", &["340", "-5"]);
    let (pan, tilt) = stack.settled();
    assert!(
        (pan + 20.0).abs() < 0.2 && (tilt + 5.0).abs() < 0.2,
        "at {pan}, {tilt}; the bus had {:?}\ndoor log:\n{}",
        stack.door_frames(),
        stack.door.log()
    );
    let asked = stack.keyboard("position", &[]);
    assert!(
        (asked["pan"].as_f64().unwrap() - 340.0).abs() < 0.02 && (asked["tilt"].as_f64().unwrap() + 5.0).abs() < 0.02,
        "{asked}"
    );
    stack.keyboard("go_to_preset", &["5"]);
    support::eventually("P05 on the bus", || stack.door_frames().iter().any(|p| p == "P05"));
    let (pan, tilt) = stack.settled();
    assert!(
        (pan - 30.0).abs() < 0.2 && (tilt - 10.0).abs() < 0.2,
        "at preset 5: {pan}, {tilt}"
    );
    // Cleared: a go to it moves nothing until it is set again.
    stack.keyboard("clear_preset", &["5"]);
    stack.keyboard("move_to", &["0", "0"]);
    let home = stack.settled();
    stack.keyboard("go_to_preset", &["5"]);
    support::wait_for_log_line(&stack.door.log_path(), "go to preset ignored");
    support::door::assert_still(&stack.gcud, MAST, home, "a cleared preset");
    assert_eq!(stack.door_frames().iter().filter(|p| *p == "P05").count(), 1);
}
