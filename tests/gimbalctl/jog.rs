//! Continuous motions through gcud (`--for`, `--hold`): kept moving, then
//! stopped and the stop confirmed; exit 22 when it is not (ARCHITECTURE
//! "Safety").

use super::*;

/// What gimbal `dest` received from clients (source 0) that stops a
/// motion, by its own record; and that gcud's dead-man stopped nothing.
fn client_stops(gcud: &DemoGcud, dest: &str) -> Vec<String> {
    gcud.wait_until_clients_are_down();
    assert_eq!(
        gcud.dead_man_lines(),
        Vec::<String>::new(),
        "gcud's dead-man did the stopping:\n{}",
        gcud.log()
    );
    let received = gcud.received(dest);
    assert!(
        received.iter().all(|(source, _)| *source == 0),
        "only clients wrote to {dest}: {received:?}"
    );
    received
        .into_iter()
        .map(|(_, payload)| payload)
        .filter(|p| p.len() == 2 && p.ends_with('S') && p != "HS")
        .collect()
}

/// The position of `to` once two readings 100 ms apart agree (the mount
/// decelerates after its stop).
fn settled(gcud: &DemoGcud, to: &str) -> (f64, f64) {
    let mut last = gcud.position(to);
    eventually("the mount to stand still", || {
        std::thread::sleep(Duration::from_millis(100));
        let now = gcud.position(to);
        let still = now == last;
        last = now;
        still
    });
    last
}

#[test]
fn jog_for_a_duration_through_gcud_keeps_moving_then_stops_and_confirms() {
    let gcud = DemoGcud::start();
    gcud.json(&["--to", "5.1.1", "rate", "pan", "20"]);
    let out = gcud.ctl(&["--json", "--to", "5.1.1", "slew", "right", "--for", "2s"]);
    assert_eq!(out.code, 0, "{out:?}\n{}", gcud.log());
    let v = out.json();
    assert_eq!(
        (v["sent"].as_str(), v["stop_sent"].as_str()),
        (Some("PR"), Some("PS")),
        "{v}"
    );
    assert_eq!(
        (v["stop_outcome"].as_str(), v["ended_by"].as_str()),
        (Some("acknowledged"), Some("duration"))
    );
    assert!(v["held_ms"].as_u64() >= Some(2000) && v["for_ms"] == 2000, "{v}");
    // The gimbal received gimbalctl's PS (not gcud's dead-man stop, which
    // would have ended the slew at once when gimbalctl disconnected) ...
    assert_eq!(client_stops(&gcud, "5.1.1"), ["PS"]);
    // ... and it stands where the PS left it, after moving for the whole
    // duration (the dead-man would have stopped it near 0), short of the
    // hard stop at 180 degrees; once it decelerated (gimbalctl is gone
    // gcud's NIC window after the ACK, 35 ms, not 300 as before `~W`).
    // Where it stands follows the bus's clock (PR to PS), not the test's:
    // at 20 deg/s, about 40 degrees on an idle machine.
    let stopped = settled(&gcud, "5.1.1");
    let moving = support::door::seconds_moving(&gcud.log(), "5.1.1", "PR", 0, "PS");
    assert!(moving >= 1.9, "the PS came after the whole duration: {moving} s");
    support::door::assert_rests_where_stopped(stopped.0, 20.0, moving, 180.0, "gimbalctl's PS after --for 2000");

    // Zoom and focus are continuous motions too.
    let v = gcud.json(&["--to", "5.1.1", "zoom", "in", "--for", "300ms"]);
    assert_eq!(
        (v["sent"].as_str(), v["stop_sent"].as_str()),
        (Some("ZI"), Some("ZS")),
        "{v}"
    );
    assert!(gcud.lens("5.1.1").0 > 0, "zoomed in");
    let v = gcud.json(&["--to", "5.1.1", "focus", "far", "--for", "300ms"]);
    assert_eq!(
        (v["sent"].as_str(), v["stop_sent"].as_str()),
        (Some("FF"), Some("FS")),
        "{v}"
    );
    assert!(gcud.lens("5.1.1").1 > 0, "focused far");
    assert_eq!(client_stops(&gcud, "5.1.1"), ["PS", "ZS", "FS"]);
    // Without --for/--hold through gcud: a note says the dead-man stops it.
    let out = gcud.ctl(&["--to", "5.1.2", "slew", "left"]);
    assert!(
        out.stderr.contains("dead-man") && out.stderr.contains("--for"),
        "{out:?}"
    );
}

