//! Tours listed, started and stopped by an administrator through gcud;
//! the screenshot of the demo page (docs/gimbal-web.png).

use super::*;

/// gimbal-web with one gimbal, mast-1 (5.1.1), in front of a stand-in gcud
/// at `gcud`: the door and its page's URL.
fn web_before(gcud: &str) -> (Door, String) {
    let mut web = Door::new("gimbal-web", env!("CARGO_BIN_EXE_gimbal-web"));
    web.start(&format!(
        "gcud = \"{gcud}\"\nlisten = \"127.0.0.1:0\"\nsource_group = {DOOR_GROUP}\n{USERS}\
         [[gimbal]]\nname = \"mast-1\"\naddress = \"5.1.1\"\n"
    ));
    let url = format!("http://127.0.0.1:{}/", web.port("page listening"));
    (web, url)
}

/// gcud's tours on the page (issue 34): listed with their state, started
/// and stopped through gcud's `~T+` and `~T-` by an administrator (with
/// the page's CSRF token), never by a user or an operator. gcud here is a stand-in
/// (`support::fake_gcud`) answering as gcud does, since tours cannot be
/// configured in gcud.toml yet; it records what the page sent.
#[test]
fn tours_are_listed_and_an_administrator_starts_and_stops_them_through_gcud() {
    if !browser_available() {
        return;
    }
    use sagebrush_protocol::TourState;
    use sagebrush_protocol::gcu::{encode_tour_list, encode_tour_reply};
    use support::fake_gcud::{Answer, FakeGcud, position};
    let state = std::sync::Arc::new(std::sync::Mutex::new(TourState::Stopped));
    let tours = std::sync::Arc::clone(&state);
    let gcud = FakeGcud::start(move |p| {
        let mut buf = [0u8; 64];
        let mut now = tours.lock().unwrap();
        match p {
            b"P?" => position(0.0, 0.0),
            b"~T?" => {
                let n = encode_tour_list([(&b"perimeter"[..], *now)], &mut buf);
                Answer::Result(buf[..n].to_vec())
            }
            b"~T+perimeter" | b"~T-perimeter" => {
                *now = if p[2] == b'+' {
                    TourState::Running
                } else {
                    TourState::Stopped
                };
                let n = encode_tour_reply(*now, b"", &mut buf).unwrap();
                Answer::Result(buf[..n].to_vec())
            }
            b"~C0101" if *now == TourState::Running => {
                let n = sagebrush_protocol::ControllerReply::Tour(b"perimeter")
                    .encode(1, 1, &mut buf)
                    .unwrap();
                Answer::Result(buf[..n].to_vec())
            }
            b"~C0101" => {
                let n = sagebrush_protocol::ControllerReply::Nobody
                    .encode(1, 1, &mut buf)
                    .unwrap();
                Answer::Result(buf[..n].to_vec())
            }
            _ => Answer::Nic,
        }
    });
    let (web, url) = web_before(&gcud.addr);
    let log = || web.log();
    // A user sees the tours and may not start one.
    let mut viewer = Browser::start();
    viewer.call(json!({ "op": "open", "url": url }), log);
    viewer.call(
        json!({ "op": "sign_in", "user": "viewer", "password": "viewer-secret" }),
        log,
    );
    viewer.call(
        json!({ "op": "wait_text", "card": "Tours", "contains": ["perimeter", "stopped"] }),
        log,
    );
    let disabled = viewer.call(
        json!({ "op": "disabled", "card": "Tours", "button": "Start tour perimeter" }),
        log,
    );
    assert_eq!(disabled, json!(true));
    let answer = viewer.call(
        json!({ "op": "fetch", "path": "/api/tour", "with_token": true,
                "body": { "name": "perimeter", "start": true } }),
        log,
    );
    assert_eq!(answer["status"], 403, "{answer}");
    drop(viewer);
    // Neither may an operator (tours are the administrator's, issue 34).
    let mut op = Browser::start();
    op.call(json!({ "op": "open", "url": url }), log);
    op.call(json!({ "op": "sign_in", "user": "op", "password": "op-secret" }), log);
    op.call(
        json!({ "op": "wait_text", "card": "Tours", "contains": ["perimeter", "stopped"] }),
        log,
    );
    let disabled = op.call(
        json!({ "op": "disabled", "card": "Tours", "button": "Start tour perimeter" }),
        log,
    );
    assert_eq!(disabled, json!(true), "an operator's tour buttons are disabled");
    let answer = op.call(
        json!({ "op": "fetch", "path": "/api/tour", "with_token": true,
                "body": { "name": "perimeter", "start": true } }),
        log,
    );
    assert_eq!(answer["status"], 403, "{answer}");
    assert!(answer["body"].as_str().unwrap().contains("administrator"), "{answer}");
    drop(op);
    assert!(
        !gcud.got().contains(&"~T+perimeter".to_owned()),
        "nothing sent for them"
    );
    // An administrator starts it, sees it running and the card controlled by it, and stops it.
    let mut b = Browser::start();
    b.call(json!({ "op": "open", "url": url }), log);
    b.call(
        json!({ "op": "sign_in", "user": "admin", "password": "admin-secret" }),
        log,
    );
    let answer = b.call(
        json!({ "op": "fetch", "path": "/api/tour", "with_token": false,
                "body": { "name": "perimeter", "start": true } }),
        log,
    );
    assert_eq!(answer["status"], 403, "without the CSRF token: {answer}");
    assert!(!gcud.got().contains(&"~T+perimeter".to_owned()), "nothing sent for it");
    b.call(
        json!({ "op": "click", "card": "Tours", "button": "Start tour perimeter" }),
        log,
    );
    b.call(
        json!({ "op": "wait_text", "card": "Tours", "contains": ["perimeter", "running"] }),
        log,
    );
    let note = b.call(
        json!({ "op": "wait_note", "card": "mast-1", "contains": "tour perimeter" }),
        log,
    );
    eprintln!("mast-1's note: {note}");
    b.call(
        json!({ "op": "click", "card": "Tours", "button": "Stop tour perimeter" }),
        log,
    );
    b.call(
        json!({ "op": "wait_text", "card": "Tours", "contains": ["perimeter", "stopped"] }),
        log,
    );
    let got = gcud.got();
    let start = got.iter().position(|p| p == "~T+perimeter").expect("~T+ sent");
    let stop = got.iter().position(|p| p == "~T-perimeter").expect("~T- sent");
    assert!(start < stop, "{got:?}");
    assert_eq!(got.iter().filter(|p| p.starts_with("~T+")).count(), 1, "{got:?}");
}

