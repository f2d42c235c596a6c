//! The door's connection to the broker: its last will when it dies, a
//! restarted broker (reconnect, republish), a cut uplink (nothing
//! published meanwhile runs later), retained commands never run.

use std::time::{Duration, Instant};

use super::*;
use support::door::assert_still;

#[test]
fn killing_the_door_turns_the_site_offline_within_the_keep_alive() {
    let Some(broker) = Broker::start() else { return };
    let mut site = Site::start(&broker, "north");
    let status = "sagebrush/north/status";
    assert_eq!(broker.step("retained", &[status], || site.logs())["message"], "online");
    // A subscriber from before the kill sees the broker's last will.
    let (r, after_kill) = std::thread::scope(|s| {
        let watch = s.spawn(|| broker.step("wait_for", &[status, "offline", "60"], String::new));
        std::thread::sleep(Duration::from_millis(2000));
        site.door.signal(nix::sys::signal::Signal::SIGKILL);
        let killed = Instant::now();
        let r = watch.join().expect("watch");
        (r, killed.elapsed())
    });
    assert_eq!(r["arrived"], true, "no offline: {r}\n{}", broker.log());
    // keep_alive_s = 5: the broker says the will within 1.5 keep-alives
    // of a dead peer; a killed process's socket closes at once.
    eprintln!("offline seen {after_kill:?} after the kill");
    assert!(after_kill < Duration::from_millis(7500), "{after_kill:?}");
}

