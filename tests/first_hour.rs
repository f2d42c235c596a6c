//! A new user's first hour (issue 24): every program exits quietly when
//! whoever reads its stdout or stderr has gone (`gimbalctl --json watch |
//! head -1`): its usual exit code, never Rust's panic (101).
//!
//! "Gone" is a pipe whose read end is closed before the program starts, so
//! its first write fails with EPIPE every time (no race with a reader).

mod support;

use std::net::TcpListener;
use std::os::fd::OwnedFd;
use std::process::{Command, ExitStatus, Stdio};
use std::time::{Duration, Instant};

use serde_json::Value;
use support::HANG_GUARD;

/// The write end of a pipe nobody reads any more.
fn closed_pipe() -> Stdio {
    let (reader, writer): (OwnedFd, OwnedFd) = nix::unistd::pipe().expect("pipe");
    drop(reader);
    Stdio::from(writer)
}

/// Waits (bounded by HANG_GUARD) for `child` to exit.
fn wait(mut child: std::process::Child, what: &str) -> ExitStatus {
    let started = Instant::now();
    loop {
        if let Some(status) = child.try_wait().expect("wait") {
            return status;
        }
        if started.elapsed() > HANG_GUARD {
            let _ = child.kill();
            panic!("{what} did not exit");
        }
        std::thread::sleep(Duration::from_millis(20));
    }
}

/// Runs `bin args` with stdout to a closed pipe; its stderr as text.
fn with_closed_stdout(bin: &str, args: &[&str]) -> (ExitStatus, String) {
    let dir = tempfile::tempdir().unwrap();
    let stderr = dir.path().join("stderr");
    let child = Command::new(bin)
        .args(args)
        .stdin(Stdio::null())
        .stdout(closed_pipe())
        .stderr(std::fs::File::create(&stderr).unwrap())
        .spawn()
        .expect("spawn");
    let status = wait(child, bin);
    (status, std::fs::read_to_string(&stderr).unwrap())
}

/// Runs `bin args` with stderr to a closed pipe (stdout discarded).
fn with_closed_stderr(bin: &str, args: &[&str]) -> ExitStatus {
    let child = Command::new(bin)
        .args(args)
        .stdin(Stdio::null())
        .stdout(Stdio::null())
        .stderr(closed_pipe())
        .spawn()
        .expect("spawn");
    wait(child, bin)
}

fn assert_quiet(what: &str, status: ExitStatus, want: i32, stderr: &str) {
    assert!(!stderr.contains("panicked"), "{what} panicked:\n{stderr}");
    assert_eq!(status.code(), Some(want), "{what}: {status:?}\n{stderr}");
    assert!(
        stderr.trim().is_empty(),
        "{what} complained about its reader leaving:\n{stderr}"
    );
}

#[test]
fn gimbalctl_watch_ends_quietly_when_its_reader_leaves() {
    let gcud = support::cli::DemoGcud::start();
    let (status, stderr) = with_closed_stdout(
        env!("CARGO_BIN_EXE_gimbalctl"),
        &[
            "--json",
            "--tcp",
            &gcud.clients,
            "--to",
            "5.1.1",
            "watch",
            "--rate",
            "20",
        ],
    );
    assert_quiet("gimbalctl --json watch", status, 0, &stderr);
    let (status, stderr) = with_closed_stdout(env!("CARGO_BIN_EXE_gimbalctl"), &["--to", "5.1.1", "encode", "P?"]);
    assert_quiet("gimbalctl encode", status, 0, &stderr);
}

#[test]
fn gimbalctl_failing_with_a_closed_stderr_keeps_its_exit_code() {
    // Nothing listens there: "cannot connect" (exit 1) goes to a closed stderr.
    let port = TcpListener::bind("127.0.0.1:0").unwrap().local_addr().unwrap();
    let status = with_closed_stderr(
        env!("CARGO_BIN_EXE_gimbalctl"),
        &["--tcp", &port.to_string(), "--to", "5.1.1", "id"],
    );
    assert_eq!(status.code(), Some(1), "{status:?}");
}

