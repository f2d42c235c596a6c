//! gcud's life as a service: bad configurations exit 2 naming the problem,
//! SIGTERM shuts down gracefully and quietly, SIGHUP reloads the
//! difference and refuses broken files, `--check --against`.

use super::*;

/// Bad configuration files: each gives its specific message and exit code 2.
#[test]
fn bad_configs_name_the_problem_and_exit_2() {
    let dir = tempfile::tempdir().expect("temp dir");
    let cases: &[(&str, &str, &str)] = &[
        (
            "[gcu]\ngroup = 300\n",
            ":2:9: gcu.group",
            "expected an integer 1..=254, found 300",
        ),
        (
            "[gcu]\ngroup = 5\n[[port]]\nid = 1\npath = \"/dev/x\"\nbaud = 9601\n",
            ":6:8: port[0].baud",
            "115200",
        ),
        (
            "[gcu]\ngroup = 5\n[[port]]\nid = 1\npaht = \"/dev/x\"\n",
            ":5:1",
            "unknown field `paht`",
        ),
        (
            "[gcu]\ngroup = 5\n[[port]]\nid = 1\npath = \"/a\"\n[[port]]\nid = 1\npath = \"/b\"\n",
            ":7:6: port[1].id",
            "configured twice",
        ),
        (
            "[gcu]\ngroup = 5\n[[route]]\ngroup = 7\nlink = \"up\"\n",
            ":5:8: route[0].link",
            "no link is named \"up\"",
        ),
        (
            "[gcu]\ngroup = 5\n[[link]]\nname = \"c\"\nrole = \"client\"\nlisten = \"localhost\"\n",
            ":6:10: link[0].listen",
            "expected an IP address and port",
        ),
        ("[gcu\ngroup = 5\n", ":1:5", "unclosed table, expected `]`"),
        ("[gcu]\n", ":1:1: gcu", "missing field `group`"),
    ];
    for (i, (text, place, message)) in cases.iter().enumerate() {
        let path = dir.path().join(format!("bad{i}.toml"));
        std::fs::write(&path, text).expect("write");
        for check in [true, false] {
            let mut cmd = Command::new(env!("CARGO_BIN_EXE_gcud"));
            if check {
                cmd.arg("--check");
            }
            let out = cmd.arg("--config").arg(&path).output().expect("run gcud");
            let stderr = String::from_utf8_lossy(&out.stderr);
            assert_eq!(out.status.code(), Some(2), "case {i} ({text:?}): {stderr}");
            let expected_place = format!("{}{place}", path.display());
            assert!(
                stderr.contains(&expected_place),
                "case {i}: {stderr:?} should contain {expected_place:?}"
            );
            assert!(
                stderr.contains(message),
                "case {i}: {stderr:?} should contain {message:?}"
            );
        }
    }
    let missing = dir.path().join("missing.toml");
    let out = Command::new(env!("CARGO_BIN_EXE_gcud"))
        .arg("--check")
        .arg("--config")
        .arg(&missing)
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&out.stderr).contains("cannot read"));
}

