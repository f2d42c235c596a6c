//! Moving a gimbal from the page: hold and release stop on the bus and the
//! position text follows (with the latency figures), a page closed or a
//! browser killed while holding stops by the door's lease, a click on the
//! picture goes there, presets saved and recalled.

use super::*;

/// Holds `button` on mast-1's card, lets the gimbal move, then ends the
/// hold by `end` (an op of browser.py that returns when it happened, in
/// seconds since the epoch); the bus must see the door's `stop` within
/// [`STOP_WITHIN_S`] of it, and the gimbal must stay still after.
fn hold_then(stack: &Stack, b: &mut Browser, button: &str, stop: &str, end: Value) -> (f64, (f64, f64)) {
    let from = stack.gcud.position(MAST);
    stack.call(b, json!({ "op": "hold", "card": "mast-1", "button": button }));
    wait_moving(&stack.gcud, MAST, from);
    std::thread::sleep(Duration::from_millis(1000));
    let answer = stack.call(b, end);
    let ended = answer.get("at").unwrap_or(&answer).as_f64().expect("a time");
    let stopped = bus_stop_time(&stack.gcud, MAST, stop);
    let after = stopped - ended;
    assert!(
        after <= STOP_WITHIN_S,
        "the bus saw {stop} {after:.3} s after the hold ended (at most {STOP_WITHIN_S})\ngimbal-web log:\n{}",
        stack.log()
    );
    let at = stack.gcud.settled_position(MAST);
    support::door::assert_still(&stack.gcud, MAST, at, "after the stop");
    support::door::assert_no_stop_from_gcud(&stack.gcud, MAST);
    eprintln!(
        "{button}: held, then {}: {stop} on the bus {:.0} ms later",
        answer,
        after * 1000.0
    );
    (after, at)
}

#[test]
fn hold_pan_right_then_release_stops_on_the_bus_and_the_position_text_follows() {
    if !browser_available() {
        return;
    }
    let stack = Stack::start();
    let mut b = stack.browser("op", "op-secret");
    let (_, at) = hold_then(&stack, &mut b, "Pan right", "PS", json!({ "op": "release" }));
    assert!(at.0 > 0.0, "pan right moved pan up from 0: {at:?}");
    assert!(door_frames(&stack.gcud, MAST).contains(&"PR".to_owned()));
    // The position text follows the gimbal: the bus's settled position.
    let text = stack.call(
        &mut b,
        json!({ "op": "wait_status", "card": "mast-1",
                "contains": [format!("Pan {:.2}°", at.0), format!("Tilt {:.2}°", at.1)] }),
    );
    eprintln!("position text: {text}");
    // And when something else moves it (gimbalctl, through gcud).
    let out = stack.gcud.ctl(&["--to", MAST, "goto", "-20", "15"]);
    assert_eq!(out.code, 0, "{out:?}");
    stack.call(
        &mut b,
        json!({ "op": "wait_status", "card": "mast-1", "contains": ["Pan -20.00°", "Tilt 15.00°"] }),
    );
    // An arrow key held on the focused card moves it while held.
    let from = stack.gcud.position(MAST);
    stack.call(&mut b, json!({ "op": "key_down", "card": "mast-1", "key": "ARROW_UP" }));
    wait_moving(&stack.gcud, MAST, from);
    let released = stack.call(&mut b, json!({ "op": "key_up", "key": "ARROW_UP" }));
    let stopped = bus_stop_time(&stack.gcud, MAST, "TS");
    assert!(
        stopped - released.as_f64().unwrap() <= STOP_WITHIN_S,
        "TS {} s after the key was released",
        stopped - released.as_f64().unwrap()
    );
    assert!(stack.gcud.settled_position(MAST).1 > 15.0, "tilt up");
    figures(&stack, &mut b);
}

