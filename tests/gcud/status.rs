//! What gcud shows of itself: status, metrics and health of the devices it
//! has seen, journal priorities, memory and metrics flat under churn.

use super::*;

/// Thousands of connections come and go: memory and the metrics stay flat
/// (a connection's counters fold into its configured link).
#[test]
fn connection_churn_leaves_memory_and_metrics_flat() {
    let gcud = Gcud::start(&format!("[gcu]\ngroup = 5\n{CLIENTS}{METRICS}"));
    let addr = gcud.clients();
    let aw = FrameBuf::new(Address::new(5, 0, 0), 0, b"AW").expect("frame");
    let churn = |n: usize| {
        for _ in 0..n {
            let mut s = TcpStream::connect(&addr).expect("connect");
            s.set_read_timeout(Some(HANG_GUARD)).expect("timeout");
            s.write_all(aw.as_bytes()).expect("send");
            let mut ack = [0u8; 1];
            assert_eq!(s.read(&mut ack).expect("the ACK"), 1);
        }
        eventually("every churned connection to be closed", || {
            gcud.metric("gcud_connections_open") == 0
        });
    };
    churn(500); // warm up allocator pools and the metrics' label set
    let (rss_before, metrics_before) = (gcud.rss_kib(), gcud.metrics().len());
    churn(5000);
    let (rss_after, metrics_after) = (gcud.rss_kib(), gcud.metrics().len());
    eprintln!(
        "5000 connections: RSS {rss_before} -> {rss_after} KiB, /metrics {metrics_before} -> {metrics_after} bytes"
    );
    assert_eq!(gcud.metric("gcud_connections_accepted_total"), 5500);
    assert!(
        gcud.metric("gcud_link_frames_in_total{link=\"clients\",role=\"client\"}") >= 5000,
        "the connections' counters live on in their link's"
    );
    assert!(
        metrics_after <= metrics_before + 200,
        "metrics grew from {metrics_before} to {metrics_after} bytes"
    );
    assert!(
        rss_after <= rss_before + 2048,
        "RSS grew from {rss_before} to {rss_after} KiB over 5000 connections"
    );
}

