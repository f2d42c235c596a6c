//! gimbal-web end to end (issue 34) in a real browser: Debian's chromium,
//! headless, driven by Selenium (`tests/web/browser.py`, installed by
//! `.ci/run`; under `CI=true` a missing browser fails), through real gcud
//! and its simulated buses. What a gimbal did is read on the bus side (the
//! simulated gimbals' own `rx frame` record in gcud's log, with its
//! timestamps, and `gimbalctl position`), never in gimbal-web's account.
//! gcud's motion lease is off here (`start_gcud` sets none), so every stop
//! after a release, a closed page or a killed browser is gimbal-web's own.

mod support;

use std::io::{BufRead, BufReader, Read, Write};
use std::path::Path;
use std::process::{Child, ChildStdin, ChildStdout, Command, Stdio};
use std::time::Duration;

use serde_json::{Value, json};
use support::door::{DOOR_GROUP, Door, python_client_available, start_gcud, wait_moving};
use support::gcud::Gcud;
use support::{HANG_GUARD, eventually};

const MAST: &str = "5.1.1";
/// The longest from a release (or a closed page, a killed browser) to the
/// stop on the bus: the issue's bound.
const STOP_WITHIN_S: f64 = 0.5;

/// Whether Selenium, chromium and chromedriver are installed; when not, the
/// test is skipped, and under `CI=true` it fails.
fn browser_available() -> bool {
    if !python_client_available("selenium", "selenium (pip install selenium)") {
        return false;
    }
    let missing: Vec<&str> = ["/usr/bin/chromium", "/usr/bin/chromedriver"]
        .into_iter()
        .filter(|p| !Path::new(p).exists())
        .collect();
    if missing.is_empty() {
        return true;
    }
    let msg = format!("{missing:?} missing (apt-get install chromium chromium-driver; .ci/run installs them)");
    if std::env::var("CI").is_ok_and(|v| v == "true") {
        panic!("{msg}");
    }
    eprintln!("SKIPPED: {msg}");
    false
}

/// The browser: `tests/web/browser.py`, one JSON request a line.
struct Browser {
    child: Child,
    stdin: ChildStdin,
    stdout: BufReader<ChildStdout>,
}

impl Browser {
    fn start() -> Self {
        let script = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/web/browser.py");
        let mut child = Command::new(support::door::python())
            .arg(script)
            .stdin(Stdio::piped())
            .stdout(Stdio::piped())
            .stderr(Stdio::inherit())
            .spawn()
            .expect("run tests/web/browser.py");
        let stdin = child.stdin.take().expect("stdin");
        let stdout = BufReader::new(child.stdout.take().expect("stdout"));
        let mut b = Self { child, stdin, stdout };
        assert_eq!(b.read(), json!({ "ok": "ready" }));
        b
    }

    fn read(&mut self) -> Value {
        let mut line = String::new();
        self.stdout.read_line(&mut line).expect("read the browser's answer");
        serde_json::from_str(&line).unwrap_or_else(|e| panic!("the browser's answer is not JSON ({e}): {line:?}"))
    }

    /// Runs `request`; its `ok` value (a failure fails the test with `log`).
    fn call(&mut self, request: Value, log: impl FnOnce() -> String) -> Value {
        writeln!(self.stdin, "{request}").expect("write to the browser");
        let answer = self.read();
        match answer.get("ok") {
            Some(ok) => ok.clone(),
            None => panic!("{request}: {answer}\ngimbal-web log:\n{}", log()),
        }
    }
}

impl Drop for Browser {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

/// gcud with its simulated buses and gimbal-web in front of it.
struct Stack {
    /// Declared first: dropped (stopped) before gcud.
    web: Door,
    gcud: Gcud,
    url: String,
}

const USERS: &str = r#"
[[user]]
name = "op"
password = "op-secret"
role = "operator"
[[user]]
name = "viewer"
password = "viewer-secret"
role = "user"
[[user]]
name = "admin"
password = "admin-secret"
role = "administrator"
"#;

impl Stack {
    /// [`start_gcud`]'s buses: mast-1 (5.1.1), mast-2 (5.2.1) and the
    /// absent 5.2.9.
    fn start() -> Self {
        Self::start_on(start_gcud())
    }

