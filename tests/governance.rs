//! gcud governs each gimbal across every tool (issue 32, ARCHITECTURE
//! "Governance"): the real gcud with a real `gimbalsim` bus on a
//! pseudo-terminal, `gimbalctl` on two client listeners of priorities 50
//! (`clients`) and 80 (`operators`), TCP on 127.0.0.1 only. What reached
//! the gimbals, and where they stopped, is read on the bus side: the
//! simulator's own log of the frames it received and the results it sent.
//! Waits are polls bounded by [`HANG_GUARD`]; the only times asserted are
//! lower bounds the rules set (a dwell, a hold), never a speed.

mod support;

use std::process::ChildStdin;
use std::sync::Arc;
use std::sync::atomic::{AtomicUsize, Ordering};
use std::time::Duration;

use serde_json::Value;
use support::gcud::{Gcud, METRICS, port_entry};
use support::relay::{self, Relay};
use support::{HANG_GUARD, Output, Sim};

const GIMBAL: &str = "5.1.1";

/// gcud (group 5) on one gimbalsim bus, with the two client listeners.
struct Stack {
    sim: Sim,
    gcud: Gcud,
    /// The relay between gcud's port and the bus, when there is one.
    relay: Option<Relay>,
    /// The configuration gcud started with.
    config: String,
    clients: String,
    operators: String,
}

impl Stack {
    /// `sim_args` for gimbalsim, `hold_ms` for `[control]`, `extra` appended
    /// to the configuration (`[[gimbal]]`, `[[tour]]`).
    fn start(sim_args: &[&str], hold_ms: u64, extra: &str) -> Self {
        Self::start_on(Sim::pty(sim_args), hold_ms, extra)
    }

    /// [`Stack::start`] on a gimbalsim bus already running.
    fn start_on(sim: Sim, hold_ms: u64, extra: &str) -> Self {
        Self::start_through(sim, None, hold_ms, extra)
    }

    /// [`Stack::start`] with a [`Relay`] between gcud's port and the bus,
    /// losing the frames toward the gimbal that `lose` picks.
    fn start_relayed(sim_args: &[&str], lose: relay::Lose, hold_ms: u64, extra: &str) -> Self {
        let sim = Sim::pty(sim_args);
        let relay = Relay::start(&sim.endpoint, lose);
        Self::start_through(sim, Some(relay), hold_ms, extra)
    }

    fn start_through(sim: Sim, relay: Option<Relay>, hold_ms: u64, extra: &str) -> Self {
        let port = match &relay {
            Some(relay) => format!("[[port]]\nid = 1\npath = \"{}\"\n", relay.path),
            None => port_entry(1, &sim),
        };
        let config = format!(
            "[gcu]\ngroup = 5\n[control]\nhold_ms = {hold_ms}\n{METRICS}{port}\
             [[link]]\nname = \"clients\"\nrole = \"client\"\nlisten = \"127.0.0.1:0\"\n\
             [[link]]\nname = \"operators\"\nrole = \"client\"\nlisten = \"127.0.0.1:0\"\npriority = 80\n{extra}"
        );
        let gcud = Gcud::start(&config);
        gcud.wait_for_log("port open port=1");
        let clients = gcud.address("listening link=clients");
        let operators = gcud.address("listening link=operators");
        Self {
            sim,
            gcud,
            relay,
            config,
            clients,
            operators,
        }
    }

    /// `gimbalctl --tcp VIA ARGS`.
    fn ctl(&self, via: &str, args: &[&str]) -> Output {
        let mut full = vec!["--tcp", via];
        full.extend_from_slice(args);
        support::gimbalctl(&full)
    }

    /// `gimbalctl --tcp VIA --to 5.1.1 ARGS`, which must succeed.
    fn ok(&self, via: &str, args: &[&str]) -> Output {
        let mut full = vec!["--to", GIMBAL];
        full.extend_from_slice(args);
        let out = self.ctl(via, &full);
        assert_eq!(out.code, 0, "{args:?}: {out:?}\n{}", self.logs());
        out
    }

    /// A gimbalctl motion left running (`--hold`: until its stdin closes).
    fn hold(&self, via: &str, args: &[&str]) -> (std::process::Child, ChildStdin) {
        let mut full = vec!["--tcp", via, "--to", GIMBAL];
        full.extend_from_slice(args);
        full.push("--hold");
        let mut child = support::cli::spawn_ctl(&full);
        let stdin = child.stdin.take().expect("stdin");
        (child, stdin)
    }

    /// [`eventually`], with both logs in the failure message.
    fn eventually(&self, what: &str, mut condition: impl FnMut() -> bool) {
        let started = std::time::Instant::now();
        while !condition() {
            assert!(
                started.elapsed() < HANG_GUARD,
                "gave up waiting for {what}\n{}",
                self.logs()
            );
            std::thread::sleep(Duration::from_millis(20));
        }
    }

    fn logs(&self) -> String {
        format!("gcud log:\n{}\ngimbalsim log:\n{}", self.gcud.log(), self.sim.log())
    }

    /// What the gimbal received, by its own log: (source group, payload).
    fn bus(&self) -> Vec<(u8, String)> {
        self.sim.received(GIMBAL)
    }

    /// The gimbal's position once it stands still, as the gimbal itself
    /// answered it (its `tx result` in the simulator's log), degrees.
    /// A `P?` that gcud gives up (a bus busy with a stop's retransmissions)
    /// is asked again: only answers read on the bus count.
    fn bus_position(&self) -> (f64, f64) {
        let mut last = None;
        self.eventually("the gimbal to stand still", || {
            std::thread::sleep(Duration::from_millis(150));
            let before = answered_positions(&self.sim.log()).len();
            let _ = self.ctl(&self.clients, &["--to", GIMBAL, "position"]);
            let answers = answered_positions(&self.sim.log());
            if answers.len() == before {
                return false;
            }
            let now = answers.last().copied();
            let still = now.is_some() && now == last;
            last = now;
            still
        });
        last.expect("a position")
    }

    /// `/status`'s tour of this name.
    fn tour(&self, name: &str) -> Value {
        let status = self.gcud.status();
        status["tours"]
            .as_array()
            .and_then(|t| t.iter().find(|t| t["name"] == name).cloned())
            .unwrap_or_else(|| panic!("no tour {name} in {status}"))
    }

    /// `/status`'s control of the gimbal.
    fn control(&self) -> Value {
        let status = self.gcud.status();
        status["control"]
            .as_array()
            .and_then(|c| c.iter().find(|c| c["address"] == GIMBAL).cloned())
            .unwrap_or(Value::Null)
    }
}

