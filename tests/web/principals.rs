//! The doors' users are principals at gcud (issue 49, ARCHITECTURE
//! "Principals"): gimbal-web and gimbal-onvif connect to gcud over TLS,
//! each with its own client certificate (principals `gimbal-web` and
//! `gimbal-onvif`, which `acts_for_users`), and say for which of their
//! users each command is (`~U`). gcud governs each user by its own
//! `[[principal]]` priority across both doors: the higher takes over, the
//! lower is refused naming the holder and the tool, and the audit lines
//! name each. Plain HTTP to gimbal-web (no browser), onvif-zeep-async to
//! gimbal-onvif.

use super::access::raw;
use super::*;

/// A signed-in user: its session cookie and CSRF token.
pub(super) struct Signed {
    cookie: String,
    csrf: String,
}

pub(super) fn sign_in(stack: &Stack, user: &str, password: &str) -> Signed {
    let body = json!({ "user": user, "password": password }).to_string();
    let (status, answer) = raw(
        &stack.url,
        "POST",
        "/api/sign-in",
        &[("Content-Type", "application/json")],
        &body,
    );
    assert_eq!(status, 200, "sign-in of {user}: {answer}");
    let cookie = answer
        .lines()
        .find(|l| l.to_ascii_lowercase().starts_with("set-cookie:"))
        .and_then(|l| l["set-cookie:".len()..].trim().split(';').next())
        .expect("a session cookie")
        .to_owned();
    let (status, answer) = raw(&stack.url, "GET", "/api/session", &[("Cookie", &cookie)], "");
    assert_eq!(status, 200, "session of {user}: {answer}");
    let json: Value = serde_json::from_str(answer.split("\r\n\r\n").nth(1).unwrap_or_default()).expect("JSON");
    let csrf = json["csrf"].as_str().expect("a CSRF token").to_owned();
    Signed { cookie, csrf }
}

pub(super) fn post(stack: &Stack, who: &Signed, path: &str, body: Value) -> (u16, String) {
    raw(
        &stack.url,
        "POST",
        path,
        &[
            ("Content-Type", "application/json"),
            ("Cookie", &who.cookie),
            ("X-CSRF-Token", &who.csrf),
        ],
        &body.to_string(),
    )
}

/// gcud's buses (as [`start_gcud`]'s) with a TLS listener `doors`
/// requiring client certificates of the CA in `pki`; gcud knows the door
/// and gimbal-onvif (90, acting for users), two users of gimbal-web, `op`
/// (50) and `admin` (80), and one of gimbal-onvif, `carol` (60).
fn tls_gcud(pki: &Path) -> Gcud {
    let p = pki.display();
    Gcud::start(&format!(
        "[gcu]\ngroup = {group}\n[control]\nhold_ms = 60000\n\
         [[port]]\nid = 1\nsimulate = [1]\n[[port]]\nid = 2\nsimulate = [1]\n\
         {clients}allow_source_groups = [0, {DOOR_GROUP}]\n\
         [[link]]\nname = \"doors\"\nrole = \"client\"\nlisten = \"127.0.0.1:0\"\npriority = 100\n\
         allow_source_groups = [0, {DOOR_GROUP}]\n\
         tls = {{ cert = \"{p}/gcud.crt\", key = \"{p}/gcud.key\", client_ca = \"{p}/ca.crt\" }}\n\
         [[principal]]\nname = \"gimbal-web\"\npriority = 90\nacts_for_users = true\n\
         [[principal]]\nname = \"gimbal-onvif\"\npriority = 90\nacts_for_users = true\n\
         [[principal]]\nname = \"carol\"\npriority = 60\n\
         [[principal]]\nname = \"op\"\npriority = 50\n\
         [[principal]]\nname = \"admin\"\npriority = 80\n",
        group = support::door::GCUD_GROUP,
        clients = support::gcud::CLIENTS,
    ))
}

