//! One test per rule of ARCHITECTURE "Governance", driving the public
//! `Router` with simulated gimbals on a bus (`tests/rig`): control by
//! priority with hold time and take-over, travel limits and keep-out
//! zones (gotos checked, slews followed and stopped short), tours, park,
//! release and reload.

mod rig;

use rig::{G, Got, ONE, PORT, Rig, THREE, TWO, gimbal, outcome, pos};
use sagebrush_gcu::{
    GimbalRules, Governance, Holder, Park, RouterEvent, Span, TourConfig, TourState, TourStep, TourTarget, Zone,
};
use sagebrush_protocol::gcu::{ControllerReply, parse_rules, parse_tour_reply};
use sagebrush_protocol::{Address, Command, GcuCommand, RuleItem, Undelivered};

const HOLD: u64 = 2000;

/// A rig at 115200 bit/s with gimbal 1, `rules` on it, and two client
/// links: `ONE` ("vms", priority 50) and `TWO` ("ops", priority 80).
fn rig(rules: impl FnOnce(&mut Governance)) -> Rig {
    let mut r = Rig::new(115_200, vec![gimbal(1)], |c| {
        c.governance.hold = HOLD;
        rules(&mut c.governance);
    });
    r.client(ONE, "vms", 50);
    r.client(TWO, "ops", 80);
    // Learning: position, rates, accelerations, presets.
    r.run(3000);
    r
}

fn bounded(g: &mut Governance) {
    let mut rules = GimbalRules::new(PORT, 1);
    rules.pan_limits = Some(Span::new(-9000, 9000));
    rules.tilt_limits = Some(Span::new(-3000, 6000));
    rules.keep_out.push(Zone {
        pan: Span::new(-6000, -4000),
        tilt: Span::new(-3000, 1000),
    });
    g.gimbals.push(rules);
}

fn holder(r: &Rig) -> Option<Holder> {
    r.router
        .control()
        .into_iter()
        .find(|c| (c.port, c.device) == (PORT, 1))?
        .holder
}

#[test]
fn a_lower_link_is_refused_while_a_higher_one_holds_control_but_its_stops_and_queries_pass() {
    let mut r = rig(|_| {});
    r.send(TWO, 1, &Command::GoTo(pos(10.0, 0.0)));
    r.run(50);
    assert_eq!(outcome(&r.got(TWO)), Some(Ok(())));
    assert_eq!(
        holder(&r),
        Some(Holder::Link {
            name: "ops".into(),
            priority: 80
        })
    );
    let before = r.now;
    r.send(ONE, 1, &Command::GoTo(pos(-10.0, 0.0)));
    r.run(50);
    assert_eq!(outcome(&r.got(ONE)), Some(Err(Some(Undelivered::NotInControl))));
    assert!(
        !r.bus_commands_since(before)
            .iter()
            .any(|c| c.starts_with('P') && c.len() == 9),
        "nothing of the refused goto reaches the bus: {:?}",
        r.bus_commands_since(before)
    );
    // Its stop and its query pass.
    r.send(ONE, 1, &Command::PanStop);
    r.run(50);
    assert_eq!(outcome(&r.got(ONE)), Some(Ok(())));
    r.send(ONE, 1, &Command::QueryPosition);
    r.run(50);
    assert!(
        r.got(ONE).iter().any(|g| matches!(g, Got::Frame(_))),
        "the query is answered"
    );
    assert!(r.bus_commands_since(before).contains(&"PS".to_string()));
}

#[test]
fn control_lapses_hold_after_the_holders_last_command_and_a_dropped_connection_keeps_it() {
    let mut r = rig(|_| {});
    r.send(
        TWO,
        1,
        &Command::SetSpeed(
            sagebrush_protocol::Axis::Pan,
            sagebrush_protocol::Speed::new(3).unwrap(),
        ),
    );
    r.run(50);
    // The connection goes away; a new one of the same link comes: still "ops".
    r.drop_link(TWO);
    r.run(HOLD / 2);
    r.send(ONE, 1, &Command::Home);
    r.run(50);
    assert_eq!(outcome(&r.got(ONE)), Some(Err(Some(Undelivered::NotInControl))));
    r.client(THREE, "ops", 80);
    r.send(THREE, 1, &Command::Home);
    r.run(50);
    assert_eq!(
        outcome(&r.got(THREE)),
        Some(Ok(())),
        "another connection of the holding link"
    );
    r.run(HOLD + 100);
    assert_eq!(holder(&r), None, "lapsed");
    r.send(ONE, 1, &Command::Home);
    r.run(50);
    assert_eq!(outcome(&r.got(ONE)), Some(Ok(())));
    assert_eq!(
        holder(&r),
        Some(Holder::Link {
            name: "vms".into(),
            priority: 50
        })
    );
}