/// A frame the gimbal received or a result it answered, from its log.
#[derive(Debug, Clone, PartialEq)]
struct BusEvent {
    /// Seconds since midnight (the log's UTC time of day).
    at: f64,
    kind: Kind,
    source: u8,
    payload: String,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Kind {
    Received,
    Answer,
}

/// The gimbal's frames in and results out, in order, from gimbalsim's log
/// (`... rx frame dest=5.1.1 source=S payload=P ...`, `... tx result ...`).
fn bus_events(log: &str) -> Vec<BusEvent> {
    log.lines()
        .filter_map(|line| {
            let kind = if line.contains(" rx frame dest=5.1.1 ") {
                Kind::Received
            } else if line.contains(" tx result ") {
                Kind::Answer
            } else {
                return None;
            };
            let time = line.split('T').nth(1)?.split('Z').next()?;
            let mut parts = time.split(':');
            let (h, m, s): (f64, f64, f64) = (
                parts.next()?.parse().ok()?,
                parts.next()?.parse().ok()?,
                parts.next()?.parse().ok()?,
            );
            let field = |name: &str| {
                let rest = line.split(&format!(" {name}=")).nth(1)?;
                Some(rest.split(' ').next()?.to_owned())
            };
            Some(BusEvent {
                at: h * 3600.0 + m * 60.0 + s,
                kind,
                source: field("source")?.parse().ok()?,
                payload: field("payload")?,
            })
        })
        .collect()
}

/// The positions the gimbal answered to a client's `P?` (source group 0;
/// gcud's own polls and preset queries left out), in order.
fn answered_positions(log: &str) -> Vec<(f64, f64)> {
    let mut asked = false;
    let mut positions = Vec::new();
    for e in bus_events(log) {
        match e.kind {
            Kind::Received => asked = e.source == 0 && e.payload == "P?",
            Kind::Answer if asked => positions.extend(position(&e.payload)),
            Kind::Answer => {}
        }
    }
    positions
}

/// A Table 15 position payload (`aaaaeeee`), degrees.
fn position(payload: &str) -> Option<(f64, f64)> {
    if payload.len() != 8 || !payload.bytes().all(|b| b.is_ascii_hexdigit()) {
        return None;
    }
    let angle = |hex: &str| {
        i16::from_str_radix(hex, 16)
            .ok()
            .or_else(|| u16::from_str_radix(hex, 16).ok().map(|v| v as i16))
    };
    Some((
        f64::from(angle(&payload[..4])?) / 100.0,
        f64::from(angle(&payload[4..])?) / 100.0,
    ))
}

/// The `Paaaaeeee` payload of a goto to (pan, tilt) degrees.
fn goto_payload(pan: f64, tilt: f64) -> String {
    let c = |d: f64| (d * 100.0).round() as i16 as u16;
    format!("P{:04X}{:04X}", c(pan), c(tilt))
}

/// Times read on the bus are later than gcud took the command (the hold
/// starts there): a command waits behind the stops of a take-over and its
/// own transmission. Lower bounds on the bus allow this much.
const BUS_SLACK: f64 = 0.25;

fn is_stop(payload: &str) -> bool {
    matches!(payload, "PS" | "TS" | "PT")
}

// ---- control: priorities, hold, release -----------------------------------------

/// The 50 link is refused (exit 23, the reason and the holder named,
/// nothing on the bus) while the 80 link holds the gimbal; its stop still
/// passes; it gets control once hold_ms passed since the holder's last
/// command. /status, the metrics and gcud-status name the holder.
#[test]
fn a_lower_priority_link_is_refused_while_a_higher_one_holds_and_gets_control_after_the_hold() {
    // 5 s: time enough for three gimbalctl runs on a loaded machine.
    let s = Stack::start(&[], 5000, "");
    s.ok(&s.operators, &["goto", "10", "0"]);
    let refused = s.ctl(&s.clients, &["--to", GIMBAL, "goto", "20", "0"]);
    assert_eq!(refused.code, 23, "{refused:?}\n{}", s.logs());
    assert!(
        refused.stderr.contains("refused, nothing sent to the gimbal")
            && refused
                .stderr
                .contains("another link of equal or higher priority controls the gimbal")
            && refused.stderr.contains("held by link operators (priority 80)"),
        "{refused:?}"
    );
    let json = s.ctl(&s.clients, &["--json", "--to", GIMBAL, "goto", "20", "0"]);
    assert_eq!(json.json()["outcome"], "not_in_control", "{json:?}");
    // Who holds it, as /status, the metrics and gcud-status show it.
    let control = s.control();
    assert_eq!(control["holder"]["name"], "operators", "{control}");
    assert_eq!(control["holder"]["priority"], 80, "{control}");
    assert!(control["lapses_in_ms"].as_u64().is_some(), "{control}");
    let metrics = s.gcud.metrics();
    assert!(
        metrics.contains("gcud_gimbal_holder{port=\"1\",device=\"1\",holder=\"operators\"} 1"),
        "{metrics}"
    );
    let status = support::gimbalctl(&["gcud-status", "--http", &s.gcud.address("metrics at /metrics")]);
    assert!(
        status
            .stdout
            .lines()
            .any(|l| l.starts_with(GIMBAL) && l.contains("link operators (priority 80)")),
        "{status:?}"
    );
    // The lower link's stop is never refused, and reaches the gimbal.
    s.ok(&s.clients, &["stop"]);
    let bus = s.bus();
    assert!(bus.contains(&(0, "PT".to_owned())), "{bus:?}");
    assert!(
        !bus.iter().any(|(_, p)| *p == goto_payload(20.0, 0.0)),
        "a refused goto reached the bus: {bus:?}"
    );
    // Its release is refused too (the holder's priority is higher).
    let release = s.ctl(&s.clients, &["--to", GIMBAL, "release"]);
    assert_eq!(release.code, 23, "{release:?}");
    assert!(
        release.stderr.contains("held by link operators (priority 80)"),
        "{release:?}"
    );
    // Once hold_ms passed, the lower link takes control.
    s.eventually("the operators' control to lapse", || {
        let out = s.ctl(&s.clients, &["--to", GIMBAL, "goto", "20", "0"]);
        assert!(matches!(out.code, 0 | 23), "{out:?}");
        out.code == 0
    });
    assert_eq!(s.control()["holder"]["name"], "clients");
    assert!(s.bus().contains(&(0, goto_payload(20.0, 0.0))));
    // The higher link may release the lower's control; then nobody holds it.
    s.ok(&s.operators, &["release"]);
    assert_eq!(s.control()["holder"], Value::Null);
}

/// The 80 link takes over from the 50 link's slew: gcud stops the slew
/// first, and the gimbal receives that stop before the new motion; the
/// 50 link's own stop at the end still passes.
#[test]
fn a_take_over_stops_the_holders_motion_before_the_new_one() {
    let s = Stack::start(&["--rate", "20"], 10_000, "");
    let (slewing, stdin) = s.hold(&s.clients, &["slew", "right"]);
    s.eventually("the slew to reach the gimbal", || {
        s.bus().contains(&(0, "PR".to_owned()))
    });
    s.ok(&s.operators, &["goto", "-10", "0", "--wait"]);
    drop(stdin);
    let jog = support::cli::wait_output(slewing);
    assert_eq!(jog.code, 0, "the slewing link's stop passes: {jog:?}\n{}", s.logs());
    let bus = s.bus();
    let slew = bus.iter().position(|f| *f == (0, "PR".to_owned())).expect("PR");
    let goto = bus
        .iter()
        .position(|f| *f == (0, goto_payload(-10.0, 0.0)))
        .expect("the goto");
    assert!(
        bus[slew..goto].iter().any(|(source, p)| *source == 5 && is_stop(p)),
        "gcud's stop of the slew (source group 5) before the goto: {bus:?}"
    );
    let (pan, tilt) = s.bus_position();
    assert!((pan + 10.0).abs() < 0.05 && tilt.abs() < 0.05, "({pan}, {tilt})");
    assert!(s.gcud.metric("gcud_governance_takeovers_total") >= 1);
    assert!(
        s.gcud
            .log()
            .contains("link operators (priority 80) took control from link clients (priority 50)")
    );
}

// ---- travel limits and keep-out zones --------------------------------------------

/// A pan limit at 40° and a zone from -50° to -30° pan (tilt -30..10).
const BOUNDED: &str = "[[gimbal]]\naddress = \"5.1.1\"\npan_limits_deg = [-90.0, 40.0]\ntilt_limits_deg = [-30.0, 60.0]\n\
                       [[gimbal.keep_out]]\npan_deg = [-50.0, -30.0]\ntilt_deg = [-30.0, 10.0]\n";

/// Starts a held slew (`gimbalctl slew DIRECTION [ARGS] --hold` through the
/// clients' listener) and returns once the gimbal received it: gcud learns
/// what it needs first (its position, its rate after a speed change), so
/// the slew is never refused for not knowing.
fn slew(s: &Stack, direction: &str, args: &[&str]) -> (std::process::Child, ChildStdin) {
    let command = if direction == "right" { "PR" } else { "PL" };
    let sent = |s: &Stack| s.bus().iter().filter(|f| **f == (0, command.to_owned())).count();
    let before = sent(s);
    let mut full = vec!["slew", direction];
    full.extend_from_slice(args);
    let (mut child, stdin) = s.hold(&s.clients, &full);
    s.eventually("the slew on the bus", || {
        if let Some(status) = child.try_wait().expect("try_wait") {
            panic!("the slew ended before the gimbal received it: {status}\n{}", s.logs());
        }
        sent(s) > before
    });
    (child, stdin)
}

/// A pan limit at 10° and a zone from -20° to -10° pan (tilt -30..10),
/// close to the start so that a slow slew reaches them soon.
const NEAR: &str = "[[gimbal]]\naddress = \"5.1.1\"\npan_limits_deg = [-90.0, 10.0]\ntilt_limits_deg = [-30.0, 60.0]\n\
                    [[gimbal.keep_out]]\npan_deg = [-20.0, -10.0]\ntilt_deg = [-30.0, 10.0]\n";

/// Slews at the gimbal's top speed toward a pan limit and toward a zone
/// stop short of them, no further than 0.5° past (where they rest read on
/// the bus side); a goto into the zone or past the limit is refused and
/// nothing reaches the bus.
#[test]
fn slews_stop_short_of_limits_and_zones_and_gotos_into_them_are_refused() {
    // 5 °/s is the gimbal's top speed (slow: a late timer on a loaded
    // machine costs little); 20 °/s² brakes it in 0.625°.
    let s = Stack::start(&["--max-rate", "5", "--rate", "5", "--accel", "20"], 10_000, NEAR);
    // The moment gcud is ready: it learns where the gimbal is, then decides.
    s.ok(&s.clients, &["goto", "0", "0", "--wait"]);
    for (pan, tilt, code, reason) in [
        (-15.0, 0.0, 25, "keep-out zone"),
        (-25.0, 0.0, 25, "keep-out zone"),
        (15.0, 0.0, 24, "travel limits"),
    ] {
        let (p, t) = (pan.to_string(), tilt.to_string());
        let out = s.ctl(&s.clients, &["--to", GIMBAL, "goto", &p, &t]);
        assert_eq!(out.code, code, "goto {pan} {tilt}: {out:?}");
        assert!(out.stderr.contains(reason), "{out:?}");
        assert!(
            !s.bus().iter().any(|(_, payload)| *payload == goto_payload(pan, tilt)),
            "a refused goto reached the bus"
        );
    }

    let (child, stdin) = slew(&s, "right", &[]);
    let (pan, _) = s.bus_position();
    drop(stdin);
    assert_eq!(support::cli::wait_output(child).code, 0);
    assert!(
        pan <= 10.5,
        "the slew passed the pan limit 10° by more than 0.5°: {pan}\n{}",
        s.logs()
    );
    eprintln!("slew right: rests at pan {pan} (limit 10)");
    assert!(pan > 5.0, "it slewed toward the limit: {pan}");
    assert!(
        s.bus().iter().any(|(source, p)| *source == 5 && p == "PS"),
        "gcud's stop: {:?}",
        s.bus()
    );

    s.ok(&s.clients, &["goto", "0", "0", "--wait"]);
    let (child, stdin) = slew(&s, "left", &[]);
    let (pan, tilt) = s.bus_position();
    drop(stdin);
    assert_eq!(support::cli::wait_output(child).code, 0);
    assert!(tilt.abs() < 0.05, "{tilt}");
    assert!(
        pan >= -10.5,
        "the slew entered the zone (pan -20..-10) by more than 0.5°: {pan}\n{}",
        s.logs()
    );
    eprintln!("slew left: rests at pan {pan} (zone from -10)");
    assert!(pan < -5.0, "it slewed toward the zone: {pan}");
    assert!(s.gcud.metric("gcud_governance_boundary_stops_total") >= 2);
}

/// Loses the next stop frames gcud (source group 5) sends to the gimbal,
/// as many as `next` says (each one lost counts it down): the first copy
/// of gcud's stop and then its retransmissions, on the wire. A stop is a
/// frame whose command the protocol table says stops an axis.
fn lose_gcud_stops(next: Arc<AtomicUsize>) -> relay::Lose {
    Box::new(move |frame| {
        let stop = matches!(
            sagebrush_protocol::Command::parse(frame.payload()).mount(),
            sagebrush_protocol::MountEffect::Stop { .. }
        );
        frame.source == 5
            && stop
            && next
                .fetch_update(Ordering::SeqCst, Ordering::SeqCst, |n| n.checked_sub(1))
                .is_ok()
    })
}

/// Lost stop frames (issue 48: two lost `PS` put the gimbal 3.5-4.5° into
/// the zone at 60 °/s): a relay between gcud's port and the bus loses
/// gcud's boundary stop of a slew toward the zone (pan 100..130) at
/// 60 °/s on a 9600 bit/s line (gimbalsim paces its bytes at it). Once
/// lost, the retransmission still stops the gimbal within the documented
/// margin (0.5°; ARCHITECTURE "Governance": the stop's latency holds one
/// lost frame). Twice lost, the documents promise no more than what the
/// second retransmission costs, 78 ms at 9600 bit/s, at the top rate:
/// it rests within 0.5° + 60 °/s × 78 ms = 5.18° into the zone, stopped by
/// the third copy (the figures are printed).
#[test]
fn lost_stop_frames_on_the_bus_leave_the_gimbal_within_the_documented_margin() {
    const ZONE: &str = "[[gimbal]]\naddress = \"5.1.1\"\npan_limits_deg = [-170.0, 170.0]\n\
                        [[gimbal.keep_out]]\npan_deg = [100.0, 130.0]\ntilt_deg = [-30.0, 10.0]\n";
    let next = Arc::new(AtomicUsize::new(0));
    let sim = ["--pace", "--max-rate", "60", "--rate", "60", "--accel", "120"];
    let s = Stack::start_relayed(&sim, lose_gcud_stops(Arc::clone(&next)), 10_000, ZONE);
    let relay = s.relay.as_ref().expect("the relay");
    let gcud_stops = |s: &Stack| s.bus().iter().filter(|(source, p)| *source == 5 && is_stop(p)).count();
    let mut rests = Vec::new();
    for (lose, bound) in [(1, 0.5), (2, 0.5 + 60.0 * 0.078)] {
        s.ok(&s.clients, &["goto", "0", "0", "--wait"]);
        let (lost, received) = (relay.lost().len(), gcud_stops(&s));
        next.store(lose, Ordering::SeqCst);
        let (child, stdin) = slew(&s, "right", &[]);
        let (pan, tilt) = s.bus_position();
        drop(stdin);
        assert_eq!(support::cli::wait_output(child).code, 0);
        eprintln!("{lose} stop frame(s) lost at 60 deg/s: rests at pan {pan} (zone from 100)");
        rests.push(pan);
        assert!(tilt.abs() < 0.05, "{tilt}");
        assert!(pan > 80.0, "it slewed toward the zone: {pan}");
        assert!(
            pan <= 100.0 + bound,
            "{lose} lost stop(s): {:.2}° into the zone (pan 100..130), more than {bound:.2}°\n{}",
            pan - 100.0,
            s.logs()
        );
        // What the relay lost, and that a copy of gcud's stop reached the gimbal after.
        let now_lost = relay.lost();
        assert_eq!(
            now_lost[lost..],
            vec![(5, "PS".to_owned()); lose],
            "{now_lost:?}\n{}",
            s.logs()
        );
        assert!(
            gcud_stops(&s) > received,
            "gcud's stop reached the gimbal: {:?}",
            s.bus()
        );
    }
    eprintln!(
        "FIGURES lost stops at 60 deg/s, 9600 bit/s: one lost rests at {}, two lost at {} (zone from 100)",
        rests[0], rests[1]
    );
}

// ---- tours and park ---------------------------------------------------------

const TOUR: &str = "[[tour]]\nname = \"round\"\naddress = \"5.1.1\"\n\
                    steps = [ { pan_deg = 10.0, tilt_deg = 5.0, dwell_s = 1 }, { pan_deg = 30.0, tilt_deg = 20.0, dwell_s = 1 } ]\n";

/// The tour's gotos, by the gimbal's log: (time, payload).
fn tour_gotos(s: &Stack) -> Vec<(f64, String)> {
    let steps = [goto_payload(10.0, 5.0), goto_payload(30.0, 20.0)];
    bus_events(&s.sim.log())
        .into_iter()
        .filter(|e| e.kind == Kind::Received && e.source == 5 && steps.contains(&e.payload))
        .map(|e| (e.at, e.payload))
        .collect()
}

/// A tour runs its steps in order and cycles, each goto confirmed (the
/// position read back) before its dwell; an operator's command pauses it,
/// and it resumes with the step it was on once control lapses; started
/// while a link holds the gimbal, it says it waits for that link.
#[test]
fn a_tour_runs_its_steps_pauses_for_an_operator_and_resumes_after_the_hold() {
    let s = Stack::start(&["--rate", "60", "--accel", "240"], 5000, TOUR);
    let list = s.ctl(&s.clients, &["tour", "list"]);
    assert_eq!((list.code, list.stdout.trim()), (0, "round  stopped"), "{list:?}");
    // Tours start and stop from the highest link's priority (`tours_min_priority`).
    let started = s.ctl(&s.operators, &["tour", "start", "round"]);
    assert_eq!(
        (started.code, started.stdout.trim()),
        (0, "tour round: running"),
        "{started:?}"
    );
    s.eventually("the tour to cycle (step 1, step 2, step 1)", || {
        tour_gotos(&s).len() >= 3
    });
    let gotos = tour_gotos(&s);
    let events = bus_events(&s.sim.log());
    for pair in gotos.windows(2) {
        let ((t0, first), (t1, second)) = (&pair[0], &pair[1]);
        assert_ne!(first, second, "steps in order: {gotos:?}");
        assert!(t1 - t0 >= 1.0, "a step's dwell (1 s) passed before the next: {gotos:?}");
        // Confirmed before the dwell: its position read back in between,
        // within the 0.5° the core counts as arrived.
        let target = position(&first[1..]).expect("a goto's position");
        let near = |p: (f64, f64)| (p.0 - target.0).abs() <= 0.5 && (p.1 - target.1).abs() <= 0.5;
        assert!(
            events
                .iter()
                .any(|e| e.kind == Kind::Answer && e.at > *t0 && e.at < *t1 && position(&e.payload).is_some_and(near)),
            "the arrival at {target:?} was read before the next step: {gotos:?}"
        );
    }

    // An operator's command pauses it.
    s.ok(&s.operators, &["goto", "-10", "0"]);
    let operator_at = bus_events(&s.sim.log())
        .into_iter()
        .rev()
        .find(|e| e.kind == Kind::Received && e.source == 0 && e.payload == goto_payload(-10.0, 0.0))
        .expect("the operator's goto")
        .at;
    s.eventually("the tour to wait for the operator", || {
        s.tour("round")["state"] != "running"
    });
    let paused = s.tour("round");
    assert_eq!(paused["state"], "waiting", "{paused}");
    assert_eq!(paused["waiting_for"]["name"], "operators", "{paused}");
    let step = paused["step"].as_u64().expect("step") as usize;
    let list = s.ctl(&s.clients, &["tour", "list"]);
    assert_eq!(list.stdout.trim(), "round  waiting", "{list:?}");
    // It resumes with the step it was on, once the operator's control lapsed.
    let before = tour_gotos(&s).len();
    s.eventually("the tour to resume", || tour_gotos(&s).len() > before);
    let (resumed_at, resumed) = tour_gotos(&s)[before].clone();
    assert!(
        resumed_at - operator_at >= 5.0 - BUS_SLACK,
        "resumed {} s after the operator's command, before hold_ms (5 s)",
        resumed_at - operator_at
    );
    let expected = [goto_payload(10.0, 5.0), goto_payload(30.0, 20.0)][step - 1].clone();
    assert_eq!(resumed, expected, "it resumes with step {step}");
    assert_eq!(s.tour("round")["state"], "running");

    let stopped = s.ctl(&s.operators, &["tour", "stop", "round"]);
    assert_eq!(stopped.stdout.trim(), "tour round: stopped", "{stopped:?}");
    // Started while a link holds the gimbal: it waits, and says for whom.
    s.ok(&s.operators, &["goto", "0", "0"]);
    let waiting = s.ctl(&s.operators, &["tour", "start", "round"]);
    assert_eq!(waiting.code, 0, "{waiting:?}");
    assert!(waiting.stdout.contains("waiting for operators"), "{waiting:?}");
    s.eventually("the waiting tour to run", || s.tour("round")["state"] == "running");
    let unknown = s.ctl(&s.operators, &["tour", "start", "nowhere"]);
    assert_eq!(unknown.code, 5, "{unknown:?}");
}

/// Park recalls its preset once, after_s after control lapsed with nobody
/// taking it; again only after a link moved the gimbal.
#[test]
fn park_recalls_its_preset_once_after_control_lapsed() {
    let park = "[[gimbal]]\naddress = \"5.1.1\"\npark = { preset = 2, after_s = 1 }\n";
    let s = Stack::start(&["--rate", "60", "--accel", "240"], 3000, park);
    s.ok(&s.clients, &["goto", "20", "10", "--wait"]);
    s.ok(&s.clients, &["preset", "store", "2"]);
    s.ok(&s.clients, &["goto", "0", "0", "--wait"]);
    let parks = |s: &Stack| -> Vec<f64> {
        bus_events(&s.sim.log())
            .into_iter()
            .filter(|e| e.kind == Kind::Received && e.source == 5 && e.payload == "P02")
            .map(|e| e.at)
            .collect()
    };
    let last_command = bus_events(&s.sim.log())
        .into_iter()
        .rev()
        .find(|e| e.kind == Kind::Received && e.source == 0 && e.payload == goto_payload(0.0, 0.0))
        .expect("the last goto")
        .at;
    s.eventually("park", || !parks(&s).is_empty());
    let parked_at = parks(&s)[0];
    assert!(
        parked_at - last_command >= 4.0 - BUS_SLACK,
        "parked {} s after the last command, before hold_ms + after_s (4 s)",
        parked_at - last_command
    );
    let (pan, tilt) = s.bus_position();
    assert!(
        (pan - 20.0).abs() < 0.05 && (tilt - 10.0).abs() < 0.05,
        "at preset 2: ({pan}, {tilt})"
    );
    assert!(s.gcud.metric("gcud_governance_parks_total") >= 1);
    // Not again while nobody moves it.
    std::thread::sleep(Duration::from_millis(5000));
    assert_eq!(parks(&s).len(), 1, "parked again without a move");
    // Moved by a link: parked again once its control lapsed.
    s.ok(&s.clients, &["goto", "5", "5", "--wait"]);
    s.eventually("the second park", || parks(&s).len() == 2);
}

/// Park runs on a gimbal that answers NIC for preset 00 (issue 48: the
/// scan stopped at the first NIC and the park preset was never asked for).
/// Its park preset 03 is stored before gcud starts (gimbalctl on the bus
/// itself): gcud asks for it whatever the scan finds, and recalls it once
/// control lapsed; stored again through gcud (`S03`), it is asked for
/// again, and the next park goes to its new place. Where the gimbal rests
/// is its own answer on the bus.
#[test]
fn park_runs_on_a_gimbal_that_answers_nic_for_preset_00() {
    let sim_args = ["--rate", "60", "--accel", "240", "--unset-presets-nic"];
    // Preset 03 stored at (20, 10) before gcud opens the bus; 00 never is.
    let sim = Sim::pty(&sim_args);
    for args in [
        &["--to", GIMBAL, "goto", "20", "10", "--wait"][..],
        &["--to", GIMBAL, "preset", "store", "3"],
        &["--to", GIMBAL, "goto", "0", "0", "--wait"],
    ] {
        let out = sim.ctl(args);
        assert_eq!(
            out.code,
            0,
            "{args:?}: {out:?}
{}",
            sim.log()
        );
    }
    let query = sim.ctl(&["--to", GIMBAL, "raw", "P?00"]);
    assert_ne!(query.code, 0, "preset 00 answers NIC: {query:?}");
    // A zone away from every path: park must know where preset 3 lies to
    // recall it (a park whose path may enter a zone is refused).
    let park = "[[gimbal]]\naddress = \"5.1.1\"\npan_limits_deg = [-170.0, 170.0]\n\
                park = { preset = 3, after_s = 1 }\n\
                [[gimbal.keep_out]]\npan_deg = [100.0, 130.0]\ntilt_deg = [-30.0, 10.0]\n";
    let s = Stack::start_on(sim, 3000, park);
    // gcud's own scan met NIC at preset 00 (the gimbal's side of the wire).
    s.eventually("gcud's P?00 answered NIC", || nic_answered(&s.sim.log(), "P?00"));
    let parks = |s: &Stack| -> Vec<f64> {
        bus_events(&s.sim.log())
            .into_iter()
            .filter(|e| e.kind == Kind::Received && e.source == 5 && e.payload == "P03")
            .map(|e| e.at)
            .collect()
    };
    s.ok(&s.clients, &["goto", "-10", "0", "--wait"]);
    s.eventually("park", || !parks(&s).is_empty());
    let (pan, tilt) = s.bus_position();
    assert!(
        (pan - 20.0).abs() < 0.05 && (tilt - 10.0).abs() < 0.05,
        "parked at preset 3 (20, 10): ({pan}, {tilt})\n{}",
        s.logs()
    );
    assert!(s.gcud.metric("gcud_governance_parks_total") >= 1);
    // Stored again through gcud at (-20, 5): the next park goes there.
    s.ok(&s.clients, &["goto", "-20", "5", "--wait"]);
    s.ok(&s.clients, &["preset", "store", "3"]);
    s.ok(&s.clients, &["goto", "0", "0", "--wait"]);
    s.eventually("the second park", || parks(&s).len() == 2);
    let (pan, tilt) = s.bus_position();
    assert!(
        (pan + 20.0).abs() < 0.05 && (tilt - 5.0).abs() < 0.05,
        "parked at preset 3's new place (-20, 5): ({pan}, {tilt})\n{}",
        s.logs()
    );
}

/// Whether the gimbal answered NIC to a `payload` it received from gcud
/// (source group 5), by its own log: its `tx NIC` before the next frame.
fn nic_answered(log: &str, payload: &str) -> bool {
    let asked = format!(" rx frame dest={GIMBAL} source=5 payload={payload} ");
    let mut after = false;
    for line in log.lines() {
        if line.contains(&asked) {
            after = true;
        } else if after && line.contains(" rx frame ") {
            after = false;
        } else if after && line.contains("tx NIC") {
            return true;
        }
    }
    false
}

// ---- reload ---------------------------------------------------------------

/// A reload (SIGHUP) applies a new link priority at once (the link's hold
/// of a gimbal included) and a new tour, and leaves a running tour whose
/// configuration did not change running.
#[test]
fn a_reload_applies_priorities_and_tours_as_a_difference() {
    let s = Stack::start(&["--device", "1,2"], 60_000, TOUR);
    let started = s.ctl(&s.operators, &["tour", "start", "round"]);
    assert_eq!(started.code, 0, "{started:?}");
    let other = ["--to", "5.1.2", "goto", "20", "0"];
    assert_eq!(s.ctl(&s.operators, &["--to", "5.1.2", "goto", "10", "0"]).code, 0);
    assert_eq!(s.ctl(&s.clients, &other).code, 23, "the operators (80) hold 5.1.2");

    let lowered = s.config.replace("priority = 80", "priority = 40")
        + "[[tour]]\nname = \"second\"\naddress = \"5.1.2\"\nsteps = [ { preset = 1, dwell_s = 1 } ]\n";
    std::fs::write(s.gcud.dir.path().join("gcud.toml"), lowered).expect("write config");
    let pid = nix::unistd::Pid::from_raw(s.gcud.child.id() as i32);
    nix::sys::signal::kill(pid, nix::sys::signal::Signal::SIGHUP).expect("SIGHUP");
    s.gcud.wait_for_log("reload: link \"operators\": priority 40");
    // The clients (50) now outrank the operators (40), whose hold took the new priority.
    let out = s.ctl(&s.clients, &other);
    assert_eq!(out.code, 0, "{out:?}\n{}", s.logs());
    let list = s.ctl(&s.clients, &["tour", "list"]);
    assert_eq!(list.stdout.trim(), "round  running\nsecond  stopped", "{list:?}");
    assert!(
        !s.gcud.log().contains("changed (its connections close"),
        "{}",
        s.gcud.log()
    );
}

// ---- gcud --check -------------------------------------------------------------

/// `gcud --check` refuses a tour step into a keep-out zone, naming the
/// file, line and key of the step.
#[test]
fn check_refuses_a_tour_step_into_a_zone_naming_its_place() {
    let dir = tempfile::tempdir().expect("temp dir");
    let path = dir.path().join("gcud.toml");
    let config = format!(
        "[gcu]\ngroup = 5\n[[port]]\nid = 1\nsimulate = [1]\n\
         [[link]]\nname = \"clients\"\nrole = \"client\"\nlisten = \"127.0.0.1:0\"\n{BOUNDED}\
         [[tour]]\nname = \"gate\"\naddress = \"5.1.1\"\nsteps = [\n  {{ preset = 1 }},\n  {{ pan_deg = -45.0, tilt_deg = 0.0, dwell_s = 5 }},\n]\n"
    );
    std::fs::write(&path, &config).expect("write");
    let out = std::process::Command::new(env!("CARGO_BIN_EXE_gcud"))
        .arg("--check")
        .arg("--config")
        .arg(&path)
        .output()
        .expect("gcud --check");
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "{stderr}");
    let line = config.lines().position(|l| l.contains("-45.0")).expect("the step") + 1;
    assert!(
        stderr.contains(&format!("{}:{line}:3: tour[0].steps[1]: ", path.display())),
        "{stderr}"
    );
    assert!(stderr.contains("enters a keep-out zone"), "{stderr}");
}

