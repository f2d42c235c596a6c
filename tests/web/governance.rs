//! gcud's decisions on the page (ARCHITECTURE "Governance"): a refused
//! command's reason on the card, the holder named, the map of gcud's rules,
//! release reserved to administrators and refused under a higher link.

use super::*;

/// A command gcud refuses shows gcud's reason on its card, below the
/// pad, which does not move.
#[test]
fn a_command_refused_by_gcud_shows_its_reason_on_the_card() {
    if !browser_available() {
        return;
    }
    let stack = Stack::start();
    let mut b = stack.browser("op", "op-secret");
    let pad = json!({ "op": "place", "card": "absent", "button": "Pan left" });
    let before = stack.call(&mut b, pad.clone());
    stack.call(&mut b, json!({ "op": "click", "card": "absent", "button": "Home" }));
    let reason = stack.call(&mut b, json!({ "op": "wait_alert", "card": "absent" }));
    let reason = reason.as_str().unwrap();
    assert!(reason.contains("5.2.9"), "the reason names the gimbal: {reason}");
    // The reason fills in below the pad: a button held there stays under
    // the pointer (one that moved away would end its hold, or take none).
    assert_eq!(stack.call(&mut b, pad), before, "the pad moved when the reason showed");
    // The same words gimbal-web answered with (the page adds none of its own).
    let log = stack.log();
    eprintln!("absent gimbal: {reason}\n{log}");
    // The other cards are not affected.
    let other = stack.call(&mut b, json!({ "op": "status", "card": "mast-2" }));
    assert!(other.as_str().unwrap().contains("Pan 0.00°"), "{other}");
}

/// gcud decides who controls a gimbal (issue 34 with issue 32): while the
/// operators' link (gimbalctl, priority 80) holds mast-1, its card names
/// the holder; a held "Pan right" is refused with gcud's words on the card,
/// and the page then sends no stop (it would end the holder's motion):
/// the door puts nothing but queries on mast-1's bus. mast-2, which nobody
/// holds, still moves from the page.
/// Needs gcud's `[control] hold_ms` and `[[link]] priority`.
#[test]
fn the_card_names_the_holder_and_a_refused_move_shows_gcuds_reason() {
    if !browser_available() {
        return;
    }
    let stack = Stack::start_on(support::door::start_governed_gcud());
    let mut b = stack.browser("op", "op-secret");
    let out = support::door::operators_ctl(&stack.gcud, &["--to", MAST, "goto", "20", "10"]);
    assert_eq!(out.code, 0, "{out:?}");
    let at = stack.gcud.settled_position(MAST);
    let note = stack.call(
        &mut b,
        json!({ "op": "wait_note", "card": "mast-1", "contains": support::door::OPERATORS_HOLDER }),
    );
    eprintln!("mast-1's note: {note}");
    stack.call(&mut b, json!({ "op": "hold", "card": "mast-1", "button": "Pan right" }));
    let reason = stack.call(&mut b, json!({ "op": "wait_alert", "card": "mast-1" }));
    let reason = reason.as_str().unwrap().to_owned();
    stack.call(&mut b, json!({ "op": "release" }));
    assert!(
        reason.contains("refused by gcud") && reason.contains(support::door::OPERATORS_HOLDER),
        "gcud's words on the card: {reason}"
    );
    support::door::assert_still(&stack.gcud, MAST, at, "a refused hold");
    support::door::assert_door_sent_only_queries(&stack.gcud, MAST);
    // Nobody holds mast-2: the page moves it (and takes control of it).
    let other = "5.2.1";
    let from = stack.gcud.position(other);
    stack.call(&mut b, json!({ "op": "hold", "card": "mast-2", "button": "Tilt up" }));
    wait_moving(&stack.gcud, other, from);
    stack.call(&mut b, json!({ "op": "release" }));
    bus_stop_time(&stack.gcud, other, "TS");
    eprintln!("refused: {reason}");
}

/// gcud's rules of mast-1 in the governed gcud's configuration: limits
/// and one keep-out zone.
const RULES: &str = "[[gimbal]]\naddress = \"5.1.1\"\npan_limits_deg = [-90.0, 90.0]\ntilt_limits_deg = [-30.0, 60.0]\n\
                     [[gimbal.keep_out]]\npan_deg = [-60.0, -30.0]\ntilt_deg = [-30.0, 10.0]\n";