#[test]
fn gimbalsim_exits_quietly_on_a_closed_stdout_or_stderr() {
    // Its first line (the endpoint) meets a closed stdout.
    let (status, stderr) = with_closed_stdout(env!("CARGO_BIN_EXE_gimbalsim"), &["--tcp", "127.0.0.1:0"]);
    assert_quiet("gimbalsim", status, 0, &stderr);
    // A bad log filter: "gimbalsim: log filter ..." (exit 2) to a closed stderr.
    let status = with_closed_stderr(env!("CARGO_BIN_EXE_gimbalsim"), &["--log", "no[such=filter"]);
    assert_eq!(status.code(), Some(2), "{status:?}");
}

#[test]
fn gcud_check_exits_quietly_on_a_closed_stdout_or_stderr() {
    let demo = concat!(env!("CARGO_MANIFEST_DIR"), "/config/demo.toml");
    let (status, stderr) = with_closed_stdout(env!("CARGO_BIN_EXE_gcud"), &["--check", "--config", demo]);
    assert_quiet("gcud --check", status, 0, &stderr);
    let dir = tempfile::tempdir().unwrap();
    let broken = dir.path().join("gcud.toml");
    std::fs::write(&broken, "[gcu]\ngroup = \"five\"\n").unwrap();
    let status = with_closed_stderr(
        env!("CARGO_BIN_EXE_gcud"),
        &["--check", "--config", broken.to_str().unwrap()],
    );
    assert_eq!(status.code(), Some(2), "{status:?}");
}

#[test]
fn gcud_serves_and_shuts_down_cleanly_with_stdout_and_stderr_closed() {
    let dir = tempfile::tempdir().unwrap();
    let clients = TcpListener::bind("127.0.0.1:0").unwrap().local_addr().unwrap();
    let config = dir.path().join("gcud.toml");
    std::fs::write(
        &config,
        format!(
            "[gcu]\ngroup = 5\n\n[[port]]\nid = 1\nsimulate = [1]\n\n\
             [[link]]\nname = \"clients\"\nrole = \"client\"\nlisten = \"{clients}\"\n"
        ),
    )
    .unwrap();
    let child = Command::new(env!("CARGO_BIN_EXE_gcud"))
        .arg("--config")
        .arg(&config)
        .env("RUST_LOG", "debug")
        .stdin(Stdio::null())
        .stdout(closed_pipe())
        .stderr(closed_pipe())
        .spawn()
        .expect("spawn gcud");
    let pid = nix::unistd::Pid::from_raw(child.id() as i32);
    // Every log line (DEBUG: per connection and per frame) meets EPIPE; it
    // still answers.
    let started = Instant::now();
    let answered = loop {
        let out = support::gimbalctl(&["--tcp", &clients.to_string(), "--to", "5.1.1", "id"]);
        if out.code == 0 {
            break out;
        }
        assert!(started.elapsed() < HANG_GUARD, "gcud never answered: {out:?}");
        std::thread::sleep(Duration::from_millis(50));
    };
    assert!(answered.stdout.contains("SIM"), "{answered:?}");
    nix::sys::signal::kill(pid, nix::sys::signal::Signal::SIGTERM).unwrap();
    let status = wait(child, "gcud");
    assert_eq!(status.code(), Some(0), "gcud after SIGTERM: {status:?}");
}

