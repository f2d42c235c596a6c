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
