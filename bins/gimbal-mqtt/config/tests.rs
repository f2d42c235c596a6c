use super::*;

const GOOD: &str = r#"
gcud = "127.0.0.1:4001"
site = "north"
[broker]
url = "mqtt://127.0.0.1:1883"
[[gimbal]]
name = "mast-1"
address = "5.1.1"
"#;

fn err(text: &str) -> String {
    parse(Path::new("m.toml"), text).unwrap_err().to_string()
}

#[test]
fn a_good_file_and_its_defaults() {
    let c = parse(Path::new("m.toml"), GOOD).unwrap();
    assert_eq!(c.site, "north");
    assert_eq!(c.prefix, "sagebrush");
    assert_eq!(c.discovery_prefix.as_deref(), Some("homeassistant"));
    assert_eq!(c.broker.host, "127.0.0.1");
    assert_eq!(c.broker.port, 1883);
    assert_eq!(c.broker.version, Version::V5);
    assert_eq!(c.broker.client_id, "gimbal-mqtt-north");
    assert_eq!(c.broker.keep_alive, Duration::from_secs(30));
    assert!(c.broker.tls.is_none() && c.broker.credentials.is_none());
    assert_eq!(c.gimbals[0].presets, (1..=8).collect::<Vec<u8>>());
    assert_eq!(c.poll, Duration::from_millis(100));
    let v3 = parse(
        Path::new("m.toml"),
        &GOOD.replace("[broker]", "[broker]\nversion = \"3.1.1\""),
    )
    .unwrap();
    assert_eq!(v3.broker.version, Version::V311);
    let default_port = parse(Path::new("m.toml"), &GOOD.replace(":1883", "")).unwrap();
    assert_eq!(default_port.broker.port, 1883);
}

#[test]
fn a_password_comes_from_its_file() {
    let dir = tempfile::tempdir().unwrap();
    let file = dir.path().join("pw");
    std::fs::write(&file, "s3cret\n").unwrap();
    let text = GOOD.replace(
        "[broker]",
        &format!("[broker]\nusername = \"door\"\npassword_file = \"{}\"", file.display()),
    );
    let c = parse(Path::new("m.toml"), &text).unwrap();
    assert_eq!(c.broker.credentials, Some(("door".to_owned(), "s3cret".to_owned())));
    let missing = text.replace("/pw", "/nope");
    assert!(err(&missing).starts_with("m.toml:6:17: broker.password_file: cannot read"));
}

#[test]
fn errors_name_the_place_and_what_was_expected() {
    assert_eq!(
        err(&GOOD.replace("\"north\"", "\"no/rth\"")),
        "m.toml:3:8: site: expected 1 to 32 of A-Z a-z 0-9 _ -, found \"no/rth\""
    );
    assert_eq!(
        err(&GOOD.replace("mqtt://127.0.0.1:1883", "http://x")),
        "m.toml:5:7: broker.url: expected mqtt://HOST[:PORT] or mqtts://HOST[:PORT]: \"http://x\" has neither scheme"
    );
    assert_eq!(
        err(&GOOD.replace("\"mast-1\"", "\"mast+1\"")),
        "m.toml:7:8: gimbal[0].name: expected 1 to 32 of A-Z a-z 0-9 _ -, found \"mast+1\""
    );
    assert!(
        err(&GOOD.replace("[broker]", "[broker]\nversion = \"4\""))
            .starts_with("m.toml:5:11: broker.version: expected \"5\" or \"3.1.1\"")
    );
    assert!(err(&GOOD.replace("[broker]", "[broker]\nkeep_alive_s = 1")).contains("broker.keep_alive_s"));
    assert!(
        err(&GOOD.replace("[broker]", "[broker]\nca = \"ca.pem\"")).contains("broker.ca: only with an mqtts:// url")
    );
    assert!(
        err(&GOOD.replace("[broker]", "[broker]\nusername = \"u\""))
            .contains("broker.username: expected password_file with it")
    );
    assert!(
        err(&GOOD.replace(
            "mqtt://127.0.0.1:1883\"",
            "mqtts://127.0.0.1\"\nca = \"/nonexistent/ca.pem\""
        ))
        .starts_with("m.toml:6:6: broker.ca: /nonexistent/ca.pem")
    );
    assert!(
        err(&GOOD.replace("address = \"5.1.1\"", "address = \"5.1.1\"\npresets = [300]")).contains("gimbal[0].presets")
    );
    assert!(err(&GOOD.replace("site = \"north\"\n", "")).contains("site"));
    assert!(
        err(&GOOD.replace("[[gimbal]]\nname = \"mast-1\"\naddress = \"5.1.1\"\n", ""))
            .contains("expected at least one [[gimbal]]")
    );
}