/// The doors print `--check`'s verdict through `sagebrush_host::outln!`
/// too: a closed stdout is no panic.
#[test]
fn the_doors_check_exits_quietly_on_a_closed_stdout() {
    for (name, bin, config) in [
        (
            "gimbal-onvif",
            env!("CARGO_BIN_EXE_gimbal-onvif"),
            concat!(env!("CARGO_MANIFEST_DIR"), "/config/gimbal-onvif.toml"),
        ),
        (
            "gimbal-mavlink",
            env!("CARGO_BIN_EXE_gimbal-mavlink"),
            concat!(env!("CARGO_MANIFEST_DIR"), "/config/gimbal-mavlink.toml"),
        ),
        (
            "gimbal-web",
            env!("CARGO_BIN_EXE_gimbal-web"),
            concat!(env!("CARGO_MANIFEST_DIR"), "/config/gimbal-web.toml"),
        ),
        (
            "gimbal-mqtt",
            env!("CARGO_BIN_EXE_gimbal-mqtt"),
            concat!(env!("CARGO_MANIFEST_DIR"), "/config/gimbal-mqtt.toml"),
        ),
        (
            "gimbal-pelco",
            env!("CARGO_BIN_EXE_gimbal-pelco"),
            concat!(env!("CARGO_MANIFEST_DIR"), "/config/gimbal-pelco.toml"),
        ),
    ] {
        let (status, stderr) = with_closed_stdout(bin, &["--check", "--config", config]);
        // A shipped door moved off loopback warns of its demo passwords
        // (tests/packaging.rs), which is no complaint.
        let stderr: String = stderr.lines().filter(|l| !l.contains("demo password")).collect();
        assert_quiet(&format!("{name} --check"), status, 0, &stderr);
    }
}

#[test]
fn an_address_error_names_the_part_and_its_range() {
    for (address, part) in [
        ("5.1.300", "device \"300\""),
        ("5.x.1", "port \"x\""),
        ("256.1.1", "group \"256\""),
    ] {
        let out = support::gimbalctl(&["--to", address, "encode", "P?"]);
        assert_eq!(out.code, 2, "{address}: {out:?}");
        assert!(
            out.stderr.contains(&format!("{part} is not a number 0..=255")),
            "{address}: the error does not name the {part}: {out:?}"
        );
    }
}

#[test]
fn for_takes_the_common_duration_forms() {
    let gcud = support::cli::DemoGcud::start();
    for duration in ["1sec", "300ms", "1s"] {
        let out = gcud.ctl(&["--to", "5.1.1", "slew", "right", "--for", duration]);
        assert_eq!(out.code, 0, "--for {duration}: {out:?}");
    }
    let out = gcud.ctl(&["--to", "5.1.1", "slew", "right", "--for", "2 fortnights"]);
    assert_eq!(out.code, 2, "{out:?}");
    assert!(out.stderr.contains("2s, 500ms, 2sec, 1m"), "{out:?}");
}

/// `gcud --check` on `text`: (exit code, stdout, stderr).
fn check(text: &str) -> (Option<i32>, String, String) {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("gcud.toml");
    std::fs::write(&path, text).unwrap();
    let out = Command::new(env!("CARGO_BIN_EXE_gcud"))
        .arg("--check")
        .arg("--config")
        .arg(&path)
        .output()
        .expect("gcud --check runs");
    let stderr = String::from_utf8_lossy(&out.stderr).replace(&path.display().to_string(), "gcud.toml");
    (
        out.status.code(),
        String::from_utf8_lossy(&out.stdout).into_owned(),
        stderr,
    )
}

#[test]
fn check_refuses_what_routes_nothing_warns_of_absent_serial_paths_and_speaks_in_words() {
    let (code, _, stderr) = check("[gcu]\ngroup = 5\n\n[[port]]\nid = 1\nsimulate = [1]\n");
    assert_eq!(code, Some(2), "{stderr}");
    assert!(stderr.contains("gcud.toml: routes nothing: no [[link]]"), "{stderr}");

    let link = "[[link]]\nname = \"c\"\nrole = \"client\"\nlisten = \"127.0.0.1:0\"\n";
    let (code, stdout, stderr) = check(&format!(
        "[gcu]\ngroup = 5\n{link}\n[[port]]\nid = 1\npath = \"/dev/no-such-gimbal-bus\"\n"
    ));
    assert_eq!(
        code,
        Some(0),
        "an absent serial device is no error (it may be plugged in later): {stderr}"
    );
    assert!(stdout.contains("valid"), "{stdout}");
    assert!(
        stderr.contains("gcud: warning: gcud.toml:10:8: port[0].path: /dev/no-such-gimbal-bus does not exist now"),
        "{stderr}"
    );

    let (code, _, stderr) = check("[gcu]\ngroup = \"five\"\n");
    assert_eq!(code, Some(2), "{stderr}");
    assert!(
        stderr.contains("gcud.toml:2:9: gcu.group: expected an integer, found the string \"five\""),
        "{stderr}"
    );
}