/// The page with the README demo's three gimbals (config/demo.toml's buses,
/// the shipped config/gimbal-web.toml) as a screenshot, after a goto on one
/// of them; and the page's weight. With `SAGEBRUSH_WRITE_SCREENSHOT=1` the
/// screenshot replaces docs/gimbal-web.png; otherwise it goes to a
/// temporary directory.
#[test]
fn screenshot_of_the_demo_page() {
    if !browser_available() {
        return;
    }
    let gcud = Gcud::start(&format!(
        "[gcu]\ngroup = 5\n[[port]]\nid = 1\nsimulate = [1, 2]\n[[port]]\nid = 2\nsimulate = [1]\n{}",
        support::gcud::CLIENTS
    ));
    let shipped = std::fs::read_to_string(Path::new(env!("CARGO_MANIFEST_DIR")).join("config/gimbal-web.toml"))
        .expect("config/gimbal-web.toml");
    let stack = Stack::with(gcud, |clients, state| {
        shipped
            .replace("gcud = \"127.0.0.1:4005\"", &format!("gcud = \"{clients}\""))
            .replace("listen = \"127.0.0.1:8080\"", "listen = \"127.0.0.1:0\"")
            .replace(
                "#state_file = \"/var/lib/gimbal-web/presets.toml\"",
                &format!("state_file = \"{}\"", state.display()),
            )
    });
    let mut b = stack.browser("admin", "change-me");
    let expect = json!(["mast-1", "mast-2", "roof", "Tours"]);
    let names = stack.call(&mut b, json!({ "op": "card_names", "expect": expect }));
    assert_eq!(names, expect, "a card per gimbal, then gcud's tours");
    assert_eq!(stack.gcud.ctl(&["--to", "5.1.2", "goto", "60", "20"]).code, 0);
    stack.call(
        &mut b,
        json!({ "op": "type", "card": "mast-1", "label": "Preset name", "text": "gate" }),
    );
    stack.call(
        &mut b,
        json!({ "op": "click", "card": "mast-1", "button": "Save preset" }),
    );
    stack.call(
        &mut b,
        json!({ "op": "disabled", "card": "mast-1", "button": "Go to preset gate" }),
    );
    stack.call(
        &mut b,
        json!({ "op": "wait_status", "card": "mast-2", "contains": ["Pan 60.00°", "Tilt 20.00°"] }),
    );
    // docs/gimbal-web.png is written only when asked (SAGEBRUSH_WRITE_SCREENSHOT=1):
    // a test run leaves the working tree as it was.
    let shots = tempfile::tempdir().expect("temp dir");
    let png = if std::env::var("SAGEBRUSH_WRITE_SCREENSHOT").is_ok_and(|v| v == "1") {
        Path::new(env!("CARGO_MANIFEST_DIR")).join("docs/gimbal-web.png")
    } else {
        shots.path().join("gimbal-web.png")
    };
    assert_eq!(
        stack.call(
            &mut b,
            json!({ "op": "screenshot", "path": png, "width": 1180, "height": 760 })
        ),
        json!(true)
    );
    let weight = stack.call(&mut b, json!({ "op": "page_weight" }));
    let bytes: u64 = weight
        .as_array()
        .unwrap()
        .iter()
        .map(|e| e[2].as_u64().unwrap_or(0))
        .sum();
    eprintln!("page weight: {bytes} bytes ({weight})");
    assert!(bytes > 0, "{weight}");
}