    /// [`Stack::start`] in front of `gcud` (the governed one of
    /// `support::door::start_governed_gcud`, with the same buses).
    fn start_on(gcud: Gcud) -> Self {
        let gimbals = "[[gimbal]]\nname = \"mast-1\"\naddress = \"5.1.1\"\n\
                       [[gimbal]]\nname = \"mast-2\"\naddress = \"5.2.1\"\n\
                       [[gimbal]]\nname = \"absent\"\naddress = \"5.2.9\"\n";
        Self::with(gcud, |clients, state| {
            format!(
                "gcud = \"{clients}\"\nlisten = \"127.0.0.1:0\"\nsource_group = {DOOR_GROUP}\nstate_file = \"{}\"\n{USERS}{gimbals}",
                state.display()
            )
        })
    }

    fn with(gcud: Gcud, config: impl FnOnce(&str, &Path) -> String) -> Self {
        let mut web = Door::new("gimbal-web", env!("CARGO_BIN_EXE_gimbal-web"));
        let state = web.dir.path().join("presets.toml");
        web.start(&config(&gcud.clients(), &state));
        let url = format!("http://127.0.0.1:{}/", web.port("page listening"));
        Self { web, gcud, url }
    }

    fn log(&self) -> String {
        self.web.log()
    }

    /// A browser on the page, signed in as `user`.
    fn browser(&self, user: &str, password: &str) -> Browser {
        let mut b = Browser::start();
        let log = || self.log();
        b.call(json!({ "op": "open", "url": self.url }), log);
        b.call(json!({ "op": "sign_in", "user": user, "password": password }), log);
        b.call(json!({ "op": "card_names" }), log);
        b
    }