/// SIGTERM with a transaction in flight: gcud lets it finish (its client
/// gets the result it asked for), says so, and exits 0. The test plays the
/// gimbal on a TCP port and holds the result back until gcud has logged
/// that it is shutting down: the command was provably in flight at SIGTERM.
#[test]
fn sigterm_shuts_down_gracefully() {
    let bus = std::net::TcpListener::bind("127.0.0.1:0").expect("bind the device server");
    let addr = bus.local_addr().expect("address");
    let mut gcud = Gcud::start(&format!(
        "[gcu]\ngroup = 5\nshutdown_grace_ms = 60000\n{CLIENTS}[[port]]\nid = 1\ntcp = \"{addr}\"\n\
         ack_timeout_ms = 10000\nresult_timeout_ms = 30000\n[link_timing]\ndelivery_timeout_ms = 30000\n"
    ));
    let (mut line, _) = bus.accept().expect("gcud connects to its port");
    line.set_read_timeout(Some(HANG_GUARD)).expect("timeout");
    let clients = gcud.clients();
    let client = std::thread::spawn(move || {
        support::gimbalctl(&[
            "--json",
            "--tcp",
            &clients,
            "--to",
            "5.1.1",
            "--result-timeout",
            "30000",
            "position",
        ])
    });
    // The P? reaches the gimbal; it is ACKed, its result not yet sent.
    let mut framer: Framer = Framer::new();
    let mut command = None;
    while command.is_none() {
        let mut buf = [0u8; 64];
        let n = line.read(&mut buf).expect("gcud writes the P?");
        assert!(n > 0, "gcud closed its port");
        framer.feed(&buf[..n], |e| {
            if let Event::Frame(f) = e {
                command = Some(FrameBuf::from_frame(&f));
            }
        });
    }
    let command = command.expect("a frame");
    assert_eq!(command.frame().payload(), b"P?");
    line.write_all(&[ACK]).expect("ACK the P?");
    let pid = nix::unistd::Pid::from_raw(gcud.child.id() as i32);
    nix::sys::signal::kill(pid, nix::sys::signal::Signal::SIGTERM).expect("SIGTERM");
    gcud.wait_for_log("shutting down");
    assert!(
        matches!(gcud.child.try_wait(), Ok(None)),
        "gcud exited with the P? in flight:\n{}",
        gcud.log()
    );
    let result = Reply::Position(Position::new(
        sagebrush_protocol::Angle::from_centidegrees(1250),
        sagebrush_protocol::Angle::from_centidegrees(-300),
    ));
    line.write_all(&support::cli::reply_frame(&command.frame(), &result))
        .expect("the result");
    let out = client.join().expect("client thread");
    let started = Instant::now();
    let status = loop {
        if let Some(status) = gcud.child.try_wait().expect("wait for gcud") {
            break status;
        }
        assert!(started.elapsed() < HANG_GUARD, "gcud never exited:\n{}", gcud.log());
        std::thread::sleep(Duration::from_millis(20));
    };
    let log = gcud.log();
    assert_eq!(out.code, 0, "the command in flight finished: {out:?}\n{log}");
    let v = out.json();
    assert_eq!(
        (v["outcome"].as_str(), v["result"]["pan_deg"].as_f64()),
        (Some("result"), Some(12.5)),
        "the client got the result sent after SIGTERM: {v}"
    );
    assert!(status.success(), "exit status {status:?}\n{log}");
    let shutting = log.find("shutting down").expect("logged");
    let finished = log
        .find("in-flight transactions finished")
        .unwrap_or_else(|| panic!("{log}"));
    assert!(shutting < finished, "{log}");
}

/// SIGHUP: an unchanged file disturbs nothing, an added and a changed port
/// are applied (a slew on the changed one is stopped first), a broken or
/// missing file is refused with its file:line and the daemon keeps running;
/// meanwhile a P? loop on port 1 never misses.
#[test]
fn sighup_reloads_the_difference_and_refuses_broken_files() {
    let sim1 = Sim::pty(&["--device", "1"]);
    let sim2 = Sim::pty(&["--device", "1", "--rate", "10"]);
    let sim3 = Sim::pty(&["--device", "1"]);
    let base = format!("[gcu]\ngroup = 5\n{CLIENTS}{}", port_entry(1, &sim1));
    let gcud = Gcud::start(&base);
    gcud.wait_for_log("port open port=1");

    let stop = std::sync::Arc::new(std::sync::atomic::AtomicBool::new(false));
    let clients = gcud.clients();
    let poller = {
        let stop = stop.clone();
        std::thread::spawn(move || {
            let (mut ok, mut failed) = (0u32, Vec::new());
            let started = Instant::now();
            while !stop.load(std::sync::atomic::Ordering::Relaxed) && started.elapsed() < HANG_GUARD * 4 {
                let out = support::gimbalctl(&["--tcp", &clients, "--to", "5.1.1", "position"]);
                match out.code {
                    0 => ok += 1,
                    _ => failed.push(out),
                }
            }
            (ok, failed)
        })
    };

    gcud.reload(Some(&base), 1, "configuration unchanged");
    let with2 = format!("{base}{}", port_entry(2, &sim2));
    gcud.reload(Some(&with2), 2, "reload: port 2: added");
    gcud.wait_for_log("port open port=2");
    let start = gcud.position("5.2.1");

    let broken = format!("{with2}[[port]]\nid = \"three\"\n");
    gcud.reload(Some(&broken), 3, "reload refused");
    let refused = gcud
        .log()
        .lines()
        .find(|l| l.contains("reload refused"))
        .unwrap_or_default()
        .to_owned();
    assert!(
        refused.contains("gcud.toml:") && refused.contains("port[2].id"),
        "{refused}"
    );
    gcud.reload(None, 4, "reload refused");

    // Port 2 moves to another bus while its gimbal slews: stopped first.
    let mut client = WireClient::connect(&gcud.clients());
    client.send(Address::new(5, 2, 1), 0, &Cmd::PanRight);
    assert_eq!(client.next(), OwnedEvent::Ack);
    eventually("the slew to move the gimbal", || gcud.position("5.2.1").0 > start.0);
    let moved = format!("{base}{}", port_entry(2, &sim3));
    gcud.reload(Some(&moved), 5, "reload: port 2: changed");
    gcud.wait_for_log("port closed (configuration reloaded)");
    assert!(gcud.log().contains("dead-man PS to 5.2.1"), "{}", gcud.log());
    let first = sim2.position();
    std::thread::sleep(Duration::from_millis(300));
    assert_eq!(sim2.position(), first, "the old bus's gimbal was stopped");
    eventually("port 2 on its new bus", || {
        gcud.ctl(&["--to", "5.2.1", "position"]).code == 0
    });

    stop.store(true, std::sync::atomic::Ordering::Relaxed);
    let (ok, failed) = poller.join().expect("poller");
    assert!(ok >= 3, "the P? loop ran ({ok})");
    assert!(failed.is_empty(), "the P? loop on port 1 missed: {failed:?}");
    drop(client);
}