/// The number of gotos (`Paaaaeeee`, Table 11) the door sent `address`.
fn door_gotos(gcud: &Gcud, address: &str) -> usize {
    door_frames(gcud, address)
        .iter()
        .filter(|p| p.len() == 9 && p.starts_with('P'))
        .count()
}

/// The pan/tilt map (issue 34): gcud's limits and keep-out zone of mast-1
/// (asked with `~B`) are drawn on its card as gcud's configuration has
/// them; a click on the map goes there (read on the bus); a click into the
/// zone shows gcud's refusal on the card and nothing moves.
#[test]
fn the_map_draws_gcuds_rules_and_a_click_goes_there_or_shows_gcuds_refusal() {
    if !browser_available() {
        return;
    }
    let stack = Stack::start_on(support::door::start_governed_gcud_with(RULES));
    let mut b = stack.browser("op", "op-secret");
    let map = stack.call(&mut b, json!({ "op": "map", "card": "mast-1" }));
    assert_eq!(
        map["zones"],
        json!([{ "pan-lo": -60.0, "pan-hi": -30.0, "tilt-lo": -30.0, "tilt-hi": 10.0 }]),
        "{map}"
    );
    // x, y (minus the top tilt), width, height.
    assert_eq!(map["limits"], json!([-90, -60, 180, 90]), "{map}");
    // mast-2 has no rules: no zone, no limits.
    let other = stack.call(&mut b, json!({ "op": "map", "card": "mast-2", "zones": 0 }));
    assert_eq!(other, json!({ "zones": [], "limits": null }), "{other}");
    // A goto of a bounded gimbal waits while gcud learns where it is, then runs.
    let out = stack.gcud.ctl(&["--to", MAST, "goto", "0", "0", "--wait"]);
    assert_eq!(out.code, 0, "{out:?}");
    // The card names the holder (gimbalctl's goto, through the doors'
    // link) before the click: the map no longer moves on the page.
    stack.call(
        &mut b,
        json!({ "op": "wait_note", "card": "mast-1", "contains": "link clients" }),
    );
    // An eighth of the map right of its centre and a sixth above: pan 45°,
    // tilt 30° of the default travel (-180..180, -90..90).
    stack.call(
        &mut b,
        json!({ "op": "click_picture", "card": "mast-1", "fx": 0.125, "fy": -1.0 / 6.0 }),
    );
    eventually("the click's goto to be reached on the bus", || {
        let (pan, tilt) = stack.gcud.position(MAST);
        (pan - 45.0).abs() < 2.0 && (tilt - 30.0).abs() < 2.0
    });
    assert_eq!(door_gotos(&stack.gcud, MAST), 1);
    let at = stack.gcud.settled_position(MAST);
    // Into the zone's middle (pan -45°, tilt -10°): gcud refuses, its words on the card.
    stack.call(
        &mut b,
        json!({ "op": "click_picture", "card": "mast-1", "fx": -0.125, "fy": 10.0 / 180.0 }),
    );
    let reason = stack.call(&mut b, json!({ "op": "wait_alert", "card": "mast-1" }));
    let reason = reason.as_str().unwrap().to_owned();
    assert!(
        reason.contains("refused by gcud") && reason.contains("keep-out"),
        "gcud's words on the card: {reason}"
    );
    support::door::assert_still(&stack.gcud, MAST, at, "a goto into the zone");
    assert_eq!(
        door_gotos(&stack.gcud, MAST),
        1,
        "nothing of the refused goto on the bus"
    );
    eprintln!("refused: {reason}");
}