/// Presets saved from the page never take a number gcud reserves (issue
/// 48: the second saved preset overwrote preset 1, the demo's park preset):
/// gcud's `~B` names the presets its park and tours recall (`R01`, `R00`),
/// and the page stores at the lowest number free of both.
#[test]
fn presets_saved_from_the_page_skip_the_presets_gcud_reserves() {
    if !browser_available() {
        return;
    }
    use support::fake_gcud::{Answer, FakeGcud, position};
    let gcud = FakeGcud::start(move |p| match p {
        b"P?" => position(0.0, 0.0),
        b"~B0101" => Answer::Result(b"~B0101=PDCD82328R00R01".to_vec()),
        [b'S', _, _] => Answer::Ack,
        _ => Answer::Nic,
    });
    let (web, url) = web_before(&gcud.addr);
    let log = || web.log();
    let mut b = Browser::start();
    b.call(json!({ "op": "open", "url": url }), log);
    b.call(json!({ "op": "sign_in", "user": "op", "password": "op-secret" }), log);
    let mut stored = Vec::new();
    for name in ["gate", "yard"] {
        let answer = b.call(
            json!({ "op": "fetch", "path": "/api/preset/save", "with_token": true,
                    "body": { "gimbal": 0, "name": name } }),
            log,
        );
        assert_eq!(answer["status"], 200, "{answer}");
        stored.push(answer["body"].as_str().unwrap_or_default().to_owned());
    }
    let sent: Vec<String> = gcud.got().into_iter().filter(|p| p.starts_with('S')).collect();
    assert_eq!(sent, ["S02", "S03"], "{stored:?}\n{}", web.log());
}