/// Figures for the closing note, printed (never asserted on): button press
/// to the first motion frame on the bus (gcud's bus-side record), p50 and
/// the largest of 20 presses; position updates the page got a second while
/// moving.
fn figures(stack: &Stack, b: &mut Browser) {
    let mut latencies = Vec::new();
    let mut updates = Vec::new();
    for i in 0..20 {
        let button = if i % 2 == 0 { "Pan right" } else { "Pan left" };
        let pressed = stack.call(b, json!({ "op": "hold", "card": "mast-1", "button": button }));
        let pressed = pressed.as_f64().expect("a time");
        let n = stack.call(b, json!({ "op": "count_updates", "card": "mast-1", "seconds": 1 }));
        updates.push(n.as_u64().expect("a count"));
        stack.call(b, json!({ "op": "release" }));
        let prefix = format!("rx frame dest={MAST} source={DOOR_GROUP} payload=");
        let first = stack
            .gcud
            .log()
            .lines()
            .filter(|l| l.contains(&prefix))
            .find(|l| {
                let p = &l[l.find(&prefix).unwrap() + prefix.len()..];
                ["SP", "PR", "PL"].iter().any(|m| p.starts_with(m)) && log_time(l) >= pressed
            })
            .map(log_time);
        if let Some(t) = first {
            latencies.push(t - pressed);
        }
        bus_stop_time(&stack.gcud, MAST, "PS");
    }
    // Push latency: from the gimbal answering a position (its `tx result`
    // in the simulator's log) to the page showing it.
    stack.call(b, json!({ "op": "hold", "card": "mast-1", "button": "Pan right" }));
    let shown = stack.call(b, json!({ "op": "watch_positions", "card": "mast-1", "seconds": 2 }));
    stack.call(b, json!({ "op": "release" }));
    bus_stop_time(&stack.gcud, MAST, "PS");
    let log = stack.gcud.log();
    let (_, port_device) = MAST.split_once('.').expect("G.P.D");
    let answered: Vec<(f64, i64)> = log
        .lines()
        .filter(|l| l.contains(" tx result ") && l.contains(&format!(".{port_device} ")))
        .filter_map(|l| {
            let payload = l.split("payload=").nth(1)?.split_whitespace().next()?;
            let hex = payload.trim_start_matches('P');
            let pan = i16::from_str_radix(hex.get(..4)?, 16).ok()?;
            Some((log_time(l), i64::from(pan)))
        })
        .collect();
    let mut push = Vec::new();
    for entry in shown.as_array().into_iter().flatten() {
        let (Some(t), Some(text)) = (entry[0].as_f64(), entry[1].as_str()) else {
            continue;
        };
        let Some(pan) = text
            .split("Pan ")
            .nth(1)
            .and_then(|s| s.split('°').next())
            .and_then(|s| s.trim().parse::<f64>().ok())
        else {
            continue;
        };
        let centi = (pan * 100.0).round() as i64;
        if let Some(at) = answered
            .iter()
            .rev()
            .find(|(at, p)| *p == centi && *at <= t)
            .map(|a| a.0)
        {
            push.push(t - at);
        }
    }
    push.sort_by(f64::total_cmp);
    assert!(
        !push.is_empty(),
        "no pushed position matched an answer of the gimbal: {shown}"
    );
    eprintln!(
        "FIGURES: position push latency, gimbal's answer to the page: p50 {:.1} ms, max {:.1} ms ({} updates)",
        push[push.len() / 2] * 1000.0,
        push.last().copied().unwrap_or_default() * 1000.0,
        push.len()
    );
    latencies.sort_by(f64::total_cmp);
    updates.sort_unstable();
    eprintln!(
        "FIGURES: press to first motion frame on the bus: p50 {:.1} ms, max {:.1} ms ({} presses); \
         position updates on the page while moving: median {} /s (min {}, max {})",
        latencies[latencies.len() / 2] * 1000.0,
        latencies.last().copied().unwrap_or_default() * 1000.0,
        latencies.len(),
        updates[updates.len() / 2],
        updates[0],
        updates[updates.len() - 1]
    );
}

#[test]
fn a_page_closed_while_holding_stops_the_gimbal_by_the_doors_lease() {
    if !browser_available() {
        return;
    }
    let stack = Stack::start();
    let mut b = stack.browser("op", "op-secret");
    hold_then(&stack, &mut b, "Pan left", "PS", json!({ "op": "close_page" }));
}

#[test]
fn a_browser_killed_while_holding_stops_the_gimbal_by_the_doors_lease() {
    if !browser_available() {
        return;
    }
    let stack = Stack::start();
    let mut b = stack.browser("op", "op-secret");
    let (_, _) = hold_then(&stack, &mut b, "Tilt down", "TS", json!({ "op": "kill_browser" }));
}

#[test]
fn a_click_on_the_picture_goes_there_and_presets_are_saved_and_recalled() {
    if !browser_available() {
        return;
    }
    let stack = Stack::start();
    let mut b = stack.browser("op", "op-secret");
    // A quarter of the picture right of and above its centre: pan 90°, tilt 45°
    // of the default travel (-180..180, -90..90), to within a pixel's worth.
    stack.call(
        &mut b,
        json!({ "op": "click_picture", "card": "mast-1", "fx": 0.25, "fy": -0.25 }),
    );
    eventually("the goto to be reached on the bus", || {
        let (pan, tilt) = stack.gcud.position(MAST);
        (pan - 90.0).abs() < 2.0 && (tilt - 45.0).abs() < 2.0
    });
    // `Paaaaeeee` (Table 11): a goto, not a slew.
    let sent = door_frames(&stack.gcud, MAST);
    assert!(sent.iter().any(|p| p.len() == 9 && p.starts_with('P')), "{sent:?}");
    assert!(
        !sent.iter().any(|p| ["PR", "PL", "TU", "TD"].contains(&p.as_str())),
        "{sent:?}"
    );
    let there = stack.gcud.settled_position(MAST);
    stack.call(
        &mut b,
        json!({ "op": "type", "card": "mast-1", "label": "Preset name", "text": "gate <1>" }),
    );
    stack.call(
        &mut b,
        json!({ "op": "click", "card": "mast-1", "button": "Save preset" }),
    );
    // The button appears once the name is stored; the gimbal stored the position.
    stack.call(
        &mut b,
        json!({ "op": "disabled", "card": "mast-1", "button": "Go to preset gate <1>" }),
    );
    assert!(
        door_frames(&stack.gcud, MAST).contains(&"S00".to_owned()),
        "{:?}",
        stack.gcud.received(MAST)
    );
    stack.call(&mut b, json!({ "op": "click", "card": "mast-1", "button": "Home" }));
    eventually("home to be reached on the bus", || {
        stack.gcud.position(MAST) == (0.0, 0.0)
    });
    stack.call(
        &mut b,
        json!({ "op": "click", "card": "mast-1", "button": "Go to preset gate <1>" }),
    );
    eventually("the preset to be reached on the bus", || {
        stack.gcud.position(MAST) == there
    });
    assert!(door_frames(&stack.gcud, MAST).contains(&"P00".to_owned()));
    let state = std::fs::read_to_string(stack.web.dir.path().join("presets.toml")).expect("the state file");
    assert!(state.contains("gate <1>"), "{state}");
}