#[test]
fn a_higher_link_takes_over_and_the_bus_sees_the_stop_before_its_motion() {
    let mut r = rig(|_| {});
    r.send(ONE, 1, &Command::PanRight);
    r.run(300);
    assert!(r.moving(1));
    let before = r.now;
    r.send(TWO, 1, &Command::TiltUp);
    r.run(100);
    assert_eq!(outcome(&r.got(TWO)), Some(Ok(())));
    let seen = r.bus_commands_since(before);
    let stop = seen.iter().position(|c| c == "PS" || c == "PT");
    let motion = seen.iter().position(|c| c == "TU");
    assert!(
        matches!((stop, motion), (Some(s), Some(m)) if s < m),
        "stop first, then the new motion: {seen:?}"
    );
    assert_eq!(
        holder(&r),
        Some(Holder::Link {
            name: "ops".into(),
            priority: 80
        })
    );
    assert_eq!(r.router.governance_stats().takeovers, 1);
    // Equal priority does not take over.
    r.client(THREE, "other", 80);
    r.send(THREE, 1, &Command::TiltDown);
    r.run(50);
    assert_eq!(outcome(&r.got(THREE)), Some(Err(Some(Undelivered::NotInControl))));
}

#[test]
fn release_is_allowed_from_the_holders_priority_or_higher() {
    let mut r = rig(|_| {});
    r.send(TWO, 1, &Command::Home);
    r.run(50);
    let release = |r: &mut Rig, link| {
        let mut buf = [0u8; 16];
        let n = GcuCommand::Release(PORT, 1).encode(&mut buf).unwrap();
        r.send_payload(link, Address::new(G, 0, 0), &buf[..n]);
        r.run(20);
        outcome(&r.got(link))
    };
    assert_eq!(release(&mut r, ONE), Some(Err(Some(Undelivered::NotInControl))));
    assert!(holder(&r).is_some());
    // `~C` names the holder.
    let mut buf = [0u8; 16];
    let n = GcuCommand::Controller(PORT, 1).encode(&mut buf).unwrap();
    r.send_payload(ONE, Address::new(G, 0, 0), &buf[..n]);
    r.run(20);
    let got = r.got(ONE);
    let frame = got
        .iter()
        .find_map(|g| if let Got::Frame(p) = g { Some(p.clone()) } else { None });
    assert_eq!(
        frame.as_deref().and_then(ControllerReply::parse),
        Some((
            PORT,
            1,
            ControllerReply::Link {
                priority: 80,
                name: b"ops"
            }
        ))
    );
    assert_eq!(release(&mut r, TWO), Some(Ok(())));
    assert_eq!(holder(&r), None);
    r.send(ONE, 1, &Command::Home);
    r.run(50);
    assert_eq!(outcome(&r.got(ONE)), Some(Ok(())));
}

/// `~B` of gimbal `device`: the parsed result frame, if any.
fn rules_of(r: &mut Rig, device: u8) -> Option<(u8, u8, Vec<RuleItem>)> {
    let mut buf = [0u8; 16];
    let n = GcuCommand::Rules(PORT, device).encode(&mut buf).unwrap();
    r.send_payload(ONE, Address::new(G, 0, 0), &buf[..n]);
    r.run(20);
    r.got(ONE).iter().find_map(|g| match g {
        Got::Frame(p) => parse_rules(p).map(|(p, d, items)| (p, d, items.collect())),
        _ => None,
    })
}

#[test]
fn rules_are_answered_from_the_governance_and_cost_no_bus_time() {
    let mut r = rig(bounded);
    let before = r.now;
    assert_eq!(
        rules_of(&mut r, 1),
        Some((
            PORT,
            1,
            vec![
                RuleItem::PanLimits([-9000, 9000]),
                RuleItem::TiltLimits([-3000, 6000]),
                RuleItem::KeepOut {
                    pan: [-6000, -4000],
                    tilt: [-3000, 1000]
                },
            ]
        ))
    );
    // A gimbal without rules: the header alone.
    assert_eq!(rules_of(&mut r, 9), Some((PORT, 9, vec![])));
    assert!(
        r.bus_commands_since(before).is_empty(),
        "answered by the GCU: {:?}",
        r.bus_commands_since(before)
    );
}

