//! The doors' own third-party clients at the addresses the launcher
//! prints, each moving one of the demo's gimbals (each its own, so that
//! gcud's control of one by a door does not refuse another): a real
//! browser on the web page, the PyPI `visca-over-ip` camera client on a
//! VISCA camera, the PyPI `pyptzcontroller` keyboard on the Pelco-D port
//! through a serial server. Each move is read where it lands: the
//! gimbal's position through gcud (gimbalctl on the printed client link)
//! and gcud's record that the door's own link asked for it.

use std::path::PathBuf;

use support::browser::{Browser, browser_available};

use super::*;

/// The web page at its printed URL in chromium, signed in with the first
/// login printed: a card for each of the demo's gimbals, and "Pan right"
/// held on `address`'s card moves that gimbal on the bus until released.
fn browser_moves(demo: &Demo, address: &str) -> Browser {
    let printed = demo.printed();
    let web = line_with(&printed, "The web page: http://127.0.0.1:");
    let url = web
        .split_whitespace()
        .find(|w| w.starts_with("http://"))
        .expect("the page's URL");
    let (user, password) = logins(web).into_iter().next().expect("a login");
    let logs = || demo.log("gimbal-web");
    let mut b = Browser::start();
    b.call(json!({ "op": "open", "url": url }), logs);
    b.call(json!({ "op": "sign_in", "user": user, "password": password }), logs);
    let gimbals = demo.gimbals();
    let mut expect: Vec<&str> = gimbals.iter().map(|(name, _)| name.as_str()).collect();
    expect.push("Tours");
    let shown = b.call(json!({ "op": "card_names", "expect": expect }), logs);
    for (name, _) in &gimbals {
        assert!(
            shown.as_array().is_some_and(|s| s.contains(&json!(name))),
            "no card {name} on the page signed in as {user}: {shown}"
        );
    }
    let card = &gimbals.iter().find(|(_, a)| a == address).expect("the gimbal").0;
    let from = demo.settled(address);
    b.call(json!({ "op": "hold", "card": card, "button": "Pan right" }), logs);
    demo.wait(&format!("{address} to pan right while held"), || {
        demo.position(address).0 > from.0 + 1.0
    });
    let accepted = demo.wait_accepted("gimbal-web", "pan right", address);
    b.call(json!({ "op": "release" }), logs);
    let at = demo.settled(address);
    assert!(at.0 > from.0 + 1.0 && at.1 == from.1, "{address}: {from:?} -> {at:?}");
    eprintln!("browser on {url} as {user}: cards {shown}; {address} {from:?} -> {at:?}; gcud: {accepted}");
    b
}

/// The VISCA over IP camera of `address` at its printed address, through
/// the PyPI client: an absolute move, read on the bus, then the position
/// inquiry answered in VISCA's units.
fn visca_moves(demo: &Demo, address: &str) {
    if !support::door::python_client_available("visca_over_ip", "visca-over-ip") {
        return;
    }
    let printed = demo.printed();
    let line = line_with(&printed, &format!("({address}): VISCA over IP udp "));
    let camera = line
        .split_once("udp ")
        .and_then(|(_, r)| r.split_once(','))
        .expect("the camera's address")
        .0;
    let (host, port) = camera.split_once(':').expect("HOST:PORT");
    let step = |step: &str, args: &[&str]| {
        let mut all = vec![host, port];
        all.extend_from_slice(args);
        support::door::python_step("tests/visca/client.py", step, &all, || demo.logs())
    };
    // 0.075° a step (gimbal-visca's default): 30°, -15°.
    let sent = step("absolute", &["400", "-200"]);
    assert_eq!(sent["ok"], true, "{camera}: {sent}");
    let accepted = demo.wait_accepted("gimbal-visca", "go to pan 30.00° tilt -15.00°", address);
    demo.wait(&format!("{address} at 30°, -15°"), || {
        let (pan, tilt) = demo.settled(address);
        (pan - 30.0).abs() < 0.2 && (tilt + 15.0).abs() < 0.2
    });
    // The door answers from what it last polled: asked until it agrees.
    demo.wait(&format!("the camera {camera} to read 400, -200"), || {
        let read = step("position", &[]);
        (read["pan"].as_i64(), read["tilt"].as_i64()) == (Some(400), Some(-200))
    });
    eprintln!("visca-over-ip on {camera}: {address} at 30°, -15°, read back 400, -200; gcud: {accepted}");
}

/// A serial device server, as a DVR's RS-485 keyboard line reaches a
/// Pelco-D TCP port: a fresh pseudo-terminal (`path`, the keyboard's
/// serial port) whose bytes go both ways over one TCP connection.
struct SerialServer {
    path: PathBuf,
    _relay: tokio::runtime::Runtime,
}