/// gcud keeps what it learns of each device (the router core's registry)
/// and shows it: `/status` (JSON) and per-device gauges with Unix times;
/// `/healthz` answers while the router task does.
#[test]
fn status_metrics_and_health_show_the_devices_gcud_has_seen() {
    let gcud = Gcud::start(&format!(
        "[gcu]\ngroup = 5\nname = \"field gcu\"\n[[port]]\nid = 1\nsimulate = [1, 2]\n{CLIENTS}{METRICS}"
    ));
    let health = gcud.http_get("/healthz");
    assert!(
        health.starts_with("HTTP/1.1 200") && health.ends_with("ok\n"),
        "{health}"
    );
    let before = std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .expect("clock")
        .as_secs_f64();
    let out = gcud.ctl(&["--to", "5.1.1", "goto", "12.5", "-3", "--wait"]);
    assert_eq!(out.code, 0, "{out:?}");
    let (pan, tilt) = gcud.position("5.1.1");
    assert_eq!((pan, tilt), (12.5, -3.0));
    let out = gcud.ctl(&["--to", "5.1.9", "id"]);
    assert_eq!(out.code, 8, "nobody at 5.1.9: {out:?}");

    let status = gcud.status();
    assert_eq!(status["gcud"]["group"], 5);
    assert_eq!(status["gcud"]["name"], "field gcu");
    assert_eq!(status["gcud"]["shutting_down"], false);
    let port = &status["ports"][0];
    assert_eq!(
        (port["port"].as_u64(), port["open"].as_bool()),
        (Some(1), Some(true)),
        "{port}"
    );
    let devices = port["devices"].as_array().expect("devices");
    let device = |n: u64| {
        devices
            .iter()
            .find(|d| d["device"].as_u64() == Some(n))
            .unwrap_or_else(|| panic!("device {n} in {port}"))
    };
    let one = device(1);
    assert_eq!(one["address"], "5.1.1");
    assert_eq!(one["online"], true);
    assert_eq!(one["position"]["pan_deg"].as_f64(), Some(12.5), "{one}");
    assert_eq!(one["position"]["tilt_deg"].as_f64(), Some(-3.0), "{one}");
    let seen = one["last_seen_unix"].as_f64().expect("last seen");
    assert!(
        seen >= before - 1.0 && seen < before + 600.0,
        "a Unix time: {seen} vs {before}"
    );
    // Issue 24: an address that never answered (nobody at 5.1.9) leaves
    // nothing behind; a device that answered once and then went silent
    // stays, offline (crates/gcu/tests/rules/, the device registry).
    // Issue 53: a configured gimbal (5.1.2, simulated) is listed from the
    // start, not yet heard from: offline, never seen.
    assert!(
        devices.iter().all(|d| d["device"] != 9),
        "only devices that answered or are configured: {port}"
    );
    let two = device(2);
    assert_eq!(
        (
            two["online"].as_bool(),
            two["last_seen_unix"].is_null(),
            two["commands"].as_u64()
        ),
        (Some(false), true, Some(0)),
        "5.1.2, configured, not yet heard: {two}"
    );
    assert_eq!(status["links"][0]["link"], "clients");

    let one = "{port=\"1\",device=\"1\"}";
    assert_eq!(gcud.real_metric(&format!("gcud_device_online{one}")), Some(1.0));
    assert_eq!(
        gcud.real_metric(&format!("gcud_device_position_pan_degrees{one}")),
        Some(12.5)
    );
    assert_eq!(
        gcud.real_metric(&format!("gcud_device_position_tilt_degrees{one}")),
        Some(-3.0)
    );
    assert!(
        !gcud.metrics().contains("device=\"9\""),
        "no series for an address that never answered"
    );
    let seen = gcud.real_metric(&format!("gcud_device_last_seen_timestamp_seconds{one}"));
    assert!(seen.is_some_and(|t| t >= before - 1.0), "{seen:?}");
    assert!(
        gcud.metrics().contains("gcud_build_info{version=\""),
        "{}",
        gcud.metrics()
    );

    // The operator's view of the same: gimbalctl gcud-status.
    let http = gcud.address("metrics at /metrics");
    let out = support::gimbalctl(&["gcud-status", "--http", &http]);
    assert_eq!(out.code, 0, "{out:?}");
    let line = |address: &str| {
        out.stdout
            .lines()
            .find(|l| l.trim_start().starts_with(address))
            .unwrap_or_else(|| panic!("{address} in {}", out.stdout))
    };
    assert!(
        line("5.1.1").contains("yes") && line("5.1.1").contains("pan 12.50° tilt -3.00°"),
        "{out:?}"
    );
    assert!(
        !out.stdout.lines().any(|l| l.trim_start().starts_with("5.1.9")),
        "{out:?}"
    );
    assert!(
        out.stdout.starts_with("gcud ") && out.stdout.contains("\"field gcu\" (group 5)"),
        "{out:?}"
    );
    let out = support::gimbalctl(&["--json", "gcud-status", "--http", &http]);
    assert_eq!(out.code, 0, "{out:?}");
    let json = out.json();
    assert_eq!(json["ok"], true);
    assert_eq!(json["status"]["ports"][0]["devices"][0]["address"], "5.1.1", "{json}");
    drop(gcud);
    let out = support::gimbalctl(&["--json", "gcud-status", "--http", &http]);
    assert_eq!(out.code, 1, "gcud is gone: {out:?}");
    assert_eq!(out.json()["outcome"], "io", "{out:?}");
    assert!(
        out.stderr.contains(&format!("http://{http}/status")),
        "names what it asked: {out:?}"
    );
}

/// Under systemd (`JOURNAL_STREAM` set) each line starts with its syslog
/// priority, so journald records the level: `<6>` for info.
#[test]
fn journal_lines_carry_their_priority() {
    let dir = tempfile::tempdir().expect("temp dir");
    let path = dir.path().join("gcud.toml");
    std::fs::write(&path, format!("[gcu]\ngroup = 5\n{CLIENTS}")).expect("write config");
    let log = std::fs::File::create(dir.path().join("gcud.log")).expect("log file");
    let child = Command::new(env!("CARGO_BIN_EXE_gcud"))
        .arg("--config")
        .arg(&path)
        .env("RUST_LOG", "info")
        .env("JOURNAL_STREAM", "8:1234")
        .stdout(Stdio::null())
        .stderr(Stdio::from(log))
        .spawn()
        .expect("spawn gcud");
    let gcud = Gcud { child, dir };
    let ready = gcud.wait_for_log("gcud ready");
    assert!(ready.starts_with("<6>"), "{ready:?}");
    let (status, log) = gcud.terminate();
    assert!(status.is_some_and(|s| s.success()), "exit status {status:?}\n{log}");
    for line in log.lines() {
        let prefixed = ["<3>", "<4>", "<6>", "<7>"].iter().any(|p| line.starts_with(p));
        assert!(prefixed, "a line without its priority: {line:?}\n{log}");
    }
}