// ---- what operators, tools and attackers send (issue 48) ----------------------

/// The everyday jog right after gcud starts: a speed, then a slew
/// (`gimbalctl slew left --speed 15`: `SPF` then `PL`), on a governed
/// gimbal whose rate `SPF` raises from 2 to 5 °/s. The slew waits while
/// gcud learns the new rate, is carried out, and rests short of the zone
/// (planned with the old rate it would run into it). How long gcud may
/// take to learn is the client's delivery budget (three quarters of it):
/// on a busy machine the simulated gimbal answers late (a retransmission,
/// then the late-answer quiet, took 0.7 s under load 12), so this client
/// gives it 3 s, as an operator on a slow bus would, instead of racing the
/// default 0.8 s.
#[test]
fn the_everyday_jog_slews_a_governed_gimbal_and_stops_short_of_its_zone() {
    let budget = format!("{NEAR}[link_timing]\ndelivery_timeout_ms = 3000\n");
    let s = Stack::start(&["--max-rate", "5", "--rate", "2", "--accel", "20"], 10_000, &budget);
    let (child, stdin) = slew(&s, "left", &["--speed", "15", "--ack-timeout", "4000"]);
    let (pan, _) = s.bus_position();
    drop(stdin);
    assert_eq!(support::cli::wait_output(child).code, 0);
    assert!(
        s.bus().iter().any(|(source, p)| *source == 0 && p == "SPF"),
        "{:?}",
        s.bus()
    );
    eprintln!("jog left at speed 15: rests at pan {pan} (zone from -10)");
    assert!(pan >= -10.5, "into the zone: {pan}\n{}", s.logs());
    assert!(pan < -5.0, "it slewed: {pan}");
}