/// Release (issue 34): an administrator's "Release" sends gcud's `~R`;
/// gcud refuses it while the operators' link (priority 80, above the
/// doors') holds the gimbal, and the card shows its words; it releases what
/// the page itself holds. An operator gets 403 and sends nothing.
#[test]
fn release_is_the_administrators_and_gcud_refuses_it_under_a_higher_link() {
    if !browser_available() {
        return;
    }
    let stack = Stack::start_on(support::door::start_governed_gcud());
    // An operator: no Release on the card, the request refused.
    let mut op = stack.browser("op", "op-secret");
    let buttons = stack.call(&mut op, json!({ "op": "buttons", "card": "mast-1" }));
    assert!(!buttons.as_array().unwrap().contains(&json!("Release")), "{buttons}");
    let answer = stack.call(
        &mut op,
        json!({ "op": "fetch", "path": "/api/release", "with_token": true, "body": { "gimbal": 1 } }),
    );
    assert_eq!(answer["status"], 403, "{answer}");
    assert!(answer["body"].as_str().unwrap().contains("administrator"), "{answer}");
    // The page moves mast-2: gimbal-web's link holds it.
    let other = "5.2.1";
    let from = stack.gcud.position(other);
    stack.call(&mut op, json!({ "op": "hold", "card": "mast-2", "button": "Tilt up" }));
    wait_moving(&stack.gcud, other, from);
    stack.call(&mut op, json!({ "op": "release" }));
    bus_stop_time(&stack.gcud, other, "TS");
    stack.call(
        &mut op,
        json!({ "op": "wait_note", "card": "mast-2", "contains": "this page's gcud link" }),
    );
    drop(op);
    // The operators' console holds mast-1.
    let out = support::door::operators_ctl(&stack.gcud, &["--to", MAST, "goto", "20", "10"]);
    assert_eq!(out.code, 0, "{out:?}");
    let mut admin = stack.browser("admin", "admin-secret");
    stack.call(
        &mut admin,
        json!({ "op": "wait_note", "card": "mast-1", "contains": support::door::OPERATORS_HOLDER }),
    );
    // Release does not apply to a gimbal the page does not hold: the card
    // shows none, and the request itself is refused in gcud's words.
    let buttons = stack.call(&mut admin, json!({ "op": "buttons", "card": "mast-1" }));
    assert!(!buttons.as_array().unwrap().contains(&json!("Release")), "{buttons}");
    let answer = stack.call(
        &mut admin,
        json!({ "op": "fetch", "path": "/api/release", "with_token": true, "body": { "gimbal": 0 } }),
    );
    let reason = answer["body"].as_str().unwrap().to_owned();
    assert!(reason.contains("refused by gcud"), "gcud's words: {answer}");
    // The operators still hold it.
    stack.call(
        &mut admin,
        json!({ "op": "wait_note", "card": "mast-1", "contains": support::door::OPERATORS_HOLDER }),
    );
    // mast-2, held by the page's link: released.
    stack.call(
        &mut admin,
        json!({ "op": "click", "card": "mast-2", "button": "Release" }),
    );
    stack.call(
        &mut admin,
        json!({ "op": "wait_text", "card": "mast-2", "contains": ["Released"] }),
    );
    stack.call(
        &mut admin,
        json!({ "op": "wait_note", "card": "mast-2", "contains": "Nobody controls it" }),
    );
    eprintln!("refused release: {reason}");
}

/// A held "Pan left" on a governed gimbal (issue 48: the page's session
/// sends a speed, then the direction, and gcud refused the direction, 409)
/// moves mast-1 toward its keep-out zone (pan -90..-60), and gcud's own
/// stop keeps it short of the zone while the button is still held (where it
/// rests, read on the bus); the release then sends the page's stop.
#[test]
fn a_held_pan_toward_the_zone_moves_the_governed_gimbal_and_stops_short_of_it() {
    if !browser_available() {
        return;
    }
    let rules = "[[gimbal]]\naddress = \"5.1.1\"\npan_limits_deg = [-170.0, 170.0]\n\
                 [[gimbal.keep_out]]\npan_deg = [-90.0, -60.0]\ntilt_deg = [-30.0, 10.0]\n";
    let stack = Stack::start_on(support::door::start_governed_gcud_with(rules));
    let mut b = stack.browser("op", "op-secret");
    stack.call(&mut b, json!({ "op": "hold", "card": "mast-1", "button": "Pan left" }));
    eventually("the page's slew on the bus (not refused)", || {
        door_frames(&stack.gcud, MAST).contains(&"PL".to_owned())
    });
    support::door::wait_for_stop(&stack.gcud, MAST, support::door::GCUD_GROUP, "PS");
    let (pan, tilt) = stack.gcud.settled_position(MAST);
    stack.call(&mut b, json!({ "op": "release" }));
    eprintln!("held Pan left toward the zone: rests at pan {pan} (zone from -60)");
    assert!(pan < -30.0, "it moved: {pan}");
    assert!(tilt.abs() < 0.05, "{tilt}");
    assert!(pan >= -60.5, "into the zone: {pan}\n{}", stack.gcud.log());
    bus_stop_time(&stack.gcud, MAST, "PS");
    support::door::assert_still(&stack.gcud, MAST, (pan, tilt), "after the release");
}
