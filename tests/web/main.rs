//! gimbal-web end to end (issue 34) in a real browser: Debian's chromium,
//! headless, driven by Selenium (`tests/web/browser.py`, installed by
//! `./test.sh`; a missing browser fails the test unless
//! `SAGEBRUSH_SKIP_MISSING_TOOLS=1`; the driver is `support::browser`), through real gcud
//! and its simulated buses. What a gimbal did is read on the bus side (the
//! simulated gimbals' own `rx frame` record in gcud's log, with its
//! timestamps, and `gimbalctl position`), never in gimbal-web's account.
//! gcud's motion lease is off here (`start_gcud` sets none), so every stop
//! after a release, a closed page or a killed browser is gimbal-web's own.

#[path = "../support/mod.rs"]
mod support;

mod access;
mod attack;
mod governance;
mod https;
mod metrics;
mod motion;
mod page;
mod principals;
mod tours;
mod words;

use std::io::{Read, Write};
use std::path::Path;
use std::time::{Duration, Instant};

use serde_json::{Value, json};

use support::browser::{Browser, browser_available};
use support::door::{DOOR_GROUP, Door, start_gcud, wait_moving};
use support::gcud::Gcud;
use support::{HANG_GUARD, eventually};

const MAST: &str = "5.1.1";

/// The longest from a release (or a closed page, a killed browser) to the
/// stop on the bus: the issue's bound.
const STOP_WITHIN_S: f64 = 0.5;

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
    let started = Instant::now();
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

/// Whether process `pid` is gone (or a zombie waiting to be reaped).
fn gone(pid: u64) -> bool {
    match std::fs::read_to_string(format!("/proc/{pid}/stat")) {
        Ok(stat) => stat.rsplit(") ").next().is_some_and(|rest| rest.starts_with('Z')),
        Err(_) => true,
    }
}

/// A browser the test is done with leaves nothing behind: chromedriver and
/// every chromium process of it end with it (killed at once, the script
/// left them all running: 14 chromedrivers and 181 chromium processes
/// after one run of these tests, loading the machine for good).
#[test]
fn a_dropped_browser_leaves_no_process_behind() {
    if !browser_available() {
        return;
    }
    let mut b = Browser::start();
    b.call(json!({ "op": "open", "url": "about:blank" }), String::new);
    let pids: Vec<u64> =
        serde_json::from_value(b.call(json!({ "op": "process_ids" }), String::new)).expect("process ids");
    assert!(pids.len() > 1, "chromedriver and its browser: {pids:?}");
    drop(b);
    let until = Instant::now() + Duration::from_secs(10);
    while !pids.iter().all(|&p| gone(p)) && Instant::now() < until {
        std::thread::sleep(Duration::from_millis(100));
    }
    let left: Vec<u64> = pids.into_iter().filter(|&p| !gone(p)).collect();
    assert!(left.is_empty(), "still running after the browser was dropped: {left:?}");
}