/// What gcud cannot bound on a governed gimbal, or what would change its
/// address, line, limits or dynamics, is refused before the bus (exit 28),
/// sent to the gimbal or through a wildcard, by any link.
#[test]
fn commands_gcud_cannot_bound_are_refused_on_a_governed_gimbal_and_never_reach_it() {
    let s = Stack::start(&[], 10_000, NEAR);
    let refused = || s.gcud.metric("gcud_commands_delivery_total{delivery=\"ungoverned\"}");
    for payload in ["*mp10.0,0.0", "*me", "*mr1", "*sl", "LC", "QQ", "#07", "IX", "HP"] {
        let out = s.ctl(&s.operators, &["--to", GIMBAL, "raw", payload]);
        assert_eq!(out.code, 28, "{payload}: {out:?}\n{}", s.logs());
        assert!(out.stderr.contains("cannot bound"), "{out:?}");
        // To every device of the port (gimbalctl awaits no answer of a broadcast): refused for 5.1.1.
        let before = refused();
        s.ctl(&s.operators, &["--to", "5.1.255", "raw", payload]);
        s.eventually("gcud's refusal of the broadcast", || refused() > before);
        assert!(
            !s.bus().iter().any(|(_, p)| p == payload),
            "{payload} reached the gimbal: {:?}",
            s.bus()
        );
    }
    // 5.1.1 still answers as 5.1.1.
    s.ok(&s.operators, &["goto", "1", "0", "--wait"]);
}