#[test]
fn the_doors_users_arbitrate_at_gcud_as_themselves_and_the_audit_names_each() {
    let dir = tempfile::tempdir().expect("temp dir");
    let pki = dir.path().join("tls");
    if !support::door::onvif_client_available() {
        return;
    }
    support::tls_init(&pki, &["gimbal-web", "gimbal-onvif"]);
    let gcud = tls_gcud(&pki);
    let doors = gcud.address("listening link=doors");
    let p = pki.display();
    let stack = Stack::with(gcud, |_, state| {
        format!(
            "gcud = \"tls://{doors}\"\n\
             gcud_tls = {{ ca = \"{p}/ca.crt\", cert = \"{p}/gimbal-web.crt\", key = \"{p}/gimbal-web.key\" }}\n\
             listen = \"127.0.0.1:0\"\nsource_group = {DOOR_GROUP}\nstate_file = \"{}\"\n{USERS}\
             [[gimbal]]\nname = \"mast-1\"\naddress = \"{MAST}\"\n",
            state.display()
        )
    });
    let onvif = onvif_door(&doors, &pki);
    let onvif_port = onvif.port("gimbal=mast-1 addr=").to_string();
    // carol's AbsoluteMove to `pan` degrees (generic x = pan / 180).
    let carol = |pan: f64| {
        let args = json!({ "x": pan / 180.0, "y": 0.0 }).to_string();
        support::door::python_step(
            "tests/onvif/client.py",
            "absolute",
            &["127.0.0.1", &onvif_port, "carol", "carol-secret", &args],
            || onvif.log(),
        )
    };
    let op = sign_in(&stack, "op", "op-secret");
    let admin = sign_in(&stack, "admin", "admin-secret");
    let goto = |who: &Signed, pan: f64| {
        post(
            &stack,
            who,
            "/api/goto",
            json!({ "gimbal": 0, "pan": pan, "tilt": 0.0 }),
        )
    };

    let (status, answer) = goto(&op, 20.0);
    assert_eq!(status, 200, "op moves the free gimbal: {answer}\n{}", stack.gcud.log());
    eventually("mast-1 at op's 20°", || stack.gcud.position(MAST).0 == 20.0);
    let moved = carol(-18.0);
    assert!(
        moved.get("ok").is_some(),
        "carol (60) through ONVIF takes over from op: {moved}"
    );
    eventually("mast-1 at carol's -18°", || stack.gcud.position(MAST).0 == -18.0);
    let (status, answer) = goto(&op, 30.0);
    assert_ne!(status, 200, "op is refused while carol holds: {answer}");
    assert!(
        answer.contains("carol via gimbal-onvif"),
        "the refusal names the holder and its tool: {answer}"
    );
    let (status, answer) = goto(&admin, -20.0);
    assert_eq!(status, 200, "admin (80) takes over from carol (60): {answer}");
    eventually("mast-1 at admin's -20°", || stack.gcud.position(MAST).0 == -20.0);
    let refused = carol(36.0);
    assert!(
        refused.get("ok").is_none(),
        "carol is refused while admin holds: {refused}"
    );
    let (status, answer) = goto(&op, 30.0);
    assert_ne!(status, 200, "op is refused while admin holds: {answer}");
    assert!(
        answer.contains("admin via gimbal-web"),
        "the refusal names the holder and its tool: {answer}"
    );
    assert_eq!(
        stack.gcud.settled_position(MAST).0,
        -20.0,
        "the refused moves moved nothing"
    );

    let log = stack.gcud.log();
    for (who, outcome) in [
        ("op", "accepted"),
        ("carol", "accepted"),
        ("op", "refused"),
        ("admin", "accepted"),
        ("carol", "refused"),
    ] {
        let tool = if who == "carol" { "gimbal-onvif" } else { "gimbal-web" };
        assert!(
            log.lines()
                .any(|l| l.contains(&format!("{who} via {tool}: go to pan ")) && l.contains(outcome)),
            "no audit line of {who}'s {outcome} goto:\n{log}"
        );
    }
}

/// gimbal-onvif in front of gcud's TLS listener `doors`, with its own
/// certificate from `pki` and one ONVIF user, carol.
fn onvif_door(doors: &str, pki: &Path) -> Door {
    let mut onvif = Door::new("gimbal-onvif", env!("CARGO_BIN_EXE_gimbal-onvif"));
    let state = onvif.dir.path().join("presets.toml");
    let p = pki.display();
    onvif.start(&format!(
        "gcud = \"tls://{doors}\"\n\
         gcud_tls = {{ ca = \"{p}/ca.crt\", cert = \"{p}/gimbal-onvif.crt\", key = \"{p}/gimbal-onvif.key\" }}\n\
         source_group = {DOOR_GROUP}\nstate_file = \"{}\"\n[discovery]\nenabled = false\n\
         [[user]]\nname = \"carol\"\npassword = \"carol-secret\"\nrole = \"operator\"\n\
         [[gimbal]]\nname = \"mast-1\"\naddress = \"{MAST}\"\nlisten = \"127.0.0.1:0\"\n\
         pan_deg = [-180.0, 180.0]\ntilt_deg = [-90.0, 90.0]\n",
        state.display()
    ));
    onvif
}
