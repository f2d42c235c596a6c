//! gimbal-web in HTTPS (issue 49): `[http] tls = "self-signed"`, the
//! certificate made and kept beside the state file; a browser that accepts
//! it signs in and drives a gimbal (the motion read on the bus); the
//! session cookie is Secure, HttpOnly and SameSite=Strict; plain HTTP to
//! the HTTPS port gets no page and no cookie.

use super::*;

/// The page in HTTPS with a self-signed certificate, in front of `gcud`:
/// the stack (its url `https://127.0.0.1:PORT/`) and the certificate.
fn https_stack() -> (Stack, std::path::PathBuf) {
    let gcud = start_gcud();
    let mut web = Door::new("gimbal-web", env!("CARGO_BIN_EXE_gimbal-web"));
    let state = web.dir.path().join("presets.toml");
    web.start(&format!(
        "gcud = \"{}\"\nlisten = \"127.0.0.1:0\"\nsource_group = {DOOR_GROUP}\nstate_file = \"{}\"\n\
         [http]\ntls = \"self-signed\"\n{USERS}[[gimbal]]\nname = \"mast-1\"\naddress = \"{MAST}\"\n",
        gcud.clients(),
        state.display()
    ));
    let url = format!("https://127.0.0.1:{}/", web.port("page listening"));
    let cert = web.dir.path().join("gimbal-web-self-signed.crt");
    (Stack { web, gcud, url }, cert)
}

/// The address `IP:PORT` of a stack's url.
fn addr_of(url: &str) -> &str {
    url.split("://").nth(1).unwrap_or(url).trim_end_matches('/')
}

/// A sign-in as `user` over HTTPS, trusting `cert`: the whole answer.
fn sign_in_over_tls(addr: &str, cert: &Path, user: &str, password: &str) -> String {
    let body = json!({ "user": user, "password": password }).to_string();
    let request = format!(
        "POST /api/sign-in HTTP/1.1\r\nHost: {addr}\r\nConnection: close\r\nContent-Type: application/json\r\nContent-Length: {}\r\n\r\n{body}",
        body.len()
    );
    support::door::https_raw(addr, cert, &request)
}

#[test]
fn over_https_a_browser_signs_in_and_drives_a_gimbal_with_a_secure_cookie() {
    if !browser_available() {
        return;
    }
    let (stack, cert) = https_stack();
    assert!(stack.url.starts_with("https://"), "{}", stack.url);
    let addr = addr_of(&stack.url).to_owned();
    // The cookie's flags, from the Set-Cookie header; the certificate
    // names 127.0.0.1 (the client trusts it and checks the name).
    let answer = sign_in_over_tls(&addr, &cert, "op", "op-secret");
    assert!(answer.starts_with("HTTP/1.1 200"), "{answer}\n{}", stack.log());
    let set_cookie = answer
        .lines()
        .find(|l| l.to_ascii_lowercase().starts_with("set-cookie:"))
        .unwrap_or_else(|| panic!("no Set-Cookie: {answer}"));
    let flags: Vec<&str> = set_cookie.split(';').skip(1).map(str::trim).collect();
    for flag in ["Secure", "HttpOnly", "SameSite=Strict"] {
        assert!(flags.contains(&flag), "{flag} missing: {set_cookie}");
    }
    // Plain HTTP to the HTTPS port: a 400 naming https, no page, no cookie.
    let plain = support::door::plain_raw(
        &addr,
        &format!("POST /api/sign-in HTTP/1.1\r\nHost: {addr}\r\nContent-Length: 2\r\n\r\n{{}}"),
    );
    assert!(
        plain.starts_with("HTTP/1.1 400") && plain.contains("https://"),
        "{plain:?}"
    );
    assert!(!plain.to_ascii_lowercase().contains("set-cookie"), "{plain:?}");
    // A browser that accepts the certificate signs in and holds a button:
    // the bus shows the motion, and the door's stop when released.
    let mut b = Browser::launch(&["--accept-insecure-certs"]);
    stack.call(&mut b, json!({ "op": "open", "url": stack.url }));
    stack.call(
        &mut b,
        json!({ "op": "sign_in", "user": "op", "password": "op-secret" }),
    );
    let cards = stack.call(&mut b, json!({ "op": "card_names" }));
    assert_eq!(cards[0], "mast-1", "signed in: {cards}");
    let from = stack.gcud.position(MAST);
    stack.call(&mut b, json!({ "op": "hold", "card": "mast-1", "button": "Pan right" }));
    wait_moving(&stack.gcud, MAST, from);
    let released = stack.call(&mut b, json!({ "op": "release" }));
    let stopped = bus_stop_time(&stack.gcud, MAST, "PS");
    let after = stopped - released.as_f64().expect("a time");
    assert!(after <= STOP_WITHIN_S, "PS {after:.3} s after the release");
    assert!(stack.gcud.settled_position(MAST).0 > from.0, "pan right moved pan up");
    assert!(door_frames(&stack.gcud, MAST).contains(&"PR".to_owned()));
    eprintln!(
        "over HTTPS: held Pan right, PS on the bus {:.0} ms after the release",
        after * 1000.0
    );
}

#[test]
fn the_self_signed_certificate_is_kept_0600_and_served_again_after_a_restart() {
    let (mut stack, cert) = https_stack();
    let key = cert.with_extension("key");
    let mode = std::os::unix::fs::PermissionsExt::mode(&std::fs::metadata(&key).expect("the key").permissions());
    assert_eq!(mode & 0o777, 0o600, "{}", key.display());
    let first = std::fs::read(&cert).expect("the certificate");
    let config = std::fs::read_to_string(stack.web.dir.path().join("gimbal-web.toml")).expect("config");
    let _ = stack.web.signal(nix::sys::signal::Signal::SIGTERM);
    stack.web.start(&config);
    let addr = format!("127.0.0.1:{}", stack.web.port("page listening"));
    assert_eq!(std::fs::read(&cert).expect("the certificate"), first, "made once, kept");
    let answer = sign_in_over_tls(&addr, &cert, "viewer", "viewer-secret");
    assert!(answer.starts_with("HTTP/1.1 200"), "{answer}");
    assert!(
        stack.log().contains("sha256="),
        "the fingerprint is logged: {}",
        stack.log()
    );
}
