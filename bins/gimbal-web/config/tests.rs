use super::*;

const GOOD: &str = r#"
gcud = "127.0.0.1:4001"
listen = "0.0.0.0:8080"
[[user]]
name = "admin"
password = "secret"
role = "administrator"
[[gimbal]]
name = "mast-1"
address = "5.1.1"
pan_deg = [-170.0, 170.0]
"#;

fn err(text: &str) -> String {
    parse(Path::new("w.toml"), text).unwrap_err().to_string()
}

#[test]
fn a_good_file_and_its_defaults() {
    let c = parse(Path::new("w.toml"), GOOD).unwrap();
    assert_eq!(c.gimbals[0].address, Address::new(5, 1, 1));
    assert_eq!(c.gimbals[0].pan_deg, (-170.0, 170.0));
    assert_eq!(c.gimbals[0].tilt_deg, (-90.0, 90.0));
    assert_eq!(c.users[0].role, Role::Administrator);
    assert_eq!(c.hold_lease, Duration::from_millis(300));
    assert_eq!(c.poll, Duration::from_millis(100));
    assert_eq!(c.listen, "0.0.0.0:8080".parse::<SocketAddr>().unwrap());
    assert_eq!(c.max_streams_per_user, 32);
    assert!(c.trusted_proxies.is_empty());
}

#[test]
fn a_trusted_proxy_is_an_address_or_a_list() {
    let with = |v: &str| GOOD.replace("[[user]]", &format!("[http]\ntrusted_proxy = {v}\n[[user]]"));
    let one = parse(Path::new("w.toml"), &with("\"127.0.0.1\"")).unwrap();
    assert_eq!(one.trusted_proxies, vec!["127.0.0.1".parse::<IpAddr>().unwrap()]);
    let two = parse(Path::new("w.toml"), &with("[\"10.0.0.2\", \"::ffff:10.0.0.3\"]")).unwrap();
    assert_eq!(two.trusted_proxies[1], "10.0.0.3".parse::<IpAddr>().unwrap());
    assert!(err(&with("\"proxy.lan\"")).contains("http.trusted_proxy: expected an IP address"));
}

#[test]
fn errors_name_the_place_and_what_was_expected() {
    assert_eq!(
        err(&GOOD.replace("\"5.1.1\"", "\"5.1\"")),
        "w.toml:10:11: gimbal[0].address: expected GROUP.PORT.DEVICE of one gimbal, e.g. \"5.1.1\""
    );
    assert_eq!(
        err(&GOOD.replace("\"0.0.0.0:8080\"", "\"8080\"")),
        "w.toml:3:10: listen: expected IP:PORT: \"8080\" has no port"
    );
    assert!(err(&GOOD.replace("administrator", "root")).starts_with("w.toml:7:8: user[0].role: expected"));
    assert!(err(&GOOD.replace("gcud =", "hold_lease_ms = 5000\ngcud =")).contains("hold_lease_ms"));
    assert!(
        err(&GOOD.replace(
            "[[gimbal]]\nname = \"mast-1\"\naddress = \"5.1.1\"\npan_deg = [-170.0, 170.0]\n",
            ""
        ))
        .contains("expected at least one [[gimbal]]")
    );
}
