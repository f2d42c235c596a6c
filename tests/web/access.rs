//! Who may do what: a user role moves nothing; a wrong password and a
//! POST without the CSRF token are refused.

use super::*;

/// A raw HTTP/1.1 request to gimbal-web: the status code and the whole answer.
pub(super) fn raw(url: &str, method: &str, path: &str, headers: &[(&str, &str)], body: &str) -> (u16, String) {
    let addr = url.trim_start_matches("http://").trim_end_matches('/');
    let mut s = std::net::TcpStream::connect(addr).expect("connect to gimbal-web");
    s.set_read_timeout(Some(HANG_GUARD)).expect("timeout");
    let mut head = format!(
        "{method} {path} HTTP/1.1\r\nHost: {addr}\r\nConnection: close\r\nContent-Length: {}\r\n",
        body.len()
    );
    for (k, v) in headers {
        head.push_str(&format!("{k}: {v}\r\n"));
    }
    write!(s, "{head}\r\n{body}").expect("request");
    let mut text = String::new();
    s.read_to_string(&mut text).expect("answer");
    let status = text.split_whitespace().nth(1).and_then(|c| c.parse().ok()).unwrap_or(0);
    (status, text)
}

#[test]
fn a_user_role_cannot_move_anything() {
    if !browser_available() {
        return;
    }
    let stack = Stack::start();
    let mut b = stack.browser("viewer", "viewer-secret");
    for button in [
        "Pan left",
        "Pan right",
        "Tilt up",
        "Tilt down",
        "Stop",
        "Home",
        "Save preset",
    ] {
        assert_eq!(
            stack.call(&mut b, json!({ "op": "disabled", "card": "mast-1", "button": button })),
            json!(true),
            "{button} is disabled for a user"
        );
    }
    // The page's own request, with its cookie and CSRF token, is refused too.
    let answer = stack.call(
        &mut b,
        json!({ "op": "fetch", "path": "/api/move", "with_token": true,
                "body": { "gimbal": 0, "pan": 1, "tilt": 0, "speed": 1.0 } }),
    );
    assert_eq!(answer["status"], 403, "{answer}");
    assert!(answer["body"].as_str().unwrap().contains("may not move"), "{answer}");
    let answer = stack.call(
        &mut b,
        json!({ "op": "fetch", "path": "/api/home", "with_token": true, "body": { "gimbal": 0 } }),
    );
    assert_eq!(answer["status"], 403, "{answer}");
    std::thread::sleep(Duration::from_millis(300));
    let sent = door_frames(&stack.gcud, MAST);
    assert!(
        sent.iter().all(|p| p == "P?" || p == "D?"),
        "a user's session sent only queries: {sent:?}"
    );
}

#[test]
fn a_wrong_password_and_a_post_without_the_csrf_token_are_refused() {
    if !browser_available() {
        return;
    }
    let stack = Stack::start();
    // In the browser: the sign-in form says why, and no card appears.
    let mut b = Browser::start();
    stack.call(&mut b, json!({ "op": "open", "url": stack.url }));
    stack.call(&mut b, json!({ "op": "sign_in", "user": "op", "password": "wrong" }));
    let why = stack.call(&mut b, json!({ "op": "sign_in_error" }));
    assert_eq!(why, json!("wrong user or password"));
    // Raw HTTP: a sign-in gives the cookie (HttpOnly, SameSite=Strict).
    let (status, answer) = raw(
        &stack.url,
        "POST",
        "/api/sign-in",
        &[("Content-Type", "application/json")],
        r#"{"user":"op","password":"op-secret"}"#,
    );
    assert_eq!(status, 200, "{answer}");
    let set_cookie = answer
        .lines()
        .find(|l| l.to_ascii_lowercase().starts_with("set-cookie:"))
        .expect("a cookie");
    assert!(
        set_cookie.contains("HttpOnly") && set_cookie.contains("SameSite=Strict"),
        "{set_cookie}"
    );
    let cookie = set_cookie["set-cookie:".len()..]
        .trim()
        .split(';')
        .next()
        .unwrap()
        .to_owned();
    let move_right = r#"{"gimbal":0,"pan":1,"tilt":0,"speed":1.0}"#;
    let json = ("Content-Type", "application/json");
    // A state-changing request without the token, or with a wrong one: refused.
    let (status, answer) = raw(
        &stack.url,
        "POST",
        "/api/move",
        &[json, ("Cookie", &cookie)],
        move_right,
    );
    assert_eq!(status, 403, "{answer}");
    assert!(answer.contains("no X-CSRF-Token header"), "{answer}");
    let (status, answer) = raw(
        &stack.url,
        "POST",
        "/api/move",
        &[json, ("Cookie", &cookie), ("X-CSRF-Token", "forged")],
        move_right,
    );
    assert_eq!(status, 403, "{answer}");
    // Without a cookie: not signed in.
    let (status, _) = raw(&stack.url, "POST", "/api/stop", &[json], r#"{"gimbal":0}"#);
    assert_eq!(status, 401);
    // A form posted from another site is no JSON sign-in.
    let (status, _) = raw(
        &stack.url,
        "POST",
        "/api/sign-in",
        &[("Content-Type", "application/x-www-form-urlencoded")],
        "user=op&password=op-secret",
    );
    assert_eq!(status, 400);
    // With the token from /api/session, the same request moves the gimbal.
    let (_, session) = raw(&stack.url, "GET", "/api/session", &[("Cookie", &cookie)], "");
    let body = session.split("\r\n\r\n").nth(1).expect("a body");
    let csrf: Value = serde_json::from_str(body).expect("JSON");
    let token = csrf["csrf"].as_str().expect("a token");
    let (status, answer) = raw(
        &stack.url,
        "POST",
        "/api/move",
        &[json, ("Cookie", &cookie), ("X-CSRF-Token", token)],
        move_right,
    );
    assert_eq!(status, 200, "{answer}");
    let before: Vec<String> = door_frames(&stack.gcud, MAST);
    assert!(
        before.contains(&"PR".to_owned()),
        "only the request with the token moved it: {before:?}"
    );
    // Not renewed: the lease stops it.
    bus_stop_time(&stack.gcud, MAST, "PS");
}
