//! ARCHITECTURE "Principals": a connection's principal and the users a
//! door acts for (`~U`) are who the governance governs, and who the audit
//! and `~C` name; driven through the public `Router` with a simulated
//! gimbal on a bus (`tests/rig`).

mod rig;

use std::sync::Arc;

use rig::{G, Got, ONE, PORT, Rig, THREE, TWO, gimbal, holder, outcome, pos};
use sagebrush_gcu::{Holder, Input, LinkConfig, LinkKind, Principal, RouterEvent, SourceFilter};
use sagebrush_protocol::gcu::ControllerReply;
use sagebrush_protocol::{Address, Command, GcuCommand, Undelivered};

fn principal(name: &str, priority: u8, acts_for_users: bool) -> Principal {
    Principal {
        name: Arc::from(name),
        priority,
        acts_for_users,
    }
}

/// A link "doors" (priority 90) whose connections `ONE` and `TWO` are the
/// doors `gimbal-web` and `gimbal-onvif` (both act for users), and `THREE`
/// a connection of "operators" authenticated as alice; gcud knows alice
/// (80) and bob (50).
fn rig() -> Rig {
    let mut r = Rig::new(115_200, vec![gimbal(1)], |c| {
        c.governance.hold = 2000;
        c.governance.principals = vec![principal("alice", 80, false), principal("bob", 50, false)];
    });
    for (link, listener, door, priority) in [
        (ONE, "doors", principal("gimbal-web", 100, true), 90),
        (TWO, "doors", principal("gimbal-onvif", 100, true), 90),
        (THREE, "operators", principal("alice", 80, false), 100),
    ] {
        let mut config = LinkConfig::new(LinkKind::Client, SourceFilter::Any);
        config.name = Some(Arc::from(listener));
        config.priority = priority;
        config.principal = Some(door);
        r.input(Input::LinkUp { link, config });
    }
    r.run(3000);
    r
}

fn act_for(r: &mut Rig, link: sagebrush_gcu::LinkId, user: Option<&str>) -> Option<Result<(), Option<Undelivered>>> {
    let mut buf = [0u8; 40];
    let n = GcuCommand::ActFor(user.map(str::as_bytes)).encode(&mut buf).unwrap();
    r.send_payload(link, Address::new(G, 0, 0), &buf[..n]);
    r.run(20);
    outcome(&r.got(link))
}

fn goto(r: &mut Rig, link: sagebrush_gcu::LinkId, pan: f32) -> Option<Result<(), Option<Undelivered>>> {
    r.send(link, 1, &Command::GoTo(pos(pan, 0.0)));
    r.run(50);
    outcome(&r.got(link))
}

fn audit(r: &Rig) -> Vec<String> {
    r.events
        .iter()
        .filter(|(_, e)| matches!(e, RouterEvent::Motion { .. }))
        .map(|(_, e)| e.to_string())
        .collect()
}

#[test]
fn users_of_doors_are_governed_as_the_principals_gcud_knows_and_named_everywhere() {
    let mut r = rig();
    assert_eq!(act_for(&mut r, ONE, Some("bob")), Some(Ok(())));
    assert_eq!(goto(&mut r, ONE, 10.0), Some(Ok(())), "bob takes the free gimbal");
    assert_eq!(
        holder(&r),
        Some(Holder::Link {
            name: "bob".into(),
            priority: 50,
            via: Some("gimbal-web".into())
        })
    );
    // The other door, for nobody gcud knows, is the door itself (90 > 50).
    assert_eq!(act_for(&mut r, TWO, Some("carol")), Some(Ok(())));
    assert_eq!(
        goto(&mut r, TWO, 20.0),
        Some(Ok(())),
        "gimbal-onvif (90) takes over from bob"
    );
    // Alice through the first door outranks nobody at 80 < 90: refused.
    assert_eq!(act_for(&mut r, ONE, Some("alice")), Some(Ok(())));
    assert_eq!(goto(&mut r, ONE, 30.0), Some(Err(Some(Undelivered::NotInControl))));
    // The same door, acting for nobody, is a different controller than
    // its user bob was: its own priority.
    assert_eq!(act_for(&mut r, ONE, None), Some(Ok(())));
    assert_eq!(
        goto(&mut r, ONE, 40.0),
        Some(Err(Some(Undelivered::NotInControl))),
        "90 = 90"
    );
    let log = audit(&r);
    assert!(
        log.iter()
            .any(|l| l.starts_with("bob via gimbal-web: ") && l.ends_with(" accepted")),
        "{log:#?}"
    );
    assert!(
        log.iter().any(|l| l.starts_with("gimbal-onvif for carol via doors: ")),
        "{log:#?}"
    );
    assert!(
        log.iter()
            .any(|l| l.starts_with("alice via gimbal-web: ") && l.contains("refused")),
        "{log:#?}"
    );
}

#[test]
fn one_person_is_one_controller_across_tools_and_the_controller_query_names_the_tool() {
    let mut r = rig();
    assert_eq!(act_for(&mut r, ONE, Some("alice")), Some(Ok(())));
    assert_eq!(goto(&mut r, ONE, 10.0), Some(Ok(())));
    // Alice on her own connection is the same controller: no take-over, no refusal.
    assert_eq!(goto(&mut r, THREE, 20.0), Some(Ok(())));
    assert!(
        !r.events
            .iter()
            .any(|(_, e)| matches!(e, RouterEvent::Control { from: Some(_), .. })),
        "no take-over between one person's tools"
    );
    let mut buf = [0u8; 16];
    let n = GcuCommand::Controller(PORT, 1).encode(&mut buf).unwrap();
    r.send_payload(TWO, Address::new(G, 0, 0), &buf[..n]);
    r.run(20);
    let frame = r
        .got(TWO)
        .into_iter()
        .find_map(|g| if let Got::Frame(p) = g { Some(p) } else { None })
        .expect("a ~C result");
    assert_eq!(
        ControllerReply::parse(&frame),
        Some((
            PORT,
            1,
            ControllerReply::Link {
                priority: 80,
                name: b"alice",
                via: b"operators",
                yours: false,
            }
        ))
    );
}

#[test]
fn only_a_door_may_act_for_users() {
    let mut r = rig();
    assert_eq!(
        act_for(&mut r, THREE, Some("bob")),
        Some(Err(Some(Undelivered::NotPermitted))),
        "alice's own connection may not speak as bob"
    );
    // A link without principals may not either.
    r.client(ONE, "plain", 50);
    assert_eq!(
        act_for(&mut r, ONE, Some("alice")),
        Some(Err(Some(Undelivered::NotPermitted)))
    );
}