/// A preset query's answer is where the preset lies, not where the gimbal
/// is: after `P?05` (and `preset recall 5 --wait`, which asks it first)
/// gcud still checks a goto's path from the gimbal's real place.
#[test]
fn a_preset_query_never_becomes_where_gcud_believes_the_gimbal_is() {
    let s = Stack::start(&["--max-rate", "30", "--rate", "30", "--accel", "120"], 10_000, NEAR);
    // Preset 5 above the zone (-30, 20), reached around it.
    s.ok(&s.clients, &["goto", "0", "20", "--wait"]);
    s.ok(&s.clients, &["goto", "-30", "20", "--wait"]);
    s.ok(&s.clients, &["preset", "store", "5"]);
    s.ok(&s.clients, &["goto", "0", "20", "--wait"]);
    s.ok(&s.clients, &["goto", "0", "0", "--wait"]);
    // From (0, 0) the recall's path crosses the zone (pan -20..-10, tilt up to 10).
    let out = s.ctl(&s.clients, &["--to", GIMBAL, "preset", "recall", "5", "--wait"]);
    assert_eq!(out.code, 25, "{out:?}\n{}", s.logs());
    assert!(
        !s.bus().iter().any(|(_, p)| p == "P05"),
        "the recall reached the gimbal"
    );
    s.ok(&s.clients, &["raw", "P?05"]);
    let out = s.ctl(&s.clients, &["--to", GIMBAL, "goto", "-30", "-5"]);
    assert_eq!(out.code, 25, "{out:?}\n{}", s.logs());
    assert!(!s.bus().iter().any(|(_, p)| *p == goto_payload(-30.0, -5.0)));
    let (pan, tilt) = s.bus_position();
    assert!(pan.abs() < 0.05 && tilt.abs() < 0.05, "({pan}, {tilt})");
}