/// `--check --against`: what a reload would change, without applying it.
#[test]
fn check_against_prints_what_a_reload_would_change() {
    let dir = tempfile::tempdir().expect("temp dir");
    let old = dir.path().join("old.toml");
    let new = dir.path().join("new.toml");
    // A client link: a GCU without links routes nothing and is refused.
    let head = format!("[gcu]\ngroup = 5\n{CLIENTS}[[port]]\nid = 1\nsimulate = [1]\n");
    std::fs::write(&old, format!("{head}[[port]]\nid = 2\nsimulate = [1]\n")).expect("write");
    std::fs::write(&new, format!("{head}[[port]]\nid = 3\nsimulate = [1]\n")).expect("write");
    let run = |a: &Path, b: &Path| {
        Command::new(env!("CARGO_BIN_EXE_gcud"))
            .args(["--check", "--config"])
            .arg(a)
            .arg("--against")
            .arg(b)
            .output()
            .expect("run gcud --check")
    };
    let out = run(&new, &old);
    let text = String::from_utf8_lossy(&out.stdout);
    assert_eq!(out.status.code(), Some(0), "{text}");
    assert!(
        text.contains("port 3: added") && text.contains("port 2: removed"),
        "{text}"
    );
    assert!(!text.contains("port 1"), "port 1 did not change: {text}");
    std::fs::write(&new, head.replace("group = 5", "group = 6")).expect("write");
    let out = run(&new, &old);
    assert_eq!(out.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&out.stdout).contains("gcu.group: changed; needs a restart"));
}

/// A clean SIGTERM is not a loss: the ports and links that end with it log
/// at info or below, never WARN; a port lost while running stays a WARN.
#[test]
fn clean_sigterm_logs_no_warning() {
    // A real loss while running: the device end of the port goes away.
    let lost = Sim::pty(&[]);
    let gcud = Gcud::start(&format!("[gcu]\ngroup = 5\n{CLIENTS}{}", port_entry(1, &lost)));
    gcud.wait_for_log("port open port=1");
    drop(lost);
    let line = gcud.wait_for_log("port lost");
    assert!(line.contains("WARN"), "{line}");
    drop(gcud);

    let sim = Sim::pty(&[]);
    let gcud = Gcud::start(&format!("[gcu]\ngroup = 5\n{CLIENTS}{}", port_entry(1, &sim)));
    gcud.wait_for_log("port open port=1");
    assert_eq!(gcud.ctl(&["--to", "5.1.1", "position"]).code, 0);
    // A client connection still open when the signal comes.
    let held = TcpStream::connect(gcud.clients()).expect("connect");
    eventually("the held connection to be up", || {
        gcud.log().lines().filter(|l| l.contains("client connected")).count() == 2
    });
    let (status, log) = gcud.terminate();
    drop(held);
    assert!(status.is_some_and(|s| s.success()), "exit status {status:?}\n{log}");
    let after = log
        .split_once("shutting down")
        .map(|(_, after)| after)
        .unwrap_or_else(|| panic!("no \"shutting down\" line:\n{log}"));
    // The port's end is logged (so a WARN for it would be seen), at info.
    let ended = after
        .lines()
        .find(|l| l.contains("port=1") && !l.contains("port open"))
        .unwrap_or_else(|| panic!("the port's end is not logged after \"shutting down\":\n{log}"));
    assert!(ended.contains("INFO"), "{ended}");
    let warnings: Vec<&str> = after
        .lines()
        .filter(|l| l.contains("WARN") || l.contains("ERROR"))
        .collect();
    assert!(
        warnings.is_empty(),
        "a clean shutdown warned: {warnings:#?}\nlog:\n{log}"
    );
}
