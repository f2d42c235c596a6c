//! What the page says beside the controls (issue 53): the map's axes,
//! scale and pan direction, the speed's value, a viewer's card that says
//! the viewer cannot command, Release only where it applies, and a
//! refusal shown with its time that clears once the gimbal's state changes.

use super::*;

/// The map names its axes with their travel and direction and its grid's
/// scale; the speed slider shows its value and follows it.
#[test]
fn the_map_names_its_axes_and_scale_and_the_speed_shows_its_value() {
    if !browser_available() {
        return;
    }
    let stack = Stack::start();
    let mut b = stack.browser("op", "op-secret");
    let text = stack.call(
        &mut b,
        json!({ "op": "wait_text", "card": "mast-1", "contains": ["(left)", "(right)", "(up)", "(down)", "grid every"] }),
    );
    let text = text.as_str().unwrap().to_owned();
    for want in ["← pan", "pan", "° (right) →", "↑ tilt", "↓ tilt", "°, lines through 0°"] {
        assert!(text.contains(want), "{want:?} on the card: {text}");
    }
    let shown = stack.call(&mut b, json!({ "op": "speed_step", "card": "mast-1", "steps": 2 }));
    assert_eq!(
        shown,
        json!("70 %"),
        "the value beside the slider after two steps up from 50 %"
    );
    let shown = stack.call(&mut b, json!({ "op": "speed_step", "card": "mast-1", "steps": -5 }));
    assert_eq!(shown, json!("20 %"));
}

/// A viewer's card says the viewer cannot command it (never "the next
/// command takes control") and shows no Release; an operator's shows no
/// Release either (an administrator's, where the page holds the gimbal:
/// `governance::release_is_the_administrators_and_gcud_refuses_it_under_a_higher_link`).
#[test]
fn a_viewers_card_says_the_viewer_cannot_command_and_release_shows_only_where_it_applies() {
    if !browser_available() {
        return;
    }
    let stack = Stack::start_on(support::door::start_governed_gcud());
    let mut viewer = stack.browser("viewer", "viewer-secret");
    let note = stack.call(
        &mut viewer,
        json!({ "op": "wait_note", "card": "mast-1", "contains": "your role cannot command it" }),
    );
    let note = note.as_str().unwrap().to_owned();
    assert!(!note.contains("next command takes control"), "{note}");
    let buttons = stack.call(&mut viewer, json!({ "op": "buttons", "card": "mast-1" }));
    assert!(!buttons.as_array().unwrap().contains(&json!("Release")), "{buttons}");
    drop(viewer);
    let mut op = stack.browser("op", "op-secret");
    let note = stack.call(
        &mut op,
        json!({ "op": "wait_note", "card": "mast-1", "contains": "Nobody controls it" }),
    );
    assert!(note.as_str().unwrap().contains("next command takes control"), "{note}");
    let buttons = stack.call(&mut op, json!({ "op": "buttons", "card": "mast-1" }));
    let buttons = buttons.as_array().unwrap();
    assert!(
        buttons.contains(&json!("Home")) && !buttons.contains(&json!("Release")),
        "{buttons:?}"
    );
}

/// A refused command's reason shows with the time it came and stays while
/// the gimbal's state is unchanged; once the holder lets go (the state
/// changed) it clears.
#[test]
fn a_refusal_shows_its_time_and_clears_once_the_state_changes() {
    if !browser_available() {
        return;
    }
    let stack = Stack::start_on(support::door::start_governed_gcud());
    let mut b = stack.browser("op", "op-secret");
    let out = support::door::operators_ctl(&stack.gcud, &["--to", MAST, "goto", "20", "10"]);
    assert_eq!(out.code, 0, "{out:?}");
    stack.gcud.settled_position(MAST);
    stack.call(
        &mut b,
        json!({ "op": "wait_note", "card": "mast-1", "contains": support::door::OPERATORS_HOLDER }),
    );
    stack.call(&mut b, json!({ "op": "click", "card": "mast-1", "button": "Home" }));
    let reason = stack.call(&mut b, json!({ "op": "wait_alert", "card": "mast-1" }));
    let reason = reason.as_str().unwrap().to_owned();
    assert!(reason.contains("refused by gcud"), "{reason}");
    let time = reason
        .rsplit_once(" (")
        .map(|(_, t)| t.trim_end_matches(')'))
        .unwrap_or_default();
    let parts: Vec<&str> = time.split(':').collect();
    assert!(
        parts.len() == 3
            && parts
                .iter()
                .all(|p| p.len() == 2 && p.chars().all(|c| c.is_ascii_digit())),
        "the refusal ends with its time (HH:MM:SS): {reason}"
    );
    // The state is unchanged: the reason stays past the time it is shown at least.
    std::thread::sleep(Duration::from_secs(7));
    let still = stack.call(&mut b, json!({ "op": "wait_alert", "card": "mast-1" }));
    assert_eq!(still.as_str(), Some(reason.as_str()), "cleared while nothing changed");
    // The operators let go: the card's state changes and the reason clears.
    let out = support::door::operators_ctl(&stack.gcud, &["--to", MAST, "release"]);
    assert_eq!(out.code, 0, "{out:?}");
    stack.call(
        &mut b,
        json!({ "op": "wait_note", "card": "mast-1", "contains": "Nobody controls it" }),
    );
    stack.call(
        &mut b,
        json!({ "op": "wait_no_alert", "card": "mast-1", "seconds": 20 }),
    );
}