/// gcud killed (SIGKILL) while a governed gimbal slews toward its zone,
/// and started again: it finds the gimbal moving with nobody to stop it,
/// and stops it (the gimbal's own answers, on the bus side).
#[test]
fn gcud_killed_mid_slew_and_started_again_stops_the_gimbal_it_finds_moving() {
    const FAR: &str = "[[gimbal]]\naddress = \"5.1.1\"\npan_limits_deg = [-170.0, 170.0]\n\
                       [[gimbal.keep_out]]\npan_deg = [20.0, 40.0]\ntilt_deg = [-30.0, 10.0]\n";
    let mut s = Stack::start(&["--max-rate", "4", "--rate", "4", "--accel", "20"], 10_000, FAR);
    let (child, stdin) = slew(&s, "right", &[]);
    std::thread::sleep(Duration::from_millis(500));
    s.gcud.child.kill().expect("SIGKILL");
    s.gcud.child.wait().expect("reaped");
    drop(stdin);
    let _ = support::cli::wait_output(child);
    let killed_at = answered_positions(&s.sim.log()).len();
    std::thread::sleep(Duration::from_millis(1000));
    let again = Gcud::start(&s.config);
    again.wait_for_log("port open port=1");
    s.eventually("gcud's stop after its start", || {
        bus_events(&s.sim.log())
            .iter()
            .skip_while(|e| e.payload != "PR")
            .any(|e| e.kind == Kind::Received && e.source == 5 && e.payload == "PT")
    });
    let _ = killed_at;
    // Still from then on, well short of the zone.
    let mut last = None;
    s.eventually("the gimbal to stand still", || {
        std::thread::sleep(Duration::from_millis(200));
        let _ = again.position(GIMBAL);
        let now = answered_positions(&s.sim.log()).last().copied();
        let still = now.is_some() && now == last;
        last = now;
        still
    });
    let (pan, _) = last.expect("a position");
    eprintln!("killed mid-slew: stopped at pan {pan} (zone from 20)");
    assert!(pan > 1.0 && pan < 19.5, "{pan}\n{}", again.log());
    assert_eq!(again.metric("gcud_governance_found_moving_total"), 1);
}