#[test]
fn a_stopped_door_says_offline_and_stops_what_it_started() {
    let Some(broker) = Broker::start() else { return };
    let mut site = Site::start(&broker, "north");
    let r = site.command(&broker, "mast", r#"{"slew": {"pan": 0.5, "lease_ms": 5000}}"#);
    assert_eq!(r["ok"], true, "{r}");
    support::door::wait_moving(&site.gcud, MAST, (0.0, 0.0));
    let status = site.door.signal(nix::sys::signal::Signal::SIGTERM);
    assert!(status.success(), "{status:?}\n{}", site.logs());
    assert_eq!(
        broker.step("retained", &["sagebrush/north/status"], || site.logs())["message"],
        "offline"
    );
    support::door::wait_for_stop(&site.gcud, MAST, DOOR_GROUP, "PS");
}

#[test]
fn a_restarted_broker_gets_everything_again_and_nothing_runs_late() {
    let Some(mut broker) = Broker::start() else { return };
    let site = Site::start(&broker, "north");
    broker.restart();
    // persistence off: the restarted broker knew no retained message; the
    // door connected again and published its status and states anew.
    site.wait_online(&broker);
    eventually("the gate's state again", || {
        site.state(&broker, "gate")["online"] == true
    });
    let discovered = broker.step(
        "retained",
        &["homeassistant/button/sagebrush_north_mast/stop/config"],
        || site.logs(),
    );
    assert_eq!(
        discovered["message"]["payload_press"], "{\"stop\": true}",
        "{discovered}"
    );
    let r = site.command(&broker, "mast", r#"{"goto": {"pan_deg": 5.0, "tilt_deg": 5.0}}"#);
    assert_eq!(r["ok"], true, "{r}");
    wait_at(&site.gcud, MAST, 5.0, 5.0);
}

#[test]
fn a_command_published_while_the_door_was_cut_off_never_runs() {
    let Some(broker) = Broker::start() else { return };
    let uplink = Uplink::start(broker.port);
    let site = Site::start_via(&broker, &uplink.url(), "north", "", "");
    let status = "sagebrush/north/status";
    uplink.cut();
    let r = broker.step("wait_for", &[status, "offline", "30"], || site.logs());
    assert_eq!(r["arrived"], true, "no last will after the cut: {r}");
    // Published while the door is away: live (QoS 1) and retained.
    let cmd = format!("{}/cmd", site.base("mast"));
    broker.step(
        "publish",
        &[&cmd, r#"{"goto": {"pan_deg": 40.0, "tilt_deg": 0.0}}"#],
        || site.logs(),
    );
    broker.step(
        "publish",
        &[&cmd, r#"{"goto": {"pan_deg": -40.0, "tilt_deg": 0.0}}"#, "retain"],
        || site.logs(),
    );
    std::thread::sleep(Duration::from_millis(500));
    uplink.restore();
    eventually("the door back online", || {
        broker.step("retained", &[status], || site.logs())["message"] == "online"
    });
    // Over the next seconds neither command reaches the gimbal.
    assert_still(&site.gcud, MAST, (0.0, 0.0), "after the door came back");
    assert_still(&site.gcud, MAST, (0.0, 0.0), "after the door came back");
    assert!(site.door_motions(MAST).is_empty(), "{:?}", site.door_frames(MAST));
    // The door works: a command published now runs.
    let r = site.command(&broker, "mast", r#"{"goto": {"pan_deg": 3.0, "tilt_deg": 0.0}}"#);
    assert_eq!(r["ok"], true, "{r}");
    wait_at(&site.gcud, MAST, 3.0, 0.0);
}

#[test]
fn a_retained_command_on_the_broker_never_runs_at_start() {
    let Some(broker) = Broker::start() else { return };
    let cmd = "sagebrush/north/mast/cmd";
    broker.step(
        "publish",
        &[cmd, r#"{"goto": {"pan_deg": 30.0, "tilt_deg": 0.0}}"#, "retain"],
        String::new,
    );
    let results = std::thread::scope(|s| {
        let watch = s.spawn(|| broker.step("collect", &["sagebrush/north/mast/result", "8"], String::new));
        std::thread::sleep(Duration::from_millis(1500));
        let site = Site::start(&broker, "north");
        let results = watch.join().expect("collect");
        assert_still(&site.gcud, MAST, (0.0, 0.0), "with a retained command on the broker");
        assert!(site.door_motions(MAST).is_empty(), "{:?}", site.door_frames(MAST));
        results
    });
    let reasons: Vec<String> = results["messages"]
        .as_array()
        .expect("messages")
        .iter()
        .map(|m| m["payload"]["reason"].as_str().unwrap_or_default().to_owned())
        .collect();
    assert!(
        reasons.iter().any(|r| r.contains("a retained command is never run")),
        "{reasons:?}"
    );
}

#[test]
fn mqtt_3_1_1_works_and_a_packet_over_the_limit_costs_a_reconnection() {
    let Some(broker) = Broker::start() else { return };
    let site = Site::start_with(&broker, "north", "", "version = \"3.1.1\"");
    let r = site.command(&broker, "mast", r#"{"goto": {"pan_deg": 8.0, "tilt_deg": 2.0}}"#);
    assert_eq!(r["ok"], true, "{r}");
    wait_at(&site.gcud, MAST, 8.0, 2.0);
    // 3.1.1 has no Maximum Packet Size: the door closes the connection
    // before reading a packet over 256 KiB, and connects again.
    broker.step("huge", &[&format!("{}/cmd", site.base("mast")), "400000"], || {
        site.logs()
    });
    support::wait_for_log_line(&site.door.log_path(), "lost the broker");
    site.wait_online(&broker);
    assert!(site.door_motions(MAST).iter().filter(|p| is_goto(p)).count() == 1);
    let r = site.command(&broker, "mast", r#"{"home": true}"#);
    assert_eq!(r["ok"], true, "{r}");
    wait_at(&site.gcud, MAST, 0.0, 0.0);
}

#[test]
fn over_mqtts_with_a_client_certificate() {
    let certs = tempfile::tempdir().expect("temp dir");
    support::tls_init(certs.path(), &["door"]);
    let file = |name: &str| certs.path().join(name).display().to_string();
    // gcud's certificate (127.0.0.1 among its names) serves as the broker's.
    let tls_port = std::net::TcpListener::bind("127.0.0.1:0")
        .expect("a free port")
        .local_addr()
        .expect("port")
        .port();
    let tls = format!(
        "listener {tls_port} 127.0.0.1\ncafile {}\ncertfile {}\nkeyfile {}\nrequire_certificate true\n",
        file("ca.crt"),
        file("gcud.crt"),
        file("gcud.key")
    );
    let Some(broker) = Broker::start_with(&tls) else { return };
    let gcud = support::door::start_governed_gcud();
    let url = format!("mqtts://127.0.0.1:{tls_port}");
    let keys = format!(
        "ca = \"{}\"\nclient_cert = \"{}\"\nclient_key = \"{}\"",
        file("ca.crt"),
        file("door.crt"),
        file("door.key")
    );
    let mut door = Door::new("gimbal-mqtt", env!("CARGO_BIN_EXE_gimbal-mqtt"));
    door.start(&door_config(&gcud, &url, "north", "", &keys));
    support::wait_for_log_line(&door.log_path(), "connected to the broker");
    // Commanded through the broker's plain listener, moved on the bus.
    let site = Site {
        gcud,
        door,
        name: "north".to_owned(),
    };
    site.wait_online(&broker);
    let r = site.command(&broker, "mast", r#"{"goto": {"pan_deg": 9.0, "tilt_deg": 0.0}}"#);
    assert_eq!(r["ok"], true, "{r}");
    wait_at(&site.gcud, MAST, 9.0, 0.0);
    // Without its certificate the broker refuses the door, which says so.
    let mut refused = Door::new("gimbal-mqtt", env!("CARGO_BIN_EXE_gimbal-mqtt"));
    let ca_only = format!("ca = \"{}\"\nclient_id = \"other\"", file("ca.crt"));
    refused.start(&door_config(&site.gcud, &url, "south", "", &ca_only));
    support::wait_for_log_line(&refused.log_path(), "cannot connect to the broker");
    assert!(!refused.log().contains("connected to the broker"), "{}", refused.log());
}

#[test]
fn home_assistant_back_online_gets_the_discovery_again() {
    let Some(broker) = Broker::start() else { return };
    let site = Site::start(&broker, "north");
    let config = "homeassistant/number/sagebrush_north_mast/pan/config";
    eventually("the pan number's discovery", || {
        broker.step("retained", &[config], || site.logs())["message"]["command_topic"] == "sagebrush/north/mast/cmd"
    });
    // A Home Assistant that lost its entities (the retained config
    // cleared), then announces itself.
    broker.step("publish", &[config, "", "retain"], || site.logs());
    assert_eq!(
        broker.step("retained", &[config], || site.logs())["message"],
        Value::Null
    );
    broker.step("publish", &["homeassistant/status", "online"], || site.logs());
    eventually("the discovery published again", || {
        broker.step("retained", &[config], || site.logs())["message"]["command_topic"] == "sagebrush/north/mast/cmd"
    });
}