#[test]
fn the_demo_gimbals_have_distinct_serial_numbers() {
    let gcud = support::cli::DemoGcud::start();
    let serials: Vec<String> = ["5.1.1", "5.1.2", "5.2.1"]
        .iter()
        .map(|to| {
            let v = gcud.json(&["--to", to, "id"]);
            v["result"]["serial"]
                .as_str()
                .unwrap_or_else(|| panic!("{to}: {v}"))
                .to_owned()
        })
        .collect();
    let mut distinct = serials.clone();
    distinct.sort();
    distinct.dedup();
    assert_eq!(distinct.len(), serials.len(), "serial numbers repeat: {serials:?}");
}

/// `gimbalctl gcud-status` needs no --http for the shipped configuration:
/// its default is config/gcud.toml's (and the demo's) [metrics] listen.
#[test]
fn gcud_status_defaults_to_the_shipped_metrics_address() {
    let out = support::gimbalctl(&["gcud-status", "--help"]);
    // The --http option's own block of the help, up to the next option.
    let http = out
        .stdout
        .split("      --http <HOST:PORT>")
        .nth(1)
        .and_then(|rest| rest.split("\n  -").next())
        .unwrap_or_else(|| panic!("no --http in the help: {out:?}"));
    let default = http
        .split("[default: ")
        .nth(1)
        .and_then(|rest| rest.split(']').next())
        .unwrap_or_else(|| panic!("--http has no default: {out:?}"))
        .to_owned();
    for config in ["config/gcud.toml", "config/demo.toml"] {
        let text = std::fs::read_to_string(format!("{}/{config}", env!("CARGO_MANIFEST_DIR"))).unwrap();
        let table: toml::Table = text.parse().unwrap();
        assert_eq!(
            table["metrics"]["listen"].as_str(),
            Some(default.as_str()),
            "{config}'s [metrics] listen is not gcud-status's default"
        );
    }
    assert!(out.stdout.contains("GIMBALCTL_HTTP"), "{out:?}");
}

/// A scan says on stderr what it will ask before its first probe, and how
/// each port went as it goes; stdout keeps only the result.
#[test]
fn scan_says_what_it_probes_on_stderr() {
    let gcud = support::cli::DemoGcud::start();
    let out = gcud.ctl(&["scan", "--gcus", "5", "--ports", "1-2", "--devices", "1-3,7"]);
    assert_eq!(out.code, 0, "{out:?}");
    assert!(
        out.stderr.contains("D? to the GCU of groups 5") && out.stderr.contains("devices 1-3,7 on ports 1-2"),
        "{out:?}"
    );
    assert!(out.stderr.contains("port 5.1: 2 found, 2 silent"), "{out:?}");
    assert!(!out.stdout.contains("gimbalctl: scan:"), "{out:?}");
}

/// `gimbalctl scan` with its defaults finishes on a demo-like gcud (the
/// devices it asks by default are few enough; `--devices 1-254` on every
/// port of the demo took minutes) and lists every simulated gimbal. The
/// bound is the support's HANG_GUARD, generous on purpose (a shared machine).
#[test]
fn a_default_scan_finishes_and_lists_the_simulated_gimbals() {
    let gcud = support::cli::DemoGcud::start();
    let v = gcud.json(&["scan"]);
    let found: Vec<&str> = v["gcus"]
        .as_array()
        .unwrap_or_else(|| panic!("{v}"))
        .iter()
        .flat_map(|g| g["ports"].as_array().into_iter().flatten())
        .flat_map(|p| p["devices"].as_array().into_iter().flatten())
        .filter_map(|d| d["address"].as_str())
        .collect();
    assert_eq!(found, ["5.1.1", "5.1.2", "5.2.1"], "{v}");
    let closed: Vec<&Value> = v["gcus"][0]["ports"]
        .as_array()
        .unwrap()
        .iter()
        .filter(|p| p["state"] == "port_closed")
        .collect();
    assert_eq!(closed.len(), 1, "port 3 (no such tty) is listed closed: {v}");
}