/// GCU commands by priority: a tour is started or stopped only from the
/// highest link's priority (default `tours_min_priority`), `~R` only from
/// the holder's link or a higher one, not an equal one.
#[test]
fn tours_and_release_answer_by_priority() {
    let extra =
        format!("{TOUR}[[link]]\nname = \"console\"\nrole = \"client\"\nlisten = \"127.0.0.1:0\"\npriority = 80\n");
    let s = Stack::start(&[], 10_000, &extra);
    let console = s.gcud.address("listening link=console");
    let out = s.ctl(&s.clients, &["tour", "start", "round"]);
    assert_eq!(out.code, 32, "{out:?}");
    assert_eq!(s.tour("round")["state"], "stopped", "{}", s.gcud.status());
    std::thread::sleep(Duration::from_millis(500));
    assert!(
        tour_gotos(&s).is_empty(),
        "no tour goto reached the gimbal: {:?}",
        s.bus()
    );
    let out = s.ctl(&s.operators, &["tour", "start", "round"]);
    assert_eq!(out.code, 0, "{out:?}");
    let out = s.ctl(&s.clients, &["tour", "stop", "round"]);
    assert_eq!(out.code, 32, "{out:?}");
    assert_eq!(s.ctl(&s.operators, &["tour", "stop", "round"]).code, 0);
    s.ok(&s.operators, &["goto", "5", "0"]);
    let out = s.ctl(&console, &["--to", GIMBAL, "release"]);
    assert_eq!(out.code, 23, "an equal priority cannot free the holder: {out:?}");
    assert_eq!(s.control()["holder"]["name"], "operators", "{}", s.gcud.status());
}

