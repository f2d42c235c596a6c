//! The front doors' motions never outlive their owner (issue 31; DESIGN
//! "Front doors", the gimbal session in `crates/client/src/session/`):
//! requests racing a move, floods of moves then a stop, a stick released
//! at 50 Hz, gcud killed and back during a move, a door frozen mid-move,
//! and `max_move_ms`. Driven by the third-party clients the doors are
//! tested with (onvif-zeep-async, pymavlink); positions and stops read on
//! the bus side.

mod support;

use std::path::Path;
use std::time::{Duration, Instant};

use serde_json::{Value, json};
use support::door::{DOOR_GROUP, Door};
use support::gcud::Gcud;

const MAST: &str = "5.1.1";
const OPERATOR: (&str, &str) = ("op", "op-secret");

fn onvif_available() -> bool {
    support::door::onvif_client_available()
}

fn pymavlink_available() -> bool {
    support::door::mavlink_client_available()
}

/// gimbal-onvif for the mast gimbal (no lens) in front of `gcud`.
fn onvif_config(gcud: &str, max_move_ms: u64) -> String {
    format!(
        r#"source_group = {DOOR_GROUP}
gcud = "{gcud}"
max_move_ms = {max_move_ms}
poll_ms = 100
[discovery]
enabled = false
[[user]]
name = "op"
password = "op-secret"
role = "operator"
[[gimbal]]
name = "mast-1"
address = "{MAST}"
listen = "127.0.0.1:0"
zoom = false
"#
    )
}

fn start_onvif(gcud: &str, max_move_ms: u64) -> (Door, u16) {
    let mut door = Door::new("gimbal-onvif", env!("CARGO_BIN_EXE_gimbal-onvif"));
    door.start(&onvif_config(gcud, max_move_ms));
    let port = door.port("gimbal=mast-1 addr=");
    (door, port)
}

/// One step of `script` (tests/onvif/*.py) against the mast's device.
fn onvif_step(script: &str, door: &Door, port: u16, step: &str, args: Value) -> Value {
    let (port, args) = (port.to_string(), args.to_string());
    support::door::python_step(
        script,
        step,
        &["127.0.0.1", &port, OPERATOR.0, OPERATOR.1, &args],
        || door.log(),
    )
}

/// The position, read on the bus side, unchanged for `quiet` after `wait`.
fn assert_still_after(gcud: &Gcud, wait: Duration, what: &str) -> (f64, f64) {
    std::thread::sleep(wait);
    let at = gcud.position(MAST);
    support::door::assert_still(gcud, MAST, at, what);
    at
}

// ---- ONVIF: requests racing a ContinuousMove ------------------------------------

/// 20 ContinuousMoves (Timeout 2 s), each raced 0 to 100 ms later by
/// `kind`; 3 s after the last request the gimbal is still.
fn race(kind: &str) {
    if !onvif_available() {
        return;
    }
    let gcud = support::door::start_gcud();
    let (door, port) = start_onvif(&gcud.clients(), 20_000);
    let r = onvif_step(
        "tests/onvif/race.py",
        &door,
        port,
        "race",
        json!({ "kind": kind, "trials": 20, "seed": 31 }),
    );
    let trials = r["trials"].as_array().expect("trials");
    assert_eq!(trials.len(), 20, "{r}");
    for t in trials {
        assert_eq!(t["move"], "ok", "every ContinuousMove is answered: {r}\n{}", door.log());
        assert_eq!(t["second"], "ok", "every {kind} is answered: {r}\n{}", door.log());
    }
    // The pan rate changes at every trial: each pan move sets its speed,
    // then its direction at the speed's ACK (chained), and `kind` races the
    // chain too. Moves `kind` overtook before the speed went set none.
    let speeds = gcud
        .received(MAST)
        .iter()
        .filter(|(from, payload)| *from == DOOR_GROUP && payload.starts_with("SP"))
        .count();
    assert!(
        kind == "zero_x" || speeds >= 5,
        "only {speeds} of 20 moves set a pan speed: the race missed the chain"
    );
    let (pan, tilt) = assert_still_after(
        &gcud,
        Duration::from_secs(3),
        &format!("3 s after ContinuousMove raced by {kind}"),
    );
    assert!(
        pan.abs() < 170.0 && tilt.abs() < 80.0,
        "a move escaped its Timeout and reached the end of travel: pan {pan}, tilt {tilt}"
    );
}

#[test]
fn a_stop_racing_a_continuous_move_leaves_the_gimbal_still() {
    race("stop");
}

#[test]
fn an_absolute_move_racing_a_continuous_move_leaves_the_gimbal_still() {
    race("absolute");
}

#[test]
fn a_home_racing_a_continuous_move_leaves_the_gimbal_still() {
    race("home");
}

#[test]
fn a_zoom_only_stop_racing_a_continuous_move_leaves_the_gimbal_still() {
    race("zoom_stop");
}

#[test]
fn a_single_axis_zero_move_during_a_tilt_leaves_the_gimbal_still() {
    race("zero_x");
}