/// Ctrl-C (SIGINT) in a long scan prints what it found so far and exits
/// 130; `--json` puts the findings in the failure object.
#[test]
fn an_interrupted_scan_prints_what_it_found_so_far() {
    let gcud = support::cli::DemoGcud::start();
    let dir = tempfile::tempdir().unwrap();
    let (out_path, err_path) = (dir.path().join("stdout"), dir.path().join("stderr"));
    // Every ID on ports 1-2: minutes, so the scan is still going when interrupted.
    let child = Command::new(env!("CARGO_BIN_EXE_gimbalctl"))
        .args([
            "--json",
            "--tcp",
            &gcud.clients,
            "scan",
            "--gcus",
            "5",
            "--ports",
            "1-2",
            "--devices",
            "1-254",
        ])
        .stdin(Stdio::null())
        .stdout(std::fs::File::create(&out_path).unwrap())
        .stderr(std::fs::File::create(&err_path).unwrap())
        .spawn()
        .expect("spawn gimbalctl");
    let started = Instant::now();
    while !std::fs::read_to_string(&err_path).unwrap().contains("found 5.1.2") {
        assert!(
            started.elapsed() < HANG_GUARD,
            "the scan did not find 5.1.2: {}",
            std::fs::read_to_string(&err_path).unwrap()
        );
        std::thread::sleep(Duration::from_millis(20));
    }
    nix::sys::signal::kill(
        nix::unistd::Pid::from_raw(child.id() as i32),
        nix::sys::signal::Signal::SIGINT,
    )
    .unwrap();
    let status = wait(child, "gimbalctl scan");
    let (stdout, stderr) = (
        std::fs::read_to_string(&out_path).unwrap(),
        std::fs::read_to_string(&err_path).unwrap(),
    );
    assert_eq!(status.code(), Some(130), "{status:?}\n{stdout}\n{stderr}");
    assert!(stderr.contains("interrupted by SIGINT"), "{stderr}");
    let v: Value = serde_json::from_str(stdout.trim()).unwrap_or_else(|e| panic!("{e}: {stdout}"));
    assert_eq!(
        (v["ok"].as_bool(), v["outcome"].as_str()),
        (Some(false), Some("interrupted")),
        "{v}"
    );
    let port = &v["gcus"][0]["ports"][0];
    let found: Vec<&str> = port["devices"]
        .as_array()
        .unwrap_or_else(|| panic!("{v}"))
        .iter()
        .filter_map(|d| d["address"].as_str())
        .collect();
    assert_eq!(found, ["5.1.1", "5.1.2"], "{v}");
    assert!(port["asked"].as_u64().is_some_and(|n| (2..254).contains(&n)), "{v}");
}

