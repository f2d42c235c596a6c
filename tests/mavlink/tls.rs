//! gimbal-mavlink reaches gcud over TLS with its own client certificate
//! (issue 49, ARCHITECTURE "Principals"): `gcud = "tls://..."` with
//! `gcud_tls`, gcud's listener requiring certificates of its CA; a ground
//! station points the gimbal through it, the bus shows the motion, and
//! gcud's audit names the door as the principal that moved it.

use serde_json::json;

use super::*;

#[test]
fn the_door_drives_the_gimbal_over_tls_as_its_own_principal() {
    if !client_available() {
        return;
    }
    let dir = tempfile::tempdir().expect("temp dir");
    let pki = dir.path().join("tls");
    support::tls_init(&pki, &["gimbal-mavlink"]);
    let p = pki.display();
    let gcud = Gcud::start(&format!(
        "[gcu]\ngroup = {group}\n[[port]]\nid = 1\nsimulate = [1]\n[[port]]\nid = 2\nsimulate = [1]\n\
         {clients}allow_source_groups = [0, {DOOR_GROUP}]\n\
         [[link]]\nname = \"doors\"\nrole = \"client\"\nlisten = \"127.0.0.1:0\"\n\
         allow_source_groups = [0, {DOOR_GROUP}]\n\
         tls = {{ cert = \"{p}/gcud.crt\", key = \"{p}/gcud.key\", client_ca = \"{p}/ca.crt\" }}\n\
         [[principal]]\nname = \"gimbal-mavlink\"\npriority = 50\n",
        group = support::door::GCUD_GROUP,
        clients = support::gcud::CLIENTS,
    ));
    let doors = gcud.address("listening link=doors");
    let config = mavlink_config(&format!("tls://{doors}"), 1000, "");
    let top = format!(
        "gcud_tls = {{ ca = \"{p}/ca.crt\", cert = \"{p}/gimbal-mavlink.crt\", key = \"{p}/gimbal-mavlink.key\" }}"
    );
    let stack = Stack::start_configured(gcud, &top, &config);
    let r = stack.gcs("pitchyaw", GCS, json!({ "pitch": -12.0, "yaw": 33.0 }));
    assert_eq!(r["result"], ACCEPTED, "{r}\n{}", stack.gcud.log());
    let (pan, tilt) = stack.gcud.settled_position(MAST);
    assert!(
        (pan - 33.0).abs() <= 0.5 && (tilt + 12.0).abs() <= 0.5,
        "bus at {pan}, {tilt}"
    );
    let log = stack.gcud.log();
    assert!(
        log.lines()
            .any(|l| l.contains("gimbal-mavlink via doors: go to pan ") && l.contains("accepted")),
        "gcud's audit names the door:\n{log}"
    );
}
