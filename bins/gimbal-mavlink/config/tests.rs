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