#[test]
fn jog_hold_lasts_until_stdin_closes_or_sigterm_then_stops() {
    let gcud = DemoGcud::start();
    gcud.json(&["--to", "5.2.1", "rate", "tilt", "5"]);
    let mut child = spawn_ctl(&[
        "--json",
        "--tcp",
        &gcud.clients,
        "--to",
        "5.2.1",
        "slew",
        "up",
        "--hold",
    ]);
    // Held: the connection stays open, so the slew goes on (at 5 deg/s the
    // hard stop is 18 s away); a dead-man stop would have ended it near 0.
    eventually("the held slew to carry tilt past 2 degrees", || {
        gcud.position("5.2.1").1 > 2.0
    });
    drop(child.stdin.take());
    let out = wait_output(child);
    assert_eq!(out.code, 0, "{out:?}");
    let v = out.json();
    assert_eq!(
        (v["ended_by"].as_str(), v["stop_sent"].as_str()),
        (Some("stdin"), Some("TS")),
        "{v}"
    );
    assert_eq!(v["stop_outcome"], "acknowledged");
    assert_eq!(
        client_stops(&gcud, "5.2.1"),
        ["TS"],
        "gimbalctl's TS reached the gimbal"
    );
    let stopped = settled(&gcud, "5.2.1");
    assert!(stopped.1 < 90.0, "stopped short of the hard stop: {stopped:?}");

    let child = spawn_ctl(&[
        "--json",
        "--tcp",
        &gcud.clients,
        "--to",
        "5.2.1",
        "slew",
        "down",
        "--hold",
    ]);
    eventually("the held slew down to carry tilt 2 degrees lower", || {
        gcud.position("5.2.1").1 < stopped.1 - 2.0
    });
    let pid = nix::unistd::Pid::from_raw(child.id() as i32);
    nix::sys::signal::kill(pid, nix::sys::signal::Signal::SIGTERM).expect("SIGTERM");
    let out = wait_output(child);
    assert_eq!(out.code, 0, "{out:?}");
    let v = out.json();
    assert_eq!(
        (
            v["ended_by"].as_str(),
            v["stop_sent"].as_str(),
            v["stop_outcome"].as_str()
        ),
        (Some("signal"), Some("TS"), Some("acknowledged")),
        "{v}"
    );
    // The TS went out before gimbalctl exited, not gcud's dead-man after.
    assert_eq!(client_stops(&gcud, "5.2.1"), ["TS", "TS"]);
    let after = gcud.position("5.2.1");
    assert!(after.1 > -90.0, "stopped short of the hard stop: {after:?}");
    std::thread::sleep(Duration::from_millis(300));
    assert_eq!(gcud.position("5.2.1"), after);
}

#[test]
fn jog_stop_that_is_not_acknowledged_exits_22() {
    // The device answers the slew, then goes silent: the stop is not confirmed.
    let sim = Sim::pty(&["--silent", "1"]);
    let out = sim.ctl1(&[
        "--retries",
        "0",
        "--ack-timeout",
        "100",
        "slew",
        "right",
        "--for",
        "50ms",
    ]);
    assert_eq!(out.code, 4, "the start itself was not acknowledged: {out:?}");
    drop(sim);
    let bus = FakeBus::start();
    // Device 4 of the scripted bus ACKs everything: the start and the stop are confirmed.
    let out = gimbalctl(&[
        "--json", "--tcp", &bus.addr, "--direct", "--to", "1.1.4", "slew", "left", "--for", "50ms",
    ]);
    assert_eq!(out.code, 0, "{out:?}");
    assert_eq!(bus.received(), ["PL", "PS"]);
    // Device 6 acknowledges motions but not their stops: exit 22, the stop's reason given.
    let out = gimbalctl(&[
        "--json",
        "--tcp",
        &bus.addr,
        "--direct",
        "--to",
        "1.1.6",
        "--retries",
        "0",
        "--ack-timeout",
        "100",
        "slew",
        "up",
        "--for",
        "50ms",
    ]);
    assert_eq!(out.code, 22, "{out:?}");
    let v = out.json();
    assert_eq!(
        (v["outcome"].as_str(), v["stop_outcome"].as_str()),
        (Some("stop_unconfirmed"), Some("no_ack")),
        "{v}"
    );
    assert!(out.stderr.contains("TS") && out.stderr.contains("may go on"), "{out:?}");
    // Device 9 is silent: the start fails with its reason (no ACK) and no stop is claimed.
    let out = gimbalctl(&[
        "--json",
        "--tcp",
        &bus.addr,
        "--direct",
        "--to",
        "1.1.9",
        "--retries",
        "0",
        "--ack-timeout",
        "100",
        "zoom",
        "in",
        "--for",
        "50ms",
    ]);
    assert_eq!(
        (out.code, out.json()["outcome"].as_str()),
        (4, Some("no_ack")),
        "{out:?}"
    );
}