#[test]
fn gotos_past_a_limit_or_into_a_zone_are_refused_and_nothing_reaches_the_bus() {
    let mut r = rig(bounded);
    let before = r.now;
    for (target, why) in [
        (pos(95.0, 0.0), Undelivered::TravelLimit),
        (pos(0.0, 70.0), Undelivered::TravelLimit),
        (pos(-50.0, 0.0), Undelivered::KeepOut),
        // Only the path meets the zone: the rectangle from (0, 0) to (-80, -20).
        (pos(-80.0, -20.0), Undelivered::KeepOut),
    ] {
        r.send(ONE, 1, &Command::GoTo(target));
        r.run(50);
        assert_eq!(outcome(&r.got(ONE)), Some(Err(Some(why))), "{target:?}");
    }
    let gotos: Vec<String> = r
        .bus_commands_since(before)
        .into_iter()
        .filter(|c| c.len() == 9)
        .collect();
    assert!(gotos.is_empty(), "{gotos:?}");
    // Around the zone: up first, then across above it.
    for target in [pos(0.0, 20.0), pos(-80.0, 20.0)] {
        r.send(ONE, 1, &Command::GoTo(target));
        r.run(3000);
        assert_eq!(outcome(&r.got(ONE)), Some(Ok(())), "{target:?}");
    }
}

/// Slews toward `boundary_deg` on `axis` and checks where the gimbal came
/// to rest on the bus side: short of it, by at most the documented margin.
fn slew_stops_short(command: Command<'static>, axis: usize, boundary: i32, dir: i32, speed: u8) -> i32 {
    let mut r = rig(bounded);
    r.send(
        ONE,
        1,
        &Command::SetSpeed(
            if axis == 0 {
                sagebrush_protocol::Axis::Pan
            } else {
                sagebrush_protocol::Axis::Tilt
            },
            sagebrush_protocol::Speed::new(speed).unwrap(),
        ),
    );
    r.run(200);
    r.send(ONE, 1, &command);
    let mut farthest = i32::MIN;
    r.run_with(10_000, 2, |r| farthest = farthest.max(dir * r.position(1)[axis]));
    assert_eq!(
        outcome(&r.got(ONE)).and_then(Result::ok),
        Some(()),
        "the slew was let through"
    );
    assert!(!r.moving(1), "it stopped");
    let past = farthest - dir * boundary;
    assert!(past <= 50, "{} hundredths of a degree past the boundary", past);
    assert!(r.router.governance_stats().boundary_stops >= 1);
    -past
}

#[test]
fn a_slew_toward_a_limit_is_stopped_short_of_it() {
    for speed in [7, 15] {
        let short = slew_stops_short(Command::PanRight, 0, 9000, 1, speed);
        eprintln!("speed {speed}: rested {short} hundredths short of the limit");
        assert!(short < 2000, "stopped {short} short: too early to be useful");
    }
}

#[test]
fn a_slew_toward_a_zone_is_stopped_short_of_it() {
    let short = slew_stops_short(Command::PanLeft, 0, -4000, -1, 7);
    eprintln!("rested {short} hundredths short of the zone");
    assert!(short < 600, "stopped {short} short");
}

#[test]
fn a_slew_that_cannot_be_stopped_in_time_or_of_an_unknown_gimbal_is_refused() {
    // Right after start nothing is known yet.
    let mut r = Rig::new(115_200, vec![gimbal(1)], |c| bounded(&mut c.governance));
    r.client(ONE, "vms", 50);
    r.send(ONE, 1, &Command::PanRight);
    r.run(20);
    assert_eq!(outcome(&r.got(ONE)), Some(Err(Some(Undelivered::PositionUnknown))));
    r.run(3000);
    // A hundredth of a degree short of the limit: no room to stop short of it.
    r.send(ONE, 1, &Command::GoTo(pos(89.9, 0.0)));
    r.run(5000);
    r.send(ONE, 1, &Command::PanRight);
    r.run(20);
    assert_eq!(outcome(&r.got(ONE)), Some(Err(Some(Undelivered::TravelLimit))));
}

fn tour(g: &mut Governance) {
    g.tours.push(TourConfig {
        name: "perimeter".into(),
        port: PORT,
        device: 1,
        steps: vec![
            TourStep {
                to: TourTarget::Position(pos(20.0, 0.0)),
                dwell: 1000,
            },
            TourStep {
                to: TourTarget::Position(pos(-20.0, 10.0)),
                dwell: 1000,
            },
        ],
    });
}

fn tour_command(r: &mut Rig, link: sagebrush_gcu::LinkId, command: GcuCommand<'_>) -> Option<(TourState, Vec<u8>)> {
    let mut buf = [0u8; 64];
    let n = command.encode(&mut buf).unwrap();
    r.send_payload(link, Address::new(G, 0, 0), &buf[..n]);
    r.run(10);
    r.got(link).iter().find_map(|g| match g {
        Got::Frame(p) => parse_tour_reply(p).map(|(s, h)| (s, h.to_vec())),
        _ => None,
    })
}

