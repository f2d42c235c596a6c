use super::*;

const GOOD: &str = r#"
gcud = "127.0.0.1:4001"
system_id = 1
[[endpoint]]
udp_listen = "0.0.0.0:14560"
[[gimbal]]
name = "mast-1"
address = "5.1.1"
component_id = 154
pan_deg = [-170.0, 170.0]
"#;

fn err(text: &str) -> String {
    parse(Path::new("m.toml"), text).unwrap_err().to_string()
}

#[test]
fn a_good_file_and_its_defaults() {
    let c = parse(Path::new("m.toml"), GOOD).unwrap();
    assert_eq!(c.gimbals[0].address, Address::new(5, 1, 1));
    assert_eq!(c.gimbals[0].pan_deg, (-170.0, 170.0));
    assert_eq!(c.gimbals[0].tilt_deg, (-90.0, 90.0));
    assert_eq!(c.gimbals[0].component_id, 154);
    assert_eq!(c.attitude_period, Duration::from_millis(200));
    assert_eq!(c.lease, Duration::from_secs(1));
    assert_eq!(c.endpoints, [Endpoint::UdpListen("0.0.0.0:14560".parse().unwrap())]);
}

#[test]
fn a_serial_endpoint_with_and_without_its_rate() {
    let serial = |extra: &str| {
        let text = GOOD.replace(
            "udp_listen = \"0.0.0.0:14560\"",
            &format!("serial = \"/dev/ttyUSB0\"{extra}"),
        );
        parse(Path::new("m.toml"), &text).unwrap().endpoints
    };
    let at = |baud| Endpoint::Serial {
        path: "/dev/ttyUSB0".into(),
        baud,
    };
    assert_eq!(serial(""), [at(57_600)]);
    assert_eq!(serial("\nbaud = 921600"), [at(921_600)]);
}

#[test]
fn errors_name_the_place_and_what_was_expected() {
    assert_eq!(
        err(&GOOD.replace("\"5.1.1\"", "\"5.1\"")),
        "m.toml:8:11: gimbal[0].address: expected GROUP.PORT.DEVICE of one gimbal, e.g. \"5.1.1\""
    );
    assert!(err(&GOOD.replace("system_id = 1", "system_id = 0")).starts_with("m.toml:3:13: system_id: expected"));
    assert!(err(&GOOD.replace("[-170.0, 170.0]", "[10.0, -10.0]")).starts_with("m.toml:10:11: gimbal[0].pan_deg"));
    assert!(
        err(&GOOD.replace("udp_listen = \"0.0.0.0:14560\"", "udp_listen = \"14560\""))
            .contains("endpoint[0].udp_listen")
    );
    assert!(
        err(&GOOD.replace("udp_listen = \"0.0.0.0:14560\"", "serial = \"/dev/ttyUSB0\"\nbaud = 0"))
            .starts_with("m.toml:6:8: endpoint[0].baud: expected")
    );
    assert!(
        err(&GOOD.replace(
            "udp_listen = \"0.0.0.0:14560\"",
            "udp_listen = \"0.0.0.0:14560\"\nbaud = 9600"
        ))
        .contains("endpoint[0].baud: baud applies to a serial endpoint only")
    );
    assert!(
        err(&GOOD.replace("udp_listen = \"0.0.0.0:14560\"", "tcp = \"gcs\""))
            .contains("endpoint[0].tcp: expected HOST:PORT")
    );
    assert!(err(&format!("{GOOD}colour = 1\n")).contains("colour"));
    assert!(
        err(&format!(
            "{GOOD}[[gimbal]]\nname = \"b\"\naddress = \"5.1.2\"\ncomponent_id = 154\n"
        ))
        .contains("gimbal[1].component_id")
    );
}

#[test]
fn the_mount_place_takes_all_three_keys_and_a_heading_is_per_gimbal() {
    let c = parse(Path::new("m.toml"), GOOD).unwrap();
    assert_eq!((c.mount, c.gimbals[0].mount_heading_deg), (None, None));
    let mast = GOOD.replace(
        "system_id = 1\n",
        "system_id = 1\nmount_latitude_deg = 47.5\nmount_longitude_deg = -8.25\nmount_altitude_m = 480.0\n",
    ) + "mount_heading_deg = 270.0\n";
    let c = parse(Path::new("m.toml"), &mast).unwrap();
    assert_eq!(
        c.mount,
        Some(Place {
            lat_deg: 47.5,
            lon_deg: -8.25,
            alt_m: 480.0
        })
    );
    assert_eq!(c.gimbals[0].mount_heading_deg, Some(270.0));
    assert!(err(&mast.replace("mount_altitude_m = 480.0\n", "")).contains("mount_altitude_m: expected with the other"));
    assert!(
        err(&mast.replace("47.5", "95.0")).starts_with("m.toml:4:22: mount_latitude_deg: expected a number within ±90")
    );
    assert!(err(&mast.replace("270.0", "400.0")).contains("gimbal[0].mount_heading_deg: expected degrees"));
}

