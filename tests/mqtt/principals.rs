//! A command from the broker is the door's principal's, or the `user` it
//! names (ARCHITECTURE "Principals"): gimbal-mqtt reaches gcud over TLS
//! with its own certificate (principal `gimbal-mqtt`, which
//! `acts_for_users`) and its commands go as `control-room`; gcud's audit
//! and the retained state name that user and the tool.

use super::*;

#[test]
fn the_broker_s_commands_go_as_the_user_the_door_names() {
    let Some(broker) = Broker::start() else { return };
    let dir = tempfile::tempdir().expect("temp dir");
    let pki = dir.path().join("tls");
    support::tls_init(&pki, &["gimbal-mqtt"]);
    let p = pki.display();
    let gcud = Gcud::start(&format!(
        "[gcu]\ngroup = {group}\n[control]\nhold_ms = 60000\n\
         [[port]]\nid = 1\nsimulate = [1]\n[[port]]\nid = 2\nsimulate = [1]\n\
         {clients}allow_source_groups = [0, {DOOR_GROUP}]\n\
         [[link]]\nname = \"doors\"\nrole = \"client\"\nlisten = \"127.0.0.1:0\"\npriority = 100\n\
         allow_source_groups = [0, {DOOR_GROUP}]\n\
         tls = {{ cert = \"{p}/gcud.crt\", key = \"{p}/gcud.key\", client_ca = \"{p}/ca.crt\" }}\n\
         [[principal]]\nname = \"gimbal-mqtt\"\npriority = 90\nacts_for_users = true\n\
         [[principal]]\nname = \"control-room\"\npriority = 70\n",
        group = support::door::GCUD_GROUP,
        clients = support::gcud::CLIENTS,
    ));
    let doors = gcud.address("listening link=doors");
    let mut door = Door::new("gimbal-mqtt", env!("CARGO_BIN_EXE_gimbal-mqtt"));
    let config = door_config(&gcud, &broker.url(), "north", "user = \"control-room\"", "")
        .replace(&format!("gcud = \"{}\"", gcud.clients()), &format!(
            "gcud = \"tls://{doors}\"\ngcud_tls = {{ ca = \"{p}/ca.crt\", cert = \"{p}/gimbal-mqtt.crt\", key = \"{p}/gimbal-mqtt.key\" }}"
        ));
    door.start(&config);
    let site = Site {
        gcud,
        door,
        name: "north".to_owned(),
    };
    site.wait_online(&broker);
    let r = site.command(&broker, "mast", r#"{"goto": {"pan_deg": 11.0, "tilt_deg": 0.0}}"#);
    assert_eq!(r["ok"], true, "{r}\n{}", site.logs());
    wait_at(&site.gcud, MAST, 11.0, 0.0);
    let log = site.gcud.log();
    assert!(
        log.lines()
            .any(|l| l.contains("control-room via gimbal-mqtt: go to pan 11.00°") && l.contains("accepted")),
        "no audit line of control-room's goto:\n{log}"
    );
    eventually("the state to name the user and the tool", || {
        site.state(&broker, "mast")["controller"] == "control-room via gimbal-mqtt (priority 70)"
    });
}