/// INFO is the daemon's life (start, ports and links up and down, reload,
/// shutdown): gimbalctl calls (a connection each, frames on the simulated
/// buses, a dead-man stop, a silent device) add no INFO line. gcud runs the
/// demo configuration as shipped (its `[log] level = "info"`, no RUST_LOG),
/// on ports of its own.
#[test]
fn gimbalctl_calls_add_no_info_lines_to_the_daemons_log() {
    let demo = std::fs::read_to_string(concat!(env!("CARGO_MANIFEST_DIR"), "/config/demo.toml")).unwrap();
    let config = demo
        .replace("127.0.0.1:4001", "127.0.0.1:0")
        .replace("127.0.0.1:4002", "127.0.0.1:0")
        .replace("127.0.0.1:4003", "127.0.0.1:0")
        .replace("127.0.0.1:4004", "127.0.0.1:0")
        .replace("127.0.0.1:4005", "127.0.0.1:0")
        .replace("127.0.0.1:4006", "127.0.0.1:0")
        .replace("127.0.0.1:4008", "127.0.0.1:0")
        .replace("127.0.0.1:9187", "127.0.0.1:0");
    let dir = tempfile::tempdir().unwrap();
    /// Stops gcud however the test ends.
    struct Stopped(std::process::Child);
    impl Drop for Stopped {
        fn drop(&mut self) {
            support::terminate(&mut self.0);
        }
    }
    let mut gcud = Stopped(support::spawn_gcud_logging(dir.path(), &config, None));
    let log_path = dir.path().join("gcud.log");
    let clients = support::addr_field(&support::wait_for_log_line(&log_path, "listening link=clients"));
    let ctl = |args: &[&str]| {
        let mut full = vec!["--tcp", clients.as_str()];
        full.extend_from_slice(args);
        support::gimbalctl(&full)
    };
    // Both ports are open once their gimbals answer.
    for to in ["5.1.1", "5.2.1"] {
        support::eventually("the demo's gimbals to answer", || ctl(&["--to", to, "id"]).code == 0);
    }
    // The roof gimbal has a keep-out zone: its goto waits while gcud reads
    // where the gimbal is and that it stands still, then runs.
    let out = ctl(&["--to", "5.2.1", "goto", "0", "0", "--wait"]);
    assert_eq!(out.code, 0, "{out:?}");
    let info = |log: &str| -> Vec<String> {
        log.lines()
            .filter(|l| l.contains(" INFO "))
            .map(str::to_owned)
            .collect()
    };
    let warnings = |log: &str| -> Vec<String> {
        log.lines()
            .filter(|l| l.contains(" WARN "))
            .map(str::to_owned)
            .collect()
    };
    let before = info(&std::fs::read_to_string(&log_path).unwrap());
    let warned_before = warnings(&std::fs::read_to_string(&log_path).unwrap());
    assert_eq!(ctl(&["--to", "5.1.1", "position"]).code, 0);
    assert_eq!(ctl(&["--to", "5.2.1", "goto", "5", "5", "--wait"]).code, 0);
    // A motion left running: gcud's dead-man stops it when gimbalctl leaves.
    assert_eq!(ctl(&["--to", "5.1.2", "slew", "right"]).code, 0);
    assert_eq!(ctl(&["--to", "5.1.9", "id"]).code, 8, "a silent device");
    assert_eq!(
        ctl(&["scan", "--gcus", "5", "--ports", "1-3", "--devices", "1-3"]).code,
        0
    );
    support::eventually("the dead-man stop to be logged", || {
        std::fs::read_to_string(&log_path).unwrap().contains("dead-man")
    });
    // Who moved a gimbal is the daemon's to answer (ARCHITECTURE
    // "Principals"): one audit line per command that moves one (the goto,
    // the slew), and no other INFO line.
    let after = info(&std::fs::read_to_string(&log_path).unwrap());
    let (audit, other): (Vec<String>, Vec<String>) = after
        .into_iter()
        .filter(|l| !before.contains(l))
        .partition(|l| l.contains(" principal=") && l.contains(" outcome="));
    assert!(other.is_empty(), "gimbalctl calls added INFO lines: {other:#?}");
    assert!(
        audit
            .iter()
            .any(|l| l.contains("link clients: go to pan ") && l.contains("for 5.2.1: accepted"))
            && audit.iter().any(|l| l.contains("for 5.1.2: accepted")),
        "an audit line per motion: {audit:#?}"
    );
    // A silent address and a scan's probes are their clients' to report,
    // no warning; the dead-man stop is one.
    let warned: Vec<String> = warnings(&std::fs::read_to_string(&log_path).unwrap())
        .into_iter()
        .filter(|l| !warned_before.contains(l))
        .collect();
    assert!(
        !warned.is_empty() && warned.iter().all(|l| l.contains("dead-man")),
        "WARN lines added: {warned:#?}"
    );
    // Reload and shutdown are the daemon's life: INFO.
    nix::sys::signal::kill(
        nix::unistd::Pid::from_raw(gcud.0.id() as i32),
        nix::sys::signal::Signal::SIGHUP,
    )
    .unwrap();
    support::wait_for_log_line(&log_path, "configuration unchanged");
    support::terminate(&mut gcud.0);
    let log = std::fs::read_to_string(&log_path).unwrap();
    let life = [
        "descriptor limit",
        "listening link=clients",
        "listening link=operators",
        "listening link=gimbal-onvif",
        "listening link=gimbal-mavlink",
        "listening link=gimbal-web",
        "listening link=gimbal-mqtt",
        "listening link=gimbal-pelco",
        "metrics at /metrics",
        "gcud ready",
        "port open port=",
        "port 1 opened",
        "port 2 opened",
        "line rate switched",
        "SIGHUP: reloading",
        "configuration unchanged",
        "shutting down",
        "in-flight transactions finished",
        "port closed: gcud stopping",
    ];
    for line in info(&log) {
        let audit = line.contains(" principal=") && line.contains(" outcome=");
        assert!(
            audit || life.iter().any(|l| line.contains(l)),
            "not a life-cycle line at INFO: {line}\n{log}"
        );
    }
    assert!(log.contains("shutting down") && log.contains("SIGHUP"), "{log}");
}

