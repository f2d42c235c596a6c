//! End of the NIC window (ARCHITECTURE "End of the NIC window (`~W`)"):
//! through gcud (`--tcp`) gimbalctl asks for end-of-window reports before
//! its first command without a result, so a slew waits gcud's port window
//! (35 ms), not its own `--nic-window` on top of it; a gcud that answers
//! NIC (an older one) still gets the command, and the window is waited
//! here. A bus master (`--serial`, `--tcp --direct` to a device server)
//! asks nothing: no device is `G.0.0`.

use super::*;
use support::fake_gcud::{Answer, FakeGcud};

/// gimbalctl's debug line after it asked `~W`.
const ASKED: &str = "end-of-window reports (~W) asked";
/// `--log` that shows it.
const DEBUG: &str = "warn,gimbalctl=debug";

#[test]
fn a_slew_through_gcud_waits_gcuds_window_not_its_own_too() {
    let gcud = DemoGcud::start();
    // A window of gimbalctl's own of 30 s: waited on top of gcud's 35 ms,
    // each of these would take more than 30 s (half of it is the bound: a
    // busy machine never comes near it).
    let own: &[&str] = &["--log", DEBUG, "--to", "5.1.1", "--nic-window", "30000"];
    for command in [&["speed", "pan", "3"][..], &["slew", "right"], &["stop", "pan"]] {
        let out = gcud.ctl(&[&["--json"], own, command].concat());
        assert_eq!(out.code, 0, "{command:?}: {out:?}\n{}", gcud.log());
        assert!(
            out.stderr.contains(ASKED) && out.stderr.contains("agreed=true"),
            "gcud agreed to ~W: {out:?}"
        );
        let took = out.json()["elapsed_ms"].as_u64().expect("elapsed_ms");
        assert!(
            took < 15_000,
            "{command:?}: gcud's window, not --nic-window 30000 as well: {took} ms"
        );
    }
    // A query waits for its result, never a window: nothing asked.
    let out = gcud.ctl(&[own, &["position"]].concat());
    assert_eq!(out.code, 0, "{out:?}");
    assert!(!out.stderr.contains("~W"), "{out:?}");
}

#[test]
fn gcud_is_asked_once_first_and_a_nic_leaves_the_window_here() {
    for (answer, agreed) in [(Answer::Result(b"~W=".to_vec()), true), (Answer::Nic, false)] {
        let fake = FakeGcud::start(move |p| match p {
            b"~W" => answer.clone(),
            _ => Answer::Ack,
        });
        let out = gimbalctl(&[
            "--json",
            "--log",
            DEBUG,
            "--tcp",
            &fake.addr,
            "--to",
            "5.1.1",
            "--nic-window",
            "50",
            "slew",
            "right",
            "--for",
            "100ms",
        ]);
        assert_eq!(out.code, 0, "{out:?}");
        assert!(out.stderr.contains(&format!("agreed={agreed}")), "{out:?}");
        let got: Vec<String> = fake.got().into_iter().filter(|p| p != "P?").collect();
        assert_eq!(got, ["~W", "PR", "PS"], "~W once, before the slew");
    }
}

#[test]
fn a_bus_master_asks_no_gcu() {
    // A serial line (pty) and a device server (gimbalsim --tcp, --direct):
    // nothing reaches the bus but the commands, no frame for 1.0.0.
    for sim in [Sim::pty(&[]), Sim::tcp(&[])] {
        sim.json1(&["--log", DEBUG, "speed", "pan", "0"]);
        let out = sim.ctl1(&["--log", DEBUG, "slew", "right"]);
        assert_eq!(out.code, 0, "{out:?}");
        assert!(!out.stderr.contains("~W"), "{out:?}");
        sim.json1(&["stop", "pan"]);
        let stats = sim.stop();
        assert_eq!(stats["frames_ignored"], 0, "a frame no device takes: {stats}");
    }
    // A device server named as such gets only the commands ...
    let bus = FakeBus::start();
    let out = gimbalctl(&["--tcp", &bus.addr, "--direct", "--to", "1.1.4", "slew", "left"]);
    assert_eq!(out.code, 0, "{out:?}");
    assert_eq!(bus.received(), ["PL"]);
    // ... and one taken for gcud costs one unanswered ~W, which says so.
    let bus = FakeBus::start();
    let out = gimbalctl(&[
        "--tcp",
        &bus.addr,
        "--ack-timeout",
        "200",
        "--to",
        "1.1.4",
        "slew",
        "left",
    ]);
    assert_eq!(out.code, 0, "{out:?}");
    assert!(
        out.stderr.contains("did not answer ~W") && out.stderr.contains("--direct"),
        "{out:?}"
    );
    assert_eq!(bus.received(), ["~W", "PL"], "asked once, not retransmitted");
}

/// `slew --speed`: the speed, then the direction at its ACK (ARCHITECTURE
/// "Routing semantics", the next command in the window). On a `duplex = "full"` port gcud
/// writes the direction in the speed's NIC window, which it counts
/// (`gcud_port_pipelined_total`); the bus hears the speed, then the direction.
#[test]
fn slew_with_a_speed_chains_the_speed_and_its_direction() {
    use support::gcud::{CLIENTS, Gcud, METRICS, port_entry};
    let sim = Sim::pty(&["--device", "1"]);
    let gcud = Gcud::start(&format!(
        "[gcu]\ngroup = 5\n{CLIENTS}{METRICS}{}duplex = \"full\"\n",
        port_entry(1, &sim)
    ));
    gcud.wait_for_log("port open port=1");
    for (n, speed) in ["9", "4"].into_iter().enumerate() {
        let out = gcud.ctl(&["--to", "5.1.1", "slew", "right", "--speed", speed, "--for", "100ms"]);
        assert_eq!(out.code, 0, "{out:?}\n{}", gcud.log());
        assert_eq!(
            gcud.metric("gcud_port_pipelined_total{port=\"1\"}"),
            n as u64 + 1,
            "PR went in SP{speed}'s window"
        );
    }
    // A speed out of 0..=15 is refused before anything is sent.
    let out = gcud.ctl(&["--to", "5.1.1", "slew", "right", "--speed", "16"]);
    assert_eq!(out.code, 2, "a usage error: {out:?}");
}