#[test]
fn a_tour_runs_its_steps_pauses_for_an_operator_and_resumes_after_hold() {
    let mut r = rig(tour);
    assert_eq!(
        tour_command(&mut r, ONE, GcuCommand::TourStart(b"perimeter")).map(|t| t.0),
        Some(TourState::Running)
    );
    let mut visited = Vec::new();
    r.run_with(8000, 20, |r| {
        let p = r.position(1);
        if !r.moving(1) && visited.last() != Some(&p) {
            visited.push(p);
        }
    });
    assert!(
        visited.contains(&[2000, 0]) && visited.contains(&[-2000, 1000]),
        "{visited:?}"
    );
    assert!(matches!(holder(&r), Some(Holder::Tour(_))));
    // An operator moves the gimbal: the tour waits for control to lapse.
    r.send(ONE, 1, &Command::GoTo(pos(0.0, 30.0)));
    r.run(HOLD / 2);
    assert_eq!(outcome(&r.got(ONE)), Some(Ok(())));
    assert_eq!(r.router.tours()[0].state, TourState::Waiting);
    assert_eq!(r.position(1), [0, 3000], "the tour did not move it meanwhile");
    r.run(HOLD + 3000);
    assert_eq!(r.router.tours()[0].state, TourState::Running);
    assert_ne!(r.position(1), [0, 3000], "it resumed");
    // Stopped: it gives control back.
    assert_eq!(
        tour_command(&mut r, ONE, GcuCommand::TourStop(b"perimeter")).map(|t| t.0),
        Some(TourState::Stopped)
    );
    assert_eq!(holder(&r), None);
}

#[test]
fn a_tour_started_while_a_link_holds_control_waits_and_says_for_whom() {
    let mut r = rig(tour);
    r.send(TWO, 1, &Command::Home);
    r.run(50);
    let reply = tour_command(&mut r, ONE, GcuCommand::TourStart(b"perimeter"));
    assert_eq!(reply, Some((TourState::Waiting, b"ops".to_vec())));
    r.run(HOLD + 500);
    assert_eq!(r.router.tours()[0].state, TourState::Running);
    assert!(
        tour_command(&mut r, ONE, GcuCommand::TourStart(b"nosuch")).is_none(),
        "unknown tour: NIC"
    );
}

#[test]
fn park_recalls_its_preset_once_after_control_lapsed() {
    let mut r = rig(|g| {
        let mut rules = GimbalRules::new(PORT, 1);
        rules.park = Some(Park { preset: 2, after: 1000 });
        g.gimbals.push(rules);
    });
    // Preset 2 at (30, 5), then away, within the hold time.
    r.send(ONE, 1, &Command::GoTo(pos(30.0, 5.0)));
    r.run(1200);
    r.send(ONE, 1, &Command::StorePreset(2));
    r.run(50);
    r.send(ONE, 1, &Command::GoTo(pos(-10.0, 0.0)));
    r.run(HOLD - 500);
    assert_eq!(r.position(1), [-1000, 0]);
    assert_eq!(r.router.governance_stats().parks, 0, "not while the link holds control");
    r.run(500 + 1000 + 3000);
    assert_eq!(r.position(1), [3000, 500], "parked at preset 2");
    assert_eq!(r.router.governance_stats().parks, 1);
    let recalls = |r: &Rig| r.bus_commands_since(0).iter().filter(|c| c.as_str() == "P02").count();
    assert_eq!(recalls(&r), 1, "the bus saw one recall of preset 2");
    r.run(10_000);
    assert_eq!(r.router.governance_stats().parks, 1, "once until moved again");
    assert_eq!(recalls(&r), 1, "no second recall on the bus");
    assert!(r.events.iter().any(|(_, e)| matches!(
        e,
        RouterEvent::Park {
            preset: 2,
            refused: None,
            ..
        }
    )));
}

#[test]
fn reload_applies_changed_rules_as_a_difference() {
    let mut r = rig(|_| {});
    r.send(TWO, 1, &Command::GoTo(pos(50.0, 0.0)));
    r.run(50);
    let mut config = sagebrush_gcu::RouterConfig::new(G);
    config.ports = vec![rig::port(115_200)];
    config.governance.hold = HOLD;
    bounded(&mut config.governance);
    let mut out = sagebrush_gcu::Outbox::new();
    r.router.reconfigure(r.now, config, &[], &mut out).expect("reload");
    assert_eq!(
        holder(&r),
        Some(Holder::Link {
            name: "ops".into(),
            priority: 80
        }),
        "control kept"
    );
    r.run(1000);
    r.send(TWO, 1, &Command::GoTo(pos(95.0, 0.0)));
    r.run(50);
    assert_eq!(
        outcome(&r.got(TWO)),
        Some(Err(Some(Undelivered::TravelLimit))),
        "the new limits hold"
    );
}