/// A failure names the command once and in words, its arguments in their
/// units (issue 53): `read current position`, `pan speed 8 of 15`, never
/// the payload or its template (`SP8 (SPn)`).
#[test]
fn an_error_names_the_command_once() {
    let gcud = support::cli::DemoGcud::start();
    let out = gcud.ctl(&["--to", "5.1.9", "position"]);
    assert_eq!(out.code, 8, "{out:?}");
    assert!(
        out.stderr.contains("not delivered: read current position for 5.1.9"),
        "{out:?}"
    );
    assert!(!out.stderr.contains("P?"), "{out:?}");
    let out = gcud.ctl(&["--to", "5.1.9", "speed", "pan", "8"]);
    assert_eq!(out.code, 8, "{out:?}");
    assert!(
        out.stderr.contains("not delivered: pan speed 8 of 15 for 5.1.9"),
        "{out:?}"
    );
    assert!(!out.stderr.contains("SP8") && !out.stderr.contains("SPn"), "{out:?}");
}

/// A scan that nothing answers exits 4 (documented in `gimbalctl --help`),
/// its empty result printed: here no GCU of groups 1-3 (gcud is group 5).
#[test]
fn a_scan_that_nothing_answers_exits_4() {
    let gcud = support::cli::DemoGcud::start();
    let out = gcud.ctl(&["--json", "scan", "--gcus", "1-3"]);
    assert_eq!(out.code, 4, "{out:?}");
    let v = out.json();
    assert_eq!(
        (v["ok"].as_bool(), v["outcome"].as_str()),
        (Some(false), Some("no_ack")),
        "{v}"
    );
    assert_eq!(v["gcus"], serde_json::json!([]), "{v}");
    assert!(out.stderr.contains("nothing answered D?"), "{out:?}");
    let text = gcud.ctl(&["scan", "--gcus", "1-3"]);
    assert_eq!(text.code, 4, "{text:?}");
    assert!(
        text.stdout.contains("no GCU answered D? at any of 3 groups"),
        "{text:?}"
    );
}

/// A port where nothing listens: the refusal says that gcud may not be
/// running, not only "connection refused".
#[test]
fn a_refused_connection_asks_whether_gcud_runs() {
    // A port bound but not listening refuses connections, and no other
    // program can take it meanwhile (a port freed for the test was at
    // times another test's listener by then: "reset by peer").
    let bound = socket2::Socket::new(socket2::Domain::IPV4, socket2::Type::STREAM, None).expect("socket");
    bound
        .bind(&std::net::SocketAddr::from(([127, 0, 0, 1], 0)).into())
        .expect("bind");
    let addr = bound.local_addr().expect("addr").as_socket().expect("IPv4").to_string();
    let out = support::gimbalctl(&["--tcp", &addr, "--to", "5.1.1", "position"]);
    assert_ne!(out.code, 0, "{out:?}");
    assert!(out.stderr.contains("Connection refused"), "{out:?}");
    assert!(out.stderr.contains("Is gcud running"), "no hint: {out:?}");
}

