//! The doors' own metrics (issue 53), `[metrics] listen`: gimbal-web and
//! gimbal-onvif count their clients' requests by route or operation, their
//! live clients, and what became of their commands (delivered, or gcud's
//! refusal by rule), read from a scrape of the real door after it drove
//! real gcud. No browser: the page's API is called as the page calls it.

use super::access::raw;
use super::*;

/// The value of the sample `name{labels}` in an OpenMetrics scrape.
fn sample(scrape: &str, series: &str) -> Option<f64> {
    scrape
        .lines()
        .find_map(|l| l.strip_prefix(series)?.strip_prefix(' ')?.parse().ok())
}

/// The header `name` of a raw HTTP answer.
fn header<'a>(answer: &'a str, name: &str) -> Option<&'a str> {
    answer.lines().take_while(|l| !l.is_empty()).find_map(|l| {
        let (k, v) = l.split_once(':')?;
        k.eq_ignore_ascii_case(name).then(|| v.trim())
    })
}

#[test]
fn gimbal_web_counts_requests_live_pages_outcomes_and_gcuds_refusals_by_rule() {
    let gimbals = "[[gimbal]]\nname = \"mast-1\"\naddress = \"5.1.1\"\n\
                   [[gimbal]]\nname = \"mast-2\"\naddress = \"5.2.1\"\n";
    let stack = Stack::with(support::door::start_governed_gcud(), |clients, state| {
        format!(
            "gcud = \"{clients}\"\nlisten = \"127.0.0.1:0\"\nsource_group = {DOOR_GROUP}\nstate_file = \"{}\"\n\
             [metrics]\nlisten = \"127.0.0.1:0\"\n{USERS}{gimbals}",
            state.display()
        )
    });
    let metrics = format!("127.0.0.1:{}", stack.web.port("metrics at /metrics"));
    let url = stack.url.trim_end_matches('/');
    // Signed in as the page does: the cookie, then the CSRF token.
    let (status, answer) = raw(
        url,
        "POST",
        "/api/sign-in",
        &[("Content-Type", "application/json")],
        r#"{"user":"op","password":"op-secret"}"#,
    );
    assert_eq!(status, 200, "{answer}");
    let cookie = header(&answer, "set-cookie")
        .expect("a session cookie")
        .split(';')
        .next()
        .unwrap()
        .to_owned();
    let (status, answer) = raw(url, "GET", "/api/session", &[("Cookie", &cookie)], "");
    assert_eq!(status, 200, "{answer}");
    let body = answer.split("\r\n\r\n").nth(1).unwrap_or_default();
    let session: Value = serde_json::from_str(body).unwrap_or_else(|e| panic!("{e}: {answer}"));
    let csrf = session["csrf"].as_str().expect("csrf").to_owned();
    let post = |path: &str, body: &str| {
        let headers = [
            ("Content-Type", "application/json"),
            ("Cookie", &cookie),
            ("X-CSRF-Token", &csrf),
        ];
        raw(url, "POST", path, &headers, body)
    };
    // The operators hold mast-1: the page's home there is refused by gcud.
    let out = support::door::operators_ctl(&stack.gcud, &["--to", MAST, "goto", "20", "10"]);
    assert_eq!(out.code, 0, "{out:?}");
    let (status, answer) = post("/api/home", r#"{"gimbal":0}"#);
    assert_eq!(status, 409, "refused by gcud: {answer}");
    // mast-2 is nobody's: its home goes through.
    let (status, answer) = post("/api/home", r#"{"gimbal":1}"#);
    assert_eq!(status, 200, "{answer}");
    // A path that is no route makes no label.
    let (status, _) = raw(url, "GET", "/no/such/route", &[], "");
    assert_eq!(status, 404);
    let scrape = support::http_get(&metrics, "/metrics");
    assert!(scrape.starts_with("HTTP/1.1 200"), "{scrape}");
    let door = "door=\"gimbal-web\"";
    let home = sample(
        &scrape,
        &format!("sagebrush_door_requests_total{{{door},kind=\"/api/home\"}}"),
    );
    assert_eq!(home, Some(2.0), "two homes asked:\n{scrape}");
    let signed_in = sample(
        &scrape,
        &format!("sagebrush_door_requests_total{{{door},kind=\"/api/sign-in\"}}"),
    );
    assert_eq!(signed_in, Some(1.0), "{scrape}");
    assert!(
        !scrape.contains("/no/such/route"),
        "a client's path became a label:\n{scrape}"
    );
    let refused = sample(
        &scrape,
        &format!("sagebrush_door_refusals_total{{{door},reason=\"not_in_control\"}}"),
    );
    assert!(refused >= Some(1.0), "gcud's refusal by its rule:\n{scrape}");
    let delivered = sample(
        &scrape,
        &format!("sagebrush_door_bus_outcomes_total{{{door},outcome=\"delivered\"}}"),
    );
    assert!(delivered >= Some(1.0), "the home of mast-2 and the polls:\n{scrape}");
    assert!(
        sample(
            &scrape,
            &format!("sagebrush_door_bus_outcomes_total{{{door},outcome=\"refused\"}}")
        ) >= Some(1.0),
        "{scrape}"
    );
    assert_eq!(
        sample(&scrape, &format!("sagebrush_door_sessions{{{door}}}")),
        Some(0.0),
        "no page open:\n{scrape}"
    );
    // A page's live updates: one session while its stream is open.
    let addr = url.trim_start_matches("http://").to_owned();
    let mut stream = std::net::TcpStream::connect(&addr).expect("connect");
    write!(
        stream,
        "GET /api/events HTTP/1.1\r\nHost: {addr}\r\nCookie: {cookie}\r\n\r\n"
    )
    .expect("request");
    eventually("the open event stream counted as a live page", || {
        let scrape = support::http_get(&metrics, "/metrics");
        sample(&scrape, &format!("sagebrush_door_sessions{{{door}}}")) == Some(1.0)
    });
    drop(stream);
    eventually("the closed stream no longer counted", || {
        let scrape = support::http_get(&metrics, "/metrics");
        sample(&scrape, &format!("sagebrush_door_sessions{{{door}}}")) == Some(0.0)
    });
}

/// A SOAP 1.2 envelope around `body` (no security header).
fn envelope(body: &str) -> String {
    format!(
        "<?xml version=\"1.0\"?><s:Envelope xmlns:s=\"http://www.w3.org/2003/05/soap-envelope\" \
         xmlns:tds=\"http://www.onvif.org/ver10/device/wsdl\"><s:Body>{body}</s:Body></s:Envelope>"
    )
}

#[test]
fn gimbal_onvif_counts_answered_operations_by_name_and_every_fault_as_one_kind() {
    let gcud = start_gcud();
    let mut onvif = Door::new("gimbal-onvif", env!("CARGO_BIN_EXE_gimbal-onvif"));
    onvif.start(&format!(
        "gcud = \"{}\"\nsource_group = {DOOR_GROUP}\n[metrics]\nlisten = \"127.0.0.1:0\"\n\
         [[user]]\nname = \"op\"\npassword = \"op-secret\"\nrole = \"operator\"\n\
         [[gimbal]]\nname = \"mast-1\"\naddress = \"{MAST}\"\nlisten = \"127.0.0.1:0\"\n",
        gcud.clients()
    ));
    let metrics = format!("127.0.0.1:{}", onvif.port("metrics at /metrics"));
    let device = format!("http://127.0.0.1:{}", onvif.port("gimbal=mast-1 addr="));
    let soap = [("Content-Type", "application/soap+xml; charset=utf-8")];
    let (status, answer) = raw(
        &device,
        "POST",
        "/onvif/device_service",
        &soap,
        &envelope("<tds:GetSystemDateAndTime/>"),
    );
    assert_eq!(status, 200, "{answer}");
    // Unsigned, and an operation no device has: faults, whatever their names.
    for body in ["<tds:GetDeviceInformation/>", "<tds:NoSuchOperationAnywhere/>"] {
        let (status, answer) = raw(&device, "POST", "/onvif/device_service", &soap, &envelope(body));
        assert_ne!(status, 200, "{body}: {answer}");
    }
    let door = "door=\"gimbal-onvif\"";
    let delivered = format!("sagebrush_door_bus_outcomes_total{{{door},outcome=\"delivered\"}}");
    eventually("the session's polls of mast-1 counted as delivered", || {
        sample(&support::http_get(&metrics, "/metrics"), &delivered) >= Some(1.0)
    });
    let scrape = support::http_get(&metrics, "/metrics");
    let asked = |kind: &str| {
        sample(
            &scrape,
            &format!("sagebrush_door_requests_total{{{door},kind=\"{kind}\"}}"),
        )
    };
    assert_eq!(asked("GetSystemDateAndTime"), Some(1.0), "{scrape}");
    assert_eq!(asked("fault"), Some(2.0), "{scrape}");
    assert!(
        !scrape.contains("NoSuchOperation"),
        "a client's name became a label:\n{scrape}"
    );
    assert!(
        sample(&scrape, &format!("sagebrush_door_sessions{{{door}}}")).is_some(),
        "{scrape}"
    );
}
