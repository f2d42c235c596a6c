//! Issue 49 end to end, two gcud processes: principals travel between
//! GCUs (ARCHITECTURE "Principals"). A hub (group 5, its clients at
//! priority 50 and its operators at 80) dials a field GCU (group 6, a
//! simulated gimbal 6.1.1, its own console at 60) over TLS with the hub's
//! certificate (principal `hub`, which `acts_for_users`); the hub says
//! whose each forwarded command is (`~P`), and the field governs the hub's
//! operators and clients apart, as the hub does, and apart from its own
//! console. What moved is read on the field's bus side.

mod support;

use support::gcud::Gcud;
use support::{Output, eventually};

const FIELD_GIMBAL: &str = "6.1.1";

fn ctl(addr: &str, args: &[&str]) -> Output {
    let mut full = vec!["--tcp", addr];
    full.extend_from_slice(args);
    support::gimbalctl(&full)
}

fn pan(field: &Gcud) -> f64 {
    field.position(FIELD_GIMBAL).0
}

#[test]
fn a_hubs_client_cannot_move_a_field_gimbal_the_hubs_operators_hold() {
    let dir = tempfile::tempdir().expect("temp dir");
    let pki = dir.path().join("tls");
    let made = support::gimbalctl(&["tls", "init", "--dir", pki.to_str().unwrap(), "--principal", "hub"]);
    assert_eq!(made.code, 0, "{made:?}");
    let p = pki.display();
    let field = Gcud::start(&format!(
        "[gcu]\ngroup = 6\n[control]\nhold_ms = 60000\n[[port]]\nid = 1\nsimulate = [1]\n\
         {clients}priority = 60\n\
         [[link]]\nname = \"from-hub\"\nrole = \"upstream\"\nlisten = \"127.0.0.1:0\"\npriority = 100\n\
         tls = {{ cert = \"{p}/gcud.crt\", key = \"{p}/gcud.key\", client_ca = \"{p}/ca.crt\" }}\n\
         [[principal]]\nname = \"hub\"\npriority = 100\nacts_for_users = true\n",
        clients = support::gcud::CLIENTS,
    ));
    let from_hub = field.address("listening link=from-hub");
    let hub = Gcud::start(&format!(
        "[gcu]\ngroup = 5\n[control]\nhold_ms = 60000\n\
         {clients}\
         [[link]]\nname = \"operators\"\nrole = \"client\"\nlisten = \"127.0.0.1:0\"\npriority = 80\n\
         [[link]]\nname = \"field\"\nrole = \"downstream\"\nconnect = \"{from_hub}\"\n\
         tls = {{ ca = \"{p}/ca.crt\", cert = \"{p}/hub.crt\", key = \"{p}/hub.key\" }}\n\
         [[route]]\ngroup = 6\nlink = \"field\"\n",
        clients = support::gcud::CLIENTS,
    ));
    hub.wait_for_log("link connected (TLS)");
    let (clients, operators) = (hub.clients(), hub.address("listening link=operators"));

    // The hub's operators take the field gimbal.
    let out = ctl(&operators, &["--to", FIELD_GIMBAL, "goto", "20", "0", "--wait"]);
    assert_eq!(out.code, 0, "{out:?}\nhub:\n{}\nfield:\n{}", hub.log(), field.log());
    assert_eq!(pan(&field), 20.0);
    // A hub client (50) is refused at the field, naming the operators.
    let out = ctl(&clients, &["--to", FIELD_GIMBAL, "goto", "-30", "0"]);
    assert_eq!(out.code, 23, "refused for control: {out:?}\nfield:\n{}", field.log());
    // So is the field's own console (60): it tells the hub's operators apart.
    let out = field.ctl(&["--to", FIELD_GIMBAL, "goto", "-40", "0"]);
    assert_eq!(out.code, 23, "the field console is below the hub's operators: {out:?}");
    assert!(out.stderr.contains("operators via hub"), "{out:?}");
    assert_eq!(field.settled_position(FIELD_GIMBAL).0, 20.0, "nothing refused moved it");
    assert!(
        !field
            .received(FIELD_GIMBAL)
            .iter()
            .any(|(_, p)| p.starts_with("P") && p.contains("F448")),
        "the hub client's goto (-30°) never reached the field's bus"
    );
    // The operators again: still theirs.
    let out = ctl(&operators, &["--to", FIELD_GIMBAL, "goto", "25", "0", "--wait"]);
    assert_eq!(out.code, 0, "{out:?}");
    eventually("the field gimbal at 25°", || pan(&field) == 25.0);
    let log = field.log();
    assert!(
        log.lines()
            .any(|l| l.contains("operators via hub: go to pan ") && l.contains("accepted")),
        "the field's audit names the hub's operators:\n{log}"
    );
    assert!(
        log.lines()
            .any(|l| l.contains("clients via hub: go to pan -30.00°") && l.contains("refused")),
        "the field's audit names the hub's client, refused:\n{log}"
    );
}