impl SerialServer {
    fn connect(addr: &str) -> Self {
        let relay = tokio::runtime::Builder::new_multi_thread()
            .worker_threads(1)
            .enable_all()
            .build()
            .expect("runtime");
        let path = relay.block_on(async {
            let mut line = sagebrush_host::pty::PtyMaster::open().expect("pty");
            let path = line.slave_path().to_owned();
            let mut tcp = tokio::time::timeout(HANG_GUARD, tokio::net::TcpStream::connect(addr))
                .await
                .unwrap_or_else(|_| panic!("connect to {addr} in time"))
                .unwrap_or_else(|e| panic!("connect to {addr}: {e}"));
            tokio::spawn(async move {
                let _ = tokio::io::copy_bidirectional(&mut line, &mut tcp).await;
            });
            path
        });
        Self { path, _relay: relay }
    }
}

/// The Pelco-D port as printed: its port, and the address of the gimbal
/// printed as camera 1 ("cameras 1 NAME"), the one the keyboard drives.
fn pelco_port(demo: &Demo) -> (u16, String) {
    let printed = demo.printed();
    let line = line_with(&printed, "Pelco-D keyboards");
    let cameras = line.split_once(", cameras ").map_or("", |(_, r)| r);
    let name = cameras
        .split(", ")
        .find_map(|c| c.strip_prefix("1 "))
        .unwrap_or_else(|| panic!("no camera 1 in {line}"));
    let gimbals = demo.gimbals();
    let address = gimbals
        .iter()
        .find(|(n, _)| n == name)
        .expect("camera 1's gimbal")
        .1
        .clone();
    (number_after(line, "tcp 127.0.0.1:"), address)
}

/// The Pelco-D port at its printed address, through a serial server, with
/// the pyptzcontroller keyboard (camera 1, at `address`): a pan right
/// held, read on the bus, then the position queries answered.
fn pelco_moves(demo: &Demo, port: u16, address: &str) {
    if !support::door::python_client_available("ptz_control_lib", "pyptzcontroller") {
        return;
    }
    let server = SerialServer::connect(&format!("127.0.0.1:{port}"));
    let serial = server.path.display().to_string();
    let step = |step: &str, args: &[&str]| {
        let mut all = vec![serial.as_str()];
        all.extend_from_slice(args);
        support::door::python_step("tests/pelco/client.py", step, &all, || demo.logs())
    };
    // A keyboard's stick held right half a second, then its stop (an
    // absolute move, `move_to`, is left to tests/pelco: gimbal-pelco
    // loses one of a pan and tilt pair at times, an open defect).
    let from = demo.settled(address);
    step("hold", &["right", "20", "0.5"]);
    let accepted = demo.wait_accepted("gimbal-pelco", "pan right", address);
    step("stop", &[]);
    let at = demo.settled(address);
    assert!(at.0 > from.0 + 1.0 && at.1 == from.1, "{address}: {from:?} -> {at:?}");
    // The door answers from what it last polled: asked until it agrees.
    let mut asked = Value::Null;
    demo.wait(&format!("the keyboard to read {at:?}"), || {
        asked = step("position", &[]);
        let (pan, tilt) = (asked["pan"].as_f64(), asked["tilt"].as_f64());
        pan.is_some_and(|p| (p - at.0).abs() < 0.02) && tilt.is_some_and(|t| (t - at.1).abs() < 0.02)
    });
    eprintln!(
        "pyptzcontroller via {serial} to port {port}: {address} {from:?} -> {at:?}, read back {asked}; gcud: {accepted}"
    );
}

#[test]
fn the_doors_own_clients_move_the_demos_gimbals_at_the_printed_addresses() {
    let mut demo = Demo::start(3);
    // The keyboard drives camera 1; the browser and the VISCA client each
    // another gimbal.
    let (port, keyboards) = pelco_port(&demo);
    let others: Vec<String> = demo
        .gimbals()
        .into_iter()
        .map(|(_, a)| a)
        .filter(|a| *a != keyboards)
        .collect();
    pelco_moves(&demo, port, &keyboards);
    let browser = browser_available().then(|| browser_moves(&demo, &others[0]));
    visca_moves(&demo, &others[1]);
    // Ctrl-C with the page still open: everything stops all the same.
    let status = demo.signal(Signal::SIGINT, true);
    assert_eq!(status.code(), Some(0), "{status}\n{}", demo.printed());
    demo.assert_nothing_left();
    drop(browser);
}