#[test]
fn forty_unawaited_continuous_moves_then_a_stop_stop_at_once() {
    if !onvif_available() {
        return;
    }
    let gcud = support::door::start_gcud();
    let (door, port) = start_onvif(&gcud.clients(), 20_000);
    let r = onvif_step(
        "tests/onvif/race.py",
        &door,
        port,
        "flood_then_stop",
        json!({ "moves": 40, "hz": 20 }),
    );
    assert_eq!(r["stop"], "ok", "{r}\n{}", door.log());
    // Before the session, the Stop was answered after 5.8 s, the gimbal
    // slewing on; the stop now overtakes the coalesced moves.
    let answered = r["stop_answer_s"].as_f64().expect("stop_answer_s");
    assert!(answered < 0.5, "the Stop waited behind the moves: {answered} s\n{r}");
    // The Stop is answered once the bus confirmed PS and TS. A move that
    // reached the door after it is newer and ends at its 1 s Timeout: still
    // from then on.
    assert_still_after(&gcud, Duration::from_millis(1200), "after the Stop");
    support::door::wait_for_stop(&gcud, MAST, DOOR_GROUP, "PS");
}

// ---- ONVIF: max_move_ms -----------------------------------------------------------

/// A ContinuousMove at 60 °/s with `timeout_s` (none, or past the
/// maximum) stops at max_move_ms (1 s): about 60°, far from the end.
fn stops_at_max_move(timeout_s: Option<f64>) {
    if !onvif_available() {
        return;
    }
    let gcud = support::door::start_gcud();
    let (door, port) = start_onvif(&gcud.clients(), 1000);
    let mut args = json!({ "x": 0.5, "y": 0.0 });
    if let Some(t) = timeout_s {
        args["timeout_s"] = json!(t);
    }
    let r = onvif_step("tests/onvif/client.py", &door, port, "continuous", args);
    assert_eq!(r["ok"], true, "{r}");
    let (pan, _) = gcud.settled_position(MAST);
    assert!(
        pan > 20.0 && pan < 120.0,
        "about 1 s at 60 °/s, then stopped by max_move_ms: pan {pan}\n{}",
        door.log()
    );
    support::door::wait_for_stop(&gcud, MAST, DOOR_GROUP, "PS");
    assert!(door.log().contains("move time-out: stopping"), "{}", door.log());
}

#[test]
fn a_continuous_move_without_a_timeout_stops_at_max_move() {
    stops_at_max_move(None);
}

#[test]
fn a_continuous_move_whose_timeout_exceeds_the_maximum_stops_at_max_move() {
    stops_at_max_move(Some(30.0));
}

// ---- gcud away during a move; a door frozen mid-move -------------------------------

/// A free port on 127.0.0.1 (bound, then released for gcud to take).
fn free_port() -> u16 {
    std::net::TcpListener::bind("127.0.0.1:0")
        .and_then(|l| l.local_addr())
        .expect("a free port")
        .port()
}

#[test]
fn gcud_killed_during_a_move_gets_the_owed_stop_first_when_it_returns() {
    if !onvif_available() {
        return;
    }
    // The gimbal on a bus of its own (gimbalsim over TCP): it keeps moving
    // while gcud is away, as a real one on a serial line does.
    let sim = support::Sim::tcp(&["--device", "1"]);
    let clients = format!("127.0.0.1:{}", free_port());
    let config = format!(
        "[gcu]\ngroup = 5\n[[port]]\nid = 1\ntcp = \"{}\"\n[[link]]\nname = \"clients\"\nrole = \"client\"\n\
         listen = \"{clients}\"\nallow_source_groups = [0, {DOOR_GROUP}]\n",
        sim.endpoint
    );
    let mut gcud = Gcud::start(&config);
    let (door, port) = start_onvif(&clients, 60_000);
    // 15 °/s right with no Timeout: the end of travel (180°) 12 s away.
    let r = onvif_step(
        "tests/onvif/client.py",
        &door,
        port,
        "continuous",
        json!({ "x": 0.1, "y": 0.0 }),
    );
    assert_eq!(r["ok"], true, "{r}");
    support::door::wait_moving(&gcud, MAST, (0.0, 0.0));
    nix::sys::signal::kill(
        nix::unistd::Pid::from_raw(gcud.child.id() as i32),
        nix::sys::signal::Signal::SIGKILL,
    )
    .expect("kill gcud");
    let _ = gcud.child.wait();
    support::wait_for_log_line(&door.log_path(), "gcud cannot be reached");
    // While gcud is away, the door does not pretend to know.
    let status = onvif_step("tests/onvif/client.py", &door, port, "status", json!({}));
    assert_eq!(status["moving"], "UNKNOWN", "{status}\n{}", door.log());
    std::thread::sleep(Duration::from_secs(4));
    let back = Instant::now();
    let gcud = Gcud::start(&config);
    support::wait_for_log_line(&door.log_path(), "gcud can be reached again");
    let (pan, _) = gcud.settled_position(MAST);
    let stopped_after = back.elapsed();
    // Without the owed stop it slews on to the end of travel (180°): it
    // rests where the door's PS put it, by the gimbal's own clock.
    let log = sim.log();
    let moving = support::door::seconds_moving(&log, MAST, "PR", DOOR_GROUP, "PS");
    let dps = support::door::speed_on_bus(&log, MAST, "PR");
    support::door::assert_rests_where_stopped(pan, dps, moving, 180.0, "the owed stop");
    support::door::assert_still(&gcud, MAST, (pan, 0.0), "after the owed stop");
    eprintln!("stopped {} ms after gcud started again", stopped_after.as_millis());
    drop(sim);
}

