//! The launcher: what it prints answers, each door is its own link of
//! gcud, and a signal stops everything it started.

use super::*;

#[test]
fn the_demo_launcher_prints_addresses_that_answer_and_ctrl_c_leaves_nothing_behind() {
    let mut demo = Demo::start(1);
    let printed = demo.printed();
    let logs = || demo.logs();

    // The web page, and a sign-in with the login it prints.
    let web = line_with(&printed, "The web page: http://127.0.0.1:");
    let port = number_after(web, "http://127.0.0.1:");
    assert_eq!(port, demo.port(8080), "{web}");
    let page = support::door::plain_raw(
        &format!("127.0.0.1:{port}"),
        "GET / HTTP/1.1\r\nHost: demo\r\nConnection: close\r\n\r\n",
    );
    assert!(page.starts_with("HTTP/1.1 200") && page.contains("<html"), "{page}");
    let (user, password) = logins(web).into_iter().next().expect("a login");
    let body = json!({ "user": user, "password": password }).to_string();
    let signed = support::door::plain_raw(
        &format!("127.0.0.1:{port}"),
        &format!(
            "POST /api/sign-in HTTP/1.1\r\nHost: demo\r\nContent-Type: application/json\r\nContent-Length: {}\r\nConnection: close\r\n\r\n{body}",
            body.len()
        ),
    );
    assert!(
        signed.starts_with("HTTP/1.1 200"),
        "sign-in as {user}: {signed}\n{}",
        logs()
    );

    // Each ONVIF camera, through the ONVIF client, as an operator it prints.
    let onvif_users = logins(line_with(&printed, "ONVIF PTZ cameras"));
    let (user, password) = onvif_users.iter().find(|(u, _)| u == "vms").expect("the vms login");
    if support::door::onvif_client_available() {
        for (n, address) in ["5.1.1", "5.1.2", "5.2.1"].iter().enumerate() {
            let line = line_with(&printed, &format!("({address}): http://127.0.0.1:"));
            let port = number_after(line, "http://127.0.0.1:");
            assert_eq!(port, demo.port(8081 + n as u16), "{line}");
            let info = support::door::python_step(
                "tests/onvif/client.py",
                "info",
                &["127.0.0.1", &port.to_string(), user, password, "{}"],
                logs,
            );
            assert_eq!(info["device"]["ok"]["Manufacturer"], "Sagebrush", "{address}: {info}");
        }
    }

    // Each MAVLink gimbal manager's heartbeat, through pymavlink.
    let mavlink = line_with(&printed, "UDP 127.0.0.1:");
    let port = number_after(mavlink, "UDP 127.0.0.1:");
    assert_eq!(port, demo.port(14560), "{mavlink}");
    if support::door::mavlink_client_available() {
        let components = line_with(&printed, "MAVLink gimbal managers");
        for name in ["mast-1", "mast-2", "roof"] {
            let id: u16 = components
                .split(", ")
                .find(|c| c.ends_with(name) || c.trim_end_matches("):").ends_with(name))
                .and_then(|c| c.split_whitespace().rev().nth(1)?.parse().ok())
                .unwrap_or_else(|| panic!("no component for {name} in {components}"));
            let beat = support::door::python_step(
                "tests/mavlink/gcs.py",
                "heartbeat",
                &[&port.to_string(), "255", "190", &json!({ "component": id }).to_string()],
                logs,
            );
            assert_eq!(beat["heartbeat"]["type"], 26, "{name} (component {id}): {beat}");
        }
    }

    // Each gimbalctl line it prints, as printed.
    let ctl_lines: Vec<&str> = printed.lines().filter(|l| l.contains("gimbalctl ")).collect();
    assert!(ctl_lines.len() >= 3, "{printed}");
    for line in ctl_lines {
        let (code, out) = shell(line.trim(), &[]);
        assert_eq!(code, 0, "the printed line `{}`: {out}\n{}", line.trim(), logs());
    }

    // Every door it starts on its own link of gcud (named after it),
    // connected.
    let doors = demo.doors();
    for door in [
        "gimbal-onvif",
        "gimbal-mavlink",
        "gimbal-web",
        "gimbal-visca",
        "gimbal-pelco",
    ] {
        assert!(doors.iter().any(|d| d == door), "{door} is not among {doors:?}");
    }
    let status = demo.status();
    let links = status["links"].as_array().expect("links");
    for door in &doors {
        let link = links
            .iter()
            .find(|l| l["link"] == door.as_str())
            .unwrap_or_else(|| panic!("no link {door} in {status}"));
        assert!(link["connections"].as_u64() > Some(0), "{door}: {link}\n{}", logs());
    }

    // Ctrl-C: every program stops, the folder goes, the ports are free.
    let programs = demo.leftovers();
    assert!(
        programs.len() >= 2 + doors.len(),
        "the launcher, gcud and {doors:?}: {programs:?}"
    );
    let status = demo.signal(Signal::SIGINT, true);
    assert_eq!(status.code(), Some(0), "{status}\n{}", demo.printed());
    demo.assert_nothing_left();
}

/// SIGTERM to the launcher alone (a supervisor's stop, `kill PID`): the
/// programs get no signal of their own, the launcher stops each.
#[test]
fn sigterm_to_the_launcher_alone_stops_every_program_it_started() {
    let mut demo = Demo::start(2);
    let programs = demo.leftovers();
    let doors = demo.doors();
    assert!(
        programs.len() >= 2 + doors.len(),
        "the launcher, gcud and {doors:?}: {programs:?}"
    );
    let status = demo.signal(Signal::SIGTERM, false);
    assert_eq!(status.code(), Some(0), "{status}\n{}", demo.printed());
    demo.assert_nothing_left();
}