/// gimbalctl pointed at an HTTP server (gcud's metrics listener, say) says
/// that bytes came that were no frames, not only that the line closed.
#[test]
fn an_http_server_is_not_taken_for_a_closed_line() {
    let http = TcpListener::bind("127.0.0.1:0").expect("bind");
    let addr = http.local_addr().expect("addr").to_string();
    let server = std::thread::spawn(move || {
        use std::io::{Read, Write};
        let (mut conn, _) = http.accept().expect("accept");
        conn.set_read_timeout(Some(Duration::from_secs(5))).expect("timeout");
        let mut request = [0u8; 64];
        let _ = conn.read(&mut request);
        let _ = conn.write_all(b"HTTP/1.1 400 Bad Request\r\ncontent-length: 0\r\nconnection: close\r\n\r\n");
    });
    let out = support::gimbalctl(&["--tcp", &addr, "--to", "5.1.1", "position"]);
    server.join().expect("server");
    assert_ne!(out.code, 0, "{out:?}");
    assert!(out.stderr.contains("no Sagebrush frames"), "{out:?}");
    assert!(out.stderr.contains("speaks HTTP"), "{out:?}");
}

/// `gcud-status` against a listener that never answers says so in words,
/// not as ureq's "timeout: global".
#[test]
fn gcud_status_says_when_nothing_answers() {
    let silent = TcpListener::bind("127.0.0.1:0").expect("bind");
    let addr = silent.local_addr().expect("addr").to_string();
    let out = support::gimbalctl(&["gcud-status", "--http", &addr]);
    drop(silent);
    assert_ne!(out.code, 0, "{out:?}");
    assert!(out.stderr.contains("no answer within 5 s"), "{out:?}");
    assert!(!out.stderr.contains("timeout: global"), "{out:?}");
    assert!(out.stderr.contains("is gcud running"), "{out:?}");
}

/// `--check` warns while a shipped demo password guards a listener on the
/// network, and only then (issue 37): gimbal-web's shipped page listens on
/// loopback; moved to 0.0.0.0 with the same users, it warns naming each.
#[test]
fn check_warns_of_a_demo_password_on_the_network() {
    let shipped = std::fs::read_to_string(concat!(env!("CARGO_MANIFEST_DIR"), "/config/gimbal-web.toml"))
        .expect("config/gimbal-web.toml");
    let (code, _, stderr) = door_check(env!("CARGO_BIN_EXE_gimbal-web"), &shipped);
    assert_eq!(code, Some(0), "{stderr}");
    assert!(!stderr.contains("demo password"), "loopback only: {stderr}");
    let open = shipped.replace("listen = \"127.0.0.1:8080\"", "listen = \"0.0.0.0:8080\"");
    assert_ne!(open, shipped, "config/gimbal-web.toml's listen line changed");
    let (code, _, stderr) = door_check(env!("CARGO_BIN_EXE_gimbal-web"), &open);
    assert_eq!(code, Some(0), "a warning, not an error: {stderr}");
    for user in ["\"admin\"", "\"viewer\""] {
        assert!(
            stderr
                .lines()
                .any(|l| l.contains("warning") && l.contains(user) && l.contains("demo password")),
            "no warning for {user}: {stderr}"
        );
    }
    let changed = open.replace("change-me", "a-long-secret-of-our-own");
    let (code, _, stderr) = door_check(env!("CARGO_BIN_EXE_gimbal-web"), &changed);
    assert_eq!(code, Some(0), "{stderr}");
    assert!(!stderr.contains("demo password"), "passwords changed: {stderr}");
}

/// `bin --check` of configuration `text`: exit code, stdout, stderr.
fn door_check(bin: &str, text: &str) -> (Option<i32>, String, String) {
    let dir = tempfile::tempdir().expect("temp dir");
    let path = dir.path().join("door.toml");
    std::fs::write(&path, text).expect("write");
    let out = Command::new(bin)
        .args(["--check", "--config"])
        .arg(&path)
        .output()
        .expect("door --check");
    (
        out.status.code(),
        String::from_utf8_lossy(&out.stdout).into_owned(),
        String::from_utf8_lossy(&out.stderr).into_owned(),
    )
}