/// The demo as shipped (its listeners on ports of their own): a goto of the
/// roof gimbal 5.2.1 the moment gcud is ready is carried out, and the
/// everyday jog (`slew right --speed 5`: `SP5` then `PR`) slews it and
/// rests short of its keep-out zone (pan 100..130), where the gimbal itself
/// answers it is.
#[test]
fn on_the_demo_a_goto_at_once_runs_and_a_jog_stops_short_of_the_roof_gimbals_zone() {
    let demo = std::fs::read_to_string(concat!(env!("CARGO_MANIFEST_DIR"), "/config/demo.toml")).expect("demo");
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
    let clients = gcud.clients();
    let roof = |args: &[&str]| {
        let mut full = vec!["--tcp", clients.as_str(), "--to", "5.2.1"];
        full.extend_from_slice(args);
        support::gimbalctl(&full)
    };
    let out = roof(&["goto", "80", "0", "--wait"]);
    assert_eq!(out.code, 0, "a goto the moment gcud is ready: {out:?}\n{}", gcud.log());
    let jog = [
        "--tcp",
        clients.as_str(),
        "--to",
        "5.2.1",
        "slew",
        "right",
        "--speed",
        "5",
        "--hold",
    ];
    let mut child = support::cli::spawn_ctl(&jog);
    let stdin = child.stdin.take().expect("stdin");
    let (pan, tilt) = gcud.settled_position("5.2.1");
    drop(stdin);
    let out = support::cli::wait_output(child);
    assert_eq!(out.code, 0, "the jog was carried out: {out:?}\n{}", gcud.log());
    eprintln!("demo jog right at speed 5: rests at pan {pan} (zone from 100)");
    assert!(tilt.abs() < 0.05, "{tilt}");
    assert!(pan > 85.0, "it slewed toward the zone: {pan}");
    assert!(pan <= 100.5, "into the zone: {pan}\n{}", gcud.log());
    assert!(
        gcud.received("5.2.1").iter().any(|(_, p)| p == "SP5"),
        "the speed reached the gimbal"
    );
}

/// Control lasts while the holder holds: a held slew (`gimbalctl slew
/// --hold`, which renews gcud's motion lease with `P?`) keeps the operators'
/// control long past `hold_ms`, so the clients are refused (exit 23); their
/// stops, below the holder, pass one a second (more: exit 29).
#[test]
fn a_held_slew_keeps_control_past_hold_ms_and_stops_from_below_are_limited() {
    let s = Stack::start(&["--max-rate", "5", "--rate", "5", "--accel", "20"], 1000, "");
    let (child, stdin) = s.hold(&s.operators, &["slew", "right"]);
    s.eventually("the held slew on the bus", || s.bus().iter().any(|(_, p)| p == "PR"));
    std::thread::sleep(Duration::from_millis(2500));
    let out = s.ctl(&s.clients, &["--to", GIMBAL, "goto", "-10", "0"]);
    assert_eq!(
        out.code,
        23,
        "2.5 s into a held slew, past hold_ms (1 s): {out:?}\n{}",
        s.logs()
    );
    let stops = |s: &Stack| s.bus().iter().filter(|(source, p)| *source == 0 && p == "PT").count();
    let before = stops(&s);
    let codes: Vec<i32> = (0..6)
        .map(|_| s.ctl(&s.clients, &["--to", GIMBAL, "stop"]).code)
        .collect();
    assert!(codes.contains(&29), "stops from below limited: {codes:?}");
    assert!(codes.iter().filter(|&&c| c == 0).count() <= 2, "{codes:?}");
    // On the wire: as many of the clients' stops as were let through, no more.
    let passed = codes.iter().filter(|&&c| c == 0).count();
    assert_eq!(stops(&s) - before, passed, "{:?}", s.bus());
    drop(stdin);
    assert_eq!(support::cli::wait_output(child).code, 0);
}

/// An acceleration lowered mid-slew (`AP0001`, to the gimbal and through
/// the wildcards) would brake the gimbal too slowly to stop short: gcud
/// refuses it (exit 24), never on the bus, and the slew rests short of the
/// limit; a wildcard `SPF` before a slew is learnt before the slew, which
/// stops short too (the gimbal's own answers).
#[test]
fn a_slower_acceleration_mid_slew_and_a_wildcard_speed_before_one_cannot_take_the_gimbal_past_its_limit() {
    let s = Stack::start(&["--max-rate", "5", "--rate", "2", "--accel", "20"], 10_000, NEAR);
    s.ok(&s.operators, &["goto", "0", "0", "--wait"]);
    let (child, stdin) = s.hold(&s.operators, &["slew", "right"]);
    s.eventually("the slew on the bus", || s.bus().iter().any(|(_, p)| p == "PR"));
    for to in [GIMBAL, "5.1.255", "5.255.255"] {
        let out = s.ctl(&s.operators, &["--to", to, "raw", "AP0001"]);
        if to == GIMBAL {
            assert_eq!(out.code, 24, "AP0001 mid-slew: {out:?}\n{}", s.logs());
        }
    }
    let (pan, _) = s.bus_position();
    drop(stdin);
    assert_eq!(support::cli::wait_output(child).code, 0);
    assert!(!s.bus().iter().any(|(_, p)| p == "AP0001"), "{:?}", s.bus());
    assert!(pan > 5.0 && pan <= 10.5, "rests at {pan} (limit 10)\n{}", s.logs());
    // A wildcard SPF (2 to 5 deg/s), then a slew at once toward the zone.
    s.ok(&s.operators, &["goto", "0", "0", "--wait"]);
    let out = s.ctl(&s.operators, &["--to", "5.255.255", "raw", "SPF"]);
    assert_eq!(out.code, 0, "{out:?}");
    let lefts = |s: &Stack| s.bus().iter().filter(|(_, p)| p == "PL").count();
    let before = lefts(&s);
    let (child, stdin) = s.hold(&s.operators, &["slew", "left"]);
    s.eventually("the slew on the bus", || lefts(&s) > before);
    let (pan, _) = s.bus_position();
    drop(stdin);
    assert_eq!(support::cli::wait_output(child).code, 0);
    eprintln!("after a wildcard SPF: rests at pan {pan} (zone from -10)");
    // Never into the zone; short of it by as much as gcud could not see (on
    // a busy machine its margin grows with answers that came late: -2.76
    // under load 12), but it slewed.
    assert!((-10.5..-1.0).contains(&pan), "{pan}\n{}", s.logs());
}