#[test]
fn a_door_frozen_mid_move_is_stopped_by_the_lease_of_the_demo_configuration() {
    if !onvif_available() {
        return;
    }
    let demo = std::fs::read_to_string(Path::new(env!("CARGO_MANIFEST_DIR")).join("config/demo.toml")).unwrap();
    assert!(demo.contains("motion_lease_ms"), "the demo configuration sets a lease");
    let config = demo
        .replace("127.0.0.1:4001", "127.0.0.1:0")
        .replace("127.0.0.1:4002", "127.0.0.1:0")
        .replace("127.0.0.1:4003", "127.0.0.1:0")
        .replace("127.0.0.1:4004", "127.0.0.1:0")
        .replace("127.0.0.1:4005", "127.0.0.1:0")
        .replace("127.0.0.1:4006", "127.0.0.1:0")
        .replace("127.0.0.1:4008", "127.0.0.1:0")
        .replace("127.0.0.1:9187", "127.0.0.1:0");
    let gcud = Gcud::start(&config);
    let mut door = Door::new("gimbal-onvif", env!("CARGO_BIN_EXE_gimbal-onvif"));
    door.start(&onvif_config(&gcud.clients(), 60_000).replace(&format!("source_group = {DOOR_GROUP}\n"), ""));
    let port = door.port("gimbal=mast-1 addr=");
    // 30 °/s right with no Timeout: the end of travel 6 s away.
    let r = onvif_step(
        "tests/onvif/client.py",
        &door,
        port,
        "continuous",
        json!({ "x": 0.25, "y": 0.0 }),
    );
    assert_eq!(r["ok"], true, "{r}");
    support::door::wait_moving(&gcud, MAST, (0.0, 0.0));
    let pid = nix::unistd::Pid::from_raw(door.pid() as i32);
    nix::sys::signal::kill(pid, nix::sys::signal::Signal::SIGSTOP).expect("SIGSTOP");
    let (pan, _) = gcud.settled_position(MAST);
    nix::sys::signal::kill(pid, nix::sys::signal::Signal::SIGCONT).expect("SIGCONT");
    // gcud stopped it itself (group 5), for the lease, and the gimbal
    // rests where that PS put it, by the bus's clock.
    support::door::wait_for_stop(&gcud, MAST, support::door::GCUD_GROUP, "PS");
    let log = gcud.log();
    let moving = support::door::seconds_moving(&log, MAST, "PR", support::door::GCUD_GROUP, "PS");
    let dps = support::door::speed_on_bus(&log, MAST, "PR");
    support::door::assert_rests_where_stopped(pan, dps, moving, 180.0, "gcud's lease stop");
    assert!(gcud.log().contains("lease"), "{}", gcud.log());
}

// ---- MAVLink: a stick released at 50 Hz ---------------------------------------------

#[test]
fn a_stick_released_at_50_hz_stops_the_pan_within_half_a_second() {
    if !pymavlink_available() {
        return;
    }
    let gcud = support::door::start_gcud();
    let mut door = Door::new("gimbal-mavlink", env!("CARGO_BIN_EXE_gimbal-mavlink"));
    door.start(&format!(
        "source_group = {DOOR_GROUP}\ngcud = \"{}\"\nsystem_id = 1\nlease_ms = 1000\n\
         [[endpoint]]\nudp_listen = \"127.0.0.1:0\"\n\
         [[gimbal]]\nname = \"mast-1\"\naddress = \"{MAST}\"\ncomponent_id = 154\n",
        gcud.clients()
    ));
    let port = door.port("MAVLink UDP endpoint bound");
    let r = support::door::python_step(
        "tests/mavlink/stick.py",
        "stick",
        &[
            &port.to_string(),
            env!("CARGO_BIN_EXE_gimbalctl"),
            &gcud.clients(),
            MAST,
        ],
        || door.log(),
    );
    // Read on the bus half a second after the first zero, then a second
    // later: the same.
    let (at_half, at_one_and_half) = (&r["pan_at_0_5_s"], &r["pan_at_1_5_s"]);
    assert!(at_half.is_f64(), "{r}");
    assert_eq!(
        at_half,
        at_one_and_half,
        "the pan still moved after the stick was released: {r}\n{}",
        door.log()
    );
    assert!(r["moved_deg"].as_f64().unwrap() > 10.0, "the stick moved it: {r}");
    assert!(
        !door.log().contains("request queue full"),
        "requests (zeros among them) were dropped:\n{}",
        door.log()
    );
    support::door::wait_for_stop(&gcud, MAST, DOOR_GROUP, "PS");
}
