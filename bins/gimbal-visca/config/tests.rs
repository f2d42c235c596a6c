use super::*;

const GOOD: &str = r#"
gcud = "127.0.0.1:4001"
[[gimbal]]
name = "mast-1"
address = "5.1.1"
visca_udp = "127.0.0.1:52381"
visca_tcp = "127.0.0.1:5678"
"#;

fn err(text: &str) -> String {
    parse(Path::new("v.toml"), text).unwrap_err().to_string()
}

#[test]
fn a_good_file_and_its_defaults() {
    let c = parse(Path::new("v.toml"), GOOD).unwrap();
    let g = &c.gimbals[0];
    assert_eq!(g.address, Address::new(5, 1, 1));
    assert_eq!(g.udp, "127.0.0.1:52381".parse::<SocketAddr>().unwrap());
    assert_eq!(g.tcp, Some("127.0.0.1:5678".parse().unwrap()));
    assert_eq!(g.degrees_per_step, DEGREES_PER_STEP);
    assert!(!g.reuse_address && !g.lens);
    assert_eq!(c.lease, Some(Duration::from_millis(5000)));
    let off = parse(
        Path::new("v.toml"),
        &GOOD.replace("gcud =", "motion_lease_ms = 0\ngcud ="),
    )
    .unwrap();
    assert_eq!(off.lease, None);
}

#[test]
fn errors_name_the_place_and_what_was_expected() {
    assert_eq!(
        err(&GOOD.replace("\"127.0.0.1:5678\"", "\"5678\"")),
        "v.toml:7:13: gimbal[0].visca_tcp: expected IP:PORT: \"5678\" has no port"
    );
    let two = format!("{GOOD}[[gimbal]]\nname = \"mast-2\"\naddress = \"5.2.1\"\nvisca_udp = \"127.0.0.1:52381\"\n");
    assert!(err(&two).contains("gimbal[1].visca_udp: expected an address no other gimbal uses"));
    assert!(
        err(&GOOD.replace(
            "[[gimbal]]",
            "[[client]]\naddress = \"10.0.0.x\"\nuser = \"a\"\n[[gimbal]]"
        ))
        .contains("client[0].address")
    );
    assert!(
        err(&GOOD.replace(
            "[[gimbal]]",
            "[[client]]\naddress = \"10.0.0.2\"\nuser = \"a b\"\n[[gimbal]]"
        ))
        .contains("client[0].user")
    );
    assert!(
        err(&GOOD.replace("visca_tcp", "degrees_per_step = 2.0\nvisca_tcp")).contains("gimbal[0].degrees_per_step")
    );
    assert!(err(&GOOD.replace("visca_udp", "udp")).contains("unknown field `udp`"));
}