const KEY: &str = "3a1f5c0e9b7d2468ace013579bdf2468ace013579bdf2468ace013579bdf2468";

/// GOOD with `[signing]` on the key file `key` (its text), `extra` keys in the section.
fn signed(key: &str, extra: &str) -> (tempfile::TempDir, Result<Config, ConfigError>) {
    use std::os::unix::fs::PermissionsExt;
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("mavlink.key");
    std::fs::write(&path, key).unwrap();
    std::fs::set_permissions(&path, std::fs::Permissions::from_mode(0o600)).unwrap();
    let text = format!("{GOOD}[signing]\nkey_file = {:?}\n{extra}", path.display().to_string());
    let parsed = parse(Path::new("m.toml"), &text);
    (dir, parsed)
}

#[test]
fn signing_takes_a_key_file_of_64_hex_digits_and_names_its_place() {
    let (_dir, c) = signed(&format!("{KEY}\n"), "link_id = 7\n");
    let c = c.unwrap();
    let s = c.signing.expect("signing on");
    assert_eq!((s.key, s.link_id), (Key::parse(KEY).unwrap(), 7));
    assert!(c.notes.is_empty(), "signed, its key file private: {:?}", c.notes);
    let (_dir, c) = signed(KEY, "");
    assert_eq!(c.unwrap().signing.unwrap().link_id, 0, "link_id's default");
    let (_dir, e) = signed("secret passphrase", "");
    let e = e.unwrap_err().to_string();
    assert!(e.starts_with("m.toml:12:12: signing.key_file: "), "{e}");
    assert!(
        e.contains("expected 64 hexadecimal digits") && !e.contains("passphrase"),
        "{e}"
    );
    let (_dir, e) = signed(KEY, "link_id = 256\n");
    assert!(
        e.unwrap_err()
            .to_string()
            .starts_with("m.toml:13:11: signing.link_id: expected")
    );
    let absent = format!("{GOOD}[signing]\nkey_file = \"/no/such/mavlink.key\"\n");
    assert!(
        err(&absent).starts_with("m.toml:12:12: signing.key_file: /no/such/mavlink.key: cannot read"),
        "{}",
        err(&absent)
    );
    assert!(err(&format!("{GOOD}[signing]\n")).contains("key_file"));
}

#[test]
fn check_warns_of_endpoints_off_loopback_without_signing_and_of_a_key_others_may_read() {
    let notes = |endpoint: &str| {
        let text = GOOD.replace("udp_listen = \"0.0.0.0:14560\"", endpoint);
        parse(Path::new("m.toml"), &text).unwrap().notes
    };
    let open = notes("udp_listen = \"0.0.0.0:14560\"");
    assert_eq!(open.len(), 1, "{open:?}");
    assert!(
        open[0]
            .starts_with("m.toml:5:14: endpoint[0].udp_listen: 0.0.0.0:14560 is off loopback and [signing] is not set"),
        "{open:?}"
    );
    for (endpoint, warned) in [
        ("udp_listen = \"127.0.0.1:14560\"", false),
        ("udp_listen = \"127.3.2.1:14560\"", false),
        ("tcp_listen = \"[::1]:5760\"", false),
        ("tcp_listen = \"192.168.1.2:5760\"", true),
        ("udp = \"localhost:14550\"", false),
        ("udp = \"192.168.1.10:14550\"", true),
        ("tcp = \"gcs.example:5760\"", true),
        ("serial = \"/dev/ttyUSB0\"", false),
    ] {
        assert_eq!(!notes(endpoint).is_empty(), warned, "{endpoint}");
    }
    // Signed: no warning for the endpoint; a key file others may read is one.
    let (dir, c) = signed(KEY, "");
    assert!(c.unwrap().notes.is_empty());
    use std::os::unix::fs::PermissionsExt;
    let key = dir.path().join("mavlink.key");
    std::fs::set_permissions(&key, std::fs::Permissions::from_mode(0o644)).unwrap();
    let text = format!("{GOOD}[signing]\nkey_file = {:?}\n", key.display().to_string());
    let notes = parse(Path::new("m.toml"), &text).unwrap().notes;
    assert_eq!(notes.len(), 1, "{notes:?}");
    assert!(
        notes[0].contains("may be read by others than its owner (mode 644)"),
        "{notes:?}"
    );
}
