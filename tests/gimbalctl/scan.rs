//! `scan`: GCUs, ports and devices found through gcud; on a bus only
//! queries, a slew left alone; garbage, time-outs and duplicate IDs
//! reported and the sweep goes on.

use super::*;

#[test]
fn scan_finds_gcus_ports_and_devices_through_gcud() {
    let gcud = DemoGcud::start();
    let v = gcud.json(&["scan", "--gcus", "1-9", "--ports", "1-4", "--devices", "1-3"]);
    let gcus = v["gcus"].as_array().expect("gcus");
    assert_eq!(gcus.len(), 1, "{v}");
    let g = &gcus[0];
    assert_eq!(
        (g["group"].as_u64(), g["name"].as_str(), g["serial"].as_str()),
        (Some(5), Some("demo GCU"), Some("DEMO-0005"))
    );
    let ports = g["ports"].as_array().expect("ports");
    let ids = |p: &Value| -> Vec<u64> {
        p["devices"]
            .as_array()
            .unwrap()
            .iter()
            .map(|d| d["id"].as_u64().unwrap())
            .collect()
    };
    assert_eq!(
        ports.iter().map(|p| p["port"].as_u64().unwrap()).collect::<Vec<_>>(),
        [1, 2, 3],
        "{v}"
    );
    assert_eq!(
        (ids(&ports[0]), ports[0]["silent"].as_u64()),
        (vec![1, 2], Some(1)),
        "{v}"
    );
    assert_eq!(ids(&ports[1]), [1], "{v}");
    assert_eq!(ports[2]["state"], "port_closed", "{v}");
    let d = &ports[0]["devices"][0];
    assert_eq!(
        (d["address"].as_str(), d["name"].as_str()),
        (Some("5.1.1"), Some("sim gimbal 1.1")),
        "{d}"
    );
    assert_eq!(d["awake"]["hardware_ok"], true);
    assert!(d["status"]["azimuth"]["not_initialized"].is_boolean(), "{d}");
    assert_eq!(d["collision"], false);
    assert_eq!(v["problems"], serde_json::json!([]), "{v}");
    let text = gcud.ctl(&["scan", "--gcus", "5", "--ports", "1-3", "--devices", "1-2"]);
    assert_eq!(text.code, 0, "{text:?}");
    assert!(
        text.stdout.starts_with("GCU 5 (5.0.0)") && text.stdout.contains("\n  port 1\n    device 1 (5.1.1)"),
        "{text:?}"
    );
    assert!(text.stdout.contains("port 3: the port is not open"), "{text:?}");
}

#[test]
fn scan_on_a_bus_sends_only_queries_and_leaves_a_slew_alone() {
    let sim = Sim::pty(&["--device", "1,2,5"]);
    sim.json1(&["rate", "pan", "5"]);
    sim.json1(&["slew", "right"]);
    let v = sim
        .ctl(&["--json", "scan", "--devices", "1-6", "--bus", "1.1", "--timeout", "150"])
        .json();
    let devices: Vec<u64> = v["bus"]["devices"]
        .as_array()
        .unwrap()
        .iter()
        .map(|d| d["id"].as_u64().unwrap())
        .collect();
    assert_eq!(devices, [1, 2, 5], "{v}");
    assert_eq!(v["bus"]["silent"], 3);
    // What the devices received during the scan (their own record): only
    // queries. Device 1 first got the rate and the slew.
    let mut received = sim.received("1.1.1");
    assert_eq!(
        received.drain(..2).map(|(_, p)| p).collect::<Vec<_>>(),
        ["RP01F4", "PR"],
        "{received:?}"
    );
    received.extend(sim.received("1.1.2"));
    received.extend(sim.received("1.1.5"));
    assert!(received.len() >= 3, "every device was asked: {received:?}");
    for (_, payload) in &received {
        assert!(
            payload.contains('?') || payload == "AW",
            "the scan sent {payload:?}, not a query: {received:?}"
        );
    }
    // The slew of device 1 went on through the scan (at 5 deg/s: a stopped
    // gimbal never gets there, and the wait fails on the hang guard).
    let a = sim.position1();
    eventually("the slew to go on after the scan", || sim.position1().0 > a.0 + 1.0);
    sim.json1(&["stop"]);
}

#[test]
fn scan_reports_garbage_timeouts_and_duplicate_ids_and_goes_on() {
    let bus = FakeBus::start();
    let out = gimbalctl(&[
        "--json",
        "--tcp",
        &bus.addr,
        "scan",
        "--direct",
        "--bus",
        "1.1",
        "--devices",
        "1-5",
        "--timeout",
        "200",
    ]);
    assert_eq!(out.code, 0, "{out:?}");
    let v = out.json();
    let devices: Vec<u64> = v["bus"]["devices"]
        .as_array()
        .unwrap()
        .iter()
        .map(|d| d["id"].as_u64().unwrap())
        .collect();
    assert_eq!(devices, [1, 3], "{v}");
    assert_eq!(v["bus"]["devices"][0]["awake"]["motors_off"], true, "{v}");
    assert_eq!(
        v["bus"]["devices"][0]["status"]["azimuth"]["error_present"], true,
        "{v}"
    );
    let problems: Vec<(&str, &str)> = v["problems"]
        .as_array()
        .unwrap()
        .iter()
        .map(|p| (p["address"].as_str().unwrap(), p["outcome"].as_str().unwrap()))
        .collect();
    assert_eq!(problems, [("1.1.2", "bad_result"), ("1.1.4", "no_result")], "{v}");
    let collisions = v["collisions"].as_array().unwrap();
    assert_eq!(collisions.len(), 1, "{v}");
    assert_eq!(collisions[0]["address"], "1.1.3");
    let serials: Vec<&str> = collisions[0]["answers"]
        .as_array()
        .unwrap()
        .iter()
        .map(|a| a["serial"].as_str().unwrap())
        .collect();
    assert_eq!(serials, ["FAKE-3A", "FAKE-3B"], "{v}");
    assert_eq!(v["bus"]["devices"][1]["collision"], true);
    // Only the identity and status queries went out.
    for p in bus.received() {
        assert!(["D?", "AW", "I?"].contains(&p.as_str()), "scan sent {p:?}");
    }
    let text = gimbalctl(&[
        "--tcp",
        &bus.addr,
        "scan",
        "--direct",
        "--bus",
        "1.1",
        "--devices",
        "1-5",
        "--timeout",
        "200",
    ]);
    assert!(
        text.stdout.contains("COLLISION") && text.stdout.contains("1.1.4:"),
        "{text:?}"
    );
}