    fn call(&self, b: &mut Browser, request: Value) -> Value {
        b.call(request, || self.log())
    }
}

/// A gcud log line's timestamp (RFC 3339, UTC), seconds since the epoch.
fn log_time(line: &str) -> f64 {
    let stamp = line.split_whitespace().next().unwrap_or_default();
    let t = time::OffsetDateTime::parse(stamp, &time::format_description::well_known::Rfc3339)
        .unwrap_or_else(|e| panic!("no timestamp ({e}) in {line:?}"));
    t.unix_timestamp_nanos() as f64 / 1e9
}

/// The bus-side time at which gimbal `address` received `stop` from the
/// door after the last motion command it received (waits for it).
fn bus_stop_time(gcud: &Gcud, address: &str, stop: &str) -> f64 {
    let prefix = format!("rx frame dest={address} source={DOOR_GROUP} payload=");
    let motion = |p: &str| ["PR", "PL", "TU", "TD"].iter().any(|m| p.starts_with(m));
    let started = std::time::Instant::now();
    loop {
        let log = gcud.log();
        let frames: Vec<(&str, &str)> = log
            .lines()
            .filter_map(|l| {
                let rest = &l[l.find(&prefix)? + prefix.len()..];
                Some((l, rest.split_whitespace().next().unwrap_or_default()))
            })
            .collect();
        if let Some(last) = frames.iter().rposition(|(_, p)| motion(p)) {
            if let Some((line, _)) = frames[last + 1..].iter().find(|(_, p)| *p == stop) {
                return log_time(line);
            }
        }
        assert!(
            started.elapsed() < HANG_GUARD,
            "no {stop} from the door reached {address} after its last motion\ngcud log:\n{log}"
        );
        std::thread::sleep(Duration::from_millis(20));
    }
}

/// The payloads the door (its source group) sent gimbal `address`.
fn door_frames(gcud: &Gcud, address: &str) -> Vec<String> {
    gcud.received(address)
        .into_iter()
        .filter(|(source, _)| *source == DOOR_GROUP)
        .map(|(_, p)| p)
        .collect()
}

/// A raw HTTP/1.1 request to gimbal-web: the status code and the whole answer.
fn raw(url: &str, method: &str, path: &str, headers: &[(&str, &str)], body: &str) -> (u16, String) {
    let addr = url.trim_start_matches("http://").trim_end_matches('/');
    let mut s = std::net::TcpStream::connect(addr).expect("connect to gimbal-web");
    s.set_read_timeout(Some(HANG_GUARD)).expect("timeout");
    let mut head = format!(
        "{method} {path} HTTP/1.1\r\nHost: {addr}\r\nConnection: close\r\nContent-Length: {}\r\n",
        body.len()
    );
    for (k, v) in headers {
        head.push_str(&format!("{k}: {v}\r\n"));
    }
    write!(s, "{head}\r\n{body}").expect("request");
    let mut text = String::new();
    s.read_to_string(&mut text).expect("answer");
    let status = text.split_whitespace().nth(1).and_then(|c| c.parse().ok()).unwrap_or(0);
    (status, text)
}

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

#[test]
fn a_user_role_cannot_move_anything() {
    if !browser_available() {
        return;
    }
    let stack = Stack::start();
    let mut b = stack.browser("viewer", "viewer-secret");
    for button in [
        "Pan left",
        "Pan right",
        "Tilt up",
        "Tilt down",
        "Stop",
        "Home",
        "Save preset",
    ] {
        assert_eq!(
            stack.call(&mut b, json!({ "op": "disabled", "card": "mast-1", "button": button })),
            json!(true),
            "{button} is disabled for a user"
        );
    }
    // The page's own request, with its cookie and CSRF token, is refused too.
    let answer = stack.call(
        &mut b,
        json!({ "op": "fetch", "path": "/api/move", "with_token": true,
                "body": { "gimbal": 0, "pan": 1, "tilt": 0, "speed": 1.0 } }),
    );
    assert_eq!(answer["status"], 403, "{answer}");
    assert!(answer["body"].as_str().unwrap().contains("may not move"), "{answer}");
    let answer = stack.call(
        &mut b,
        json!({ "op": "fetch", "path": "/api/home", "with_token": true, "body": { "gimbal": 0 } }),
    );
    assert_eq!(answer["status"], 403, "{answer}");
    std::thread::sleep(Duration::from_millis(300));
    let sent = door_frames(&stack.gcud, MAST);
    assert!(
        sent.iter().all(|p| p == "P?" || p == "D?"),
        "a user's session sent only queries: {sent:?}"
    );
}

#[test]
fn a_wrong_password_and_a_post_without_the_csrf_token_are_refused() {
    if !browser_available() {
        return;
    }
    let stack = Stack::start();
    // In the browser: the sign-in form says why, and no card appears.
    let mut b = Browser::start();
    stack.call(&mut b, json!({ "op": "open", "url": stack.url }));
    stack.call(&mut b, json!({ "op": "sign_in", "user": "op", "password": "wrong" }));
    let why = stack.call(&mut b, json!({ "op": "sign_in_error" }));
    assert_eq!(why, json!("wrong user or password"));
    // Raw HTTP: a sign-in gives the cookie (HttpOnly, SameSite=Strict).
    let (status, answer) = raw(
        &stack.url,
        "POST",
        "/api/sign-in",
        &[("Content-Type", "application/json")],
        r#"{"user":"op","password":"op-secret"}"#,
    );
    assert_eq!(status, 200, "{answer}");
    let set_cookie = answer
        .lines()
        .find(|l| l.to_ascii_lowercase().starts_with("set-cookie:"))
        .expect("a cookie");
    assert!(
        set_cookie.contains("HttpOnly") && set_cookie.contains("SameSite=Strict"),
        "{set_cookie}"
    );
    let cookie = set_cookie["set-cookie:".len()..]
        .trim()
        .split(';')
        .next()
        .unwrap()
        .to_owned();
    let move_right = r#"{"gimbal":0,"pan":1,"tilt":0,"speed":1.0}"#;
    let json = ("Content-Type", "application/json");
    // A state-changing request without the token, or with a wrong one: refused.
    let (status, answer) = raw(
        &stack.url,
        "POST",
        "/api/move",
        &[json, ("Cookie", &cookie)],
        move_right,
    );
    assert_eq!(status, 403, "{answer}");
    assert!(answer.contains("no X-CSRF-Token header"), "{answer}");
    let (status, answer) = raw(
        &stack.url,
        "POST",
        "/api/move",
        &[json, ("Cookie", &cookie), ("X-CSRF-Token", "forged")],
        move_right,
    );
    assert_eq!(status, 403, "{answer}");
    // Without a cookie: not signed in.
    let (status, _) = raw(&stack.url, "POST", "/api/stop", &[json], r#"{"gimbal":0}"#);
    assert_eq!(status, 401);
    // A form posted from another site is no JSON sign-in.
    let (status, _) = raw(
        &stack.url,
        "POST",
        "/api/sign-in",
        &[("Content-Type", "application/x-www-form-urlencoded")],
        "user=op&password=op-secret",
    );
    assert_eq!(status, 400);
    // With the token from /api/session, the same request moves the gimbal.
    let (_, session) = raw(&stack.url, "GET", "/api/session", &[("Cookie", &cookie)], "");
    let body = session.split("\r\n\r\n").nth(1).expect("a body");
    let csrf: Value = serde_json::from_str(body).expect("JSON");
    let token = csrf["csrf"].as_str().expect("a token");
    let (status, answer) = raw(
        &stack.url,
        "POST",
        "/api/move",
        &[json, ("Cookie", &cookie), ("X-CSRF-Token", token)],
        move_right,
    );
    assert_eq!(status, 200, "{answer}");
    let before: Vec<String> = door_frames(&stack.gcud, MAST);
    assert!(
        before.contains(&"PR".to_owned()),
        "only the request with the token moved it: {before:?}"
    );
    // Not renewed: the lease stops it.
    bus_stop_time(&stack.gcud, MAST, "PS");
}

#[test]
fn a_command_refused_by_gcud_shows_its_reason_on_the_card() {
    if !browser_available() {
        return;
    }
    let stack = Stack::start();
    let mut b = stack.browser("op", "op-secret");
    stack.call(&mut b, json!({ "op": "click", "card": "absent", "button": "Home" }));
    let reason = stack.call(&mut b, json!({ "op": "wait_alert", "card": "absent" }));
    let reason = reason.as_str().unwrap();
    assert!(reason.contains("5.2.9"), "the reason names the gimbal: {reason}");
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
    // gcud refuses gotos of a bounded gimbal until it knows where it is.
    eventually("gcud to know where mast-1 is", || {
        stack.gcud.ctl(&["--to", MAST, "goto", "0", "0", "--wait"]).code == 0
    });
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
    // An operator: the button is disabled, the request refused.
    let mut op = stack.browser("op", "op-secret");
    assert_eq!(
        stack.call(
            &mut op,
            json!({ "op": "disabled", "card": "mast-1", "button": "Release" })
        ),
        json!(true)
    );
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
    stack.call(
        &mut admin,
        json!({ "op": "click", "card": "mast-1", "button": "Release" }),
    );
    let reason = stack.call(&mut admin, json!({ "op": "wait_alert", "card": "mast-1" }));
    let reason = reason.as_str().unwrap().to_owned();
    assert!(reason.contains("refused by gcud"), "gcud's words on the card: {reason}");
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
    let mut web = Door::new("gimbal-web", env!("CARGO_BIN_EXE_gimbal-web"));
    web.start(&format!(
        "gcud = \"{}\"\nlisten = \"127.0.0.1:0\"\nsource_group = {DOOR_GROUP}\n{USERS}\
         [[gimbal]]\nname = \"mast-1\"\naddress = \"5.1.1\"\n",
        gcud.addr
    ));
    let url = format!("http://127.0.0.1:{}/", web.port("page listening"));
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
            .replace("gcud = \"127.0.0.1:4001\"", &format!("gcud = \"{clients}\""))
            .replace("listen = \"127.0.0.1:8080\"", "listen = \"127.0.0.1:0\"")
            .replace(
                "#state_file = \"/var/lib/gimbal-web/presets.toml\"",
                &format!("state_file = \"{}\"", state.display()),
            )
    });
    let mut b = stack.browser("admin", "change-me");
    let names = stack.call(&mut b, json!({ "op": "card_names" }));
    assert_eq!(
        names,
        json!(["mast-1", "mast-2", "roof", "Tours"]),
        "a card per gimbal, then gcud's tours"
    );
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
