//! `gimbalctl gcud-status` as an operator reads it (issue 24): a client
//! listener is up while it serves, before anyone has connected; a link that
//! dials out is up only while its connection is.

mod support;

use support::gcud::{CLIENTS, Gcud, METRICS};

#[test]
fn a_serving_listener_is_up_and_a_link_that_cannot_connect_is_not() {
    // An address nobody listens on: the upstream link keeps retrying.
    let closed = std::net::TcpListener::bind("127.0.0.1:0").expect("bind");
    let nowhere = closed.local_addr().expect("address");
    drop(closed);
    let gcud = Gcud::start(&format!(
        "[gcu]\ngroup = 5\n[[port]]\nid = 1\nsimulate = [1]\n{CLIENTS}\
         [[link]]\nname = \"hub\"\nrole = \"upstream\"\nconnect = \"{nowhere}\"\n{METRICS}"
    ));
    gcud.clients(); // bound and serving

    let status = gcud.status();
    let link = |name: &str| {
        let links = status["links"].as_array().expect("links");
        links
            .iter()
            .find(|l| l["link"] == name)
            .unwrap_or_else(|| panic!("{name} in {status}"))
            .clone()
    };
    let (clients, hub) = (link("clients"), link("hub"));
    assert_eq!(
        (clients["up"].as_bool(), clients["connections"].as_u64()),
        (Some(true), Some(0)),
        "{clients}"
    );
    assert_eq!(
        (hub["up"].as_bool(), hub["connections"].as_u64()),
        (Some(false), Some(0)),
        "{hub}"
    );

    let http = gcud.address("metrics at /metrics");
    let out = support::gimbalctl(&["gcud-status", "--http", &http]);
    assert_eq!(out.code, 0, "{out:?}");
    let row = |name: &str| -> Vec<String> {
        let line = out.stdout.lines().find(|l| l.starts_with(&format!("{name} ")));
        let line = line.unwrap_or_else(|| panic!("a row for {name}: {}", out.stdout));
        line.split_whitespace().map(str::to_owned).collect()
    };
    assert_eq!(row("clients")[..3], ["clients", "client", "yes"], "{}", out.stdout);
    assert_eq!(row("hub")[..3], ["hub", "upstream", "no"], "{}", out.stdout);
}

/// After a broadcast `home` (5.1.255), gcud-status no longer shows the old
/// positions as where the gimbals are: each says it moved since (issue 37).
#[test]
fn a_broadcast_motion_marks_every_position_on_the_port_as_left() {
    let gcud = Gcud::start(&format!(
        "[gcu]\ngroup = 5\n[[port]]\nid = 1\nsimulate = [1, 2]\n{CLIENTS}{METRICS}"
    ));
    for to in ["5.1.1", "5.1.2"] {
        let out = gcud.ctl(&["--to", to, "goto", "12.5", "-3", "--wait"]);
        assert_eq!(out.code, 0, "{out:?}");
    }
    let device = |status: &serde_json::Value, n: u64| {
        status["ports"][0]["devices"]
            .as_array()
            .and_then(|d| d.iter().find(|d| d["device"].as_u64() == Some(n)).cloned())
            .unwrap_or_else(|| panic!("device {n} in {status}"))
    };
    let status = gcud.status();
    for n in [1, 2] {
        let p = &device(&status, n)["position"];
        assert_eq!(p["pan_deg"].as_f64(), Some(12.5), "{p}");
        assert!(p["moved_unix"].is_null(), "nothing moved it since: {p}");
    }

    // A broadcast is answered by nobody: gimbalctl returns once it is sent,
    // and gcud runs it on the bus in its turn. Wait (bounded) for that.
    let out = gcud.ctl(&["--to", "5.1.255", "home"]);
    assert_eq!(out.code, 0, "{out:?}");
    let deadline = std::time::Instant::now() + support::HANG_GUARD;
    let moved =
        |status: &serde_json::Value| [1, 2].map(|n| device(status, n)["position"]["moved_unix"].as_f64().is_some());
    let mut status = gcud.status();
    while moved(&status) != [true, true] && std::time::Instant::now() < deadline {
        std::thread::sleep(std::time::Duration::from_millis(50));
        status = gcud.status();
    }
    assert_eq!(
        moved(&status),
        [true, true],
        "both moved since their readings: {status}"
    );
    let http = gcud.address("metrics at /metrics");
    let out = support::gimbalctl(&["gcud-status", "--http", &http]);
    assert_eq!(out.code, 0, "{out:?}");
    assert_eq!(out.stdout.matches("moved since").count(), 2, "{}", out.stdout);

    // A new reading is where the gimbal is again.
    gcud.position("5.1.1");
    let p = &device(&gcud.status(), 1)["position"];
    assert!(p["moved_unix"].is_null(), "read again: {p}");
}
