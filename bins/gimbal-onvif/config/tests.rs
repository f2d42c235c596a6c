use super::*;

const GOOD: &str = r#"
gcud = "127.0.0.1:4001"
[discovery]
listen = "127.0.0.1:3702"
[[user]]
name = "admin"
password = "secret"
role = "administrator"
[[gimbal]]
name = "mast-1"
address = "5.1.1"
listen = "127.0.0.1:8081"
pan_deg = [-170.0, 170.0]
"#;

fn err(text: &str) -> String {
    parse(Path::new("o.toml"), text).unwrap_err().to_string()
}

#[test]
fn a_good_file_and_its_defaults() {
    let c = parse(Path::new("o.toml"), GOOD).unwrap();
    assert_eq!(c.gimbals[0].address, Address::new(5, 1, 1));
    assert_eq!(c.gimbals[0].pan_deg, (-170.0, 170.0));
    assert_eq!(c.gimbals[0].tilt_deg, (-90.0, 90.0));
    assert_eq!(c.users.list[0].role, Role::Administrator);
    assert_eq!(c.max_move, Duration::from_secs(10));
}

#[test]
fn errors_name_the_place_and_what_was_expected() {
    assert_eq!(
        err(&GOOD.replace("\"5.1.1\"", "\"5.1\"")),
        "o.toml:11:11: gimbal[0].address: expected GROUP.PORT.DEVICE of one gimbal, e.g. \"5.1.1\""
    );
    assert!(err(&GOOD.replace("administrator", "root")).starts_with("o.toml:8:8: user[0].role: expected"));
    assert!(err(&GOOD.replace("[-170.0, 170.0]", "[10.0, -10.0]")).starts_with("o.toml:13:11: gimbal[0].pan_deg"));
    assert!(err(&GOOD.replace("listen = \"127.0.0.1:8081\"", "listen = \"8081\"")).contains("gimbal[0].listen"));
    assert!(err(&format!("{GOOD}colour = 1\n")).contains("colour"));
    assert!(err(&GOOD.replace("password = \"secret\"", "")).contains("exactly one of `password`"));
}

#[test]
fn two_gimbals_cannot_listen_where_one_binds_already() {
    let second =
        |listen: &str| format!("{GOOD}[[gimbal]]\nname = \"mast-2\"\naddress = \"5.1.2\"\nlisten = \"{listen}\"\n");
    // 0.0.0.0 covers 127.0.0.1: both could not bind.
    let e = err(&second("0.0.0.0:8081"));
    assert!(
        e.starts_with("o.toml:17:10: gimbal[1].listen: expected an address of its own"),
        "{e}"
    );
    assert!(parse(Path::new("o.toml"), &second("127.0.0.1:8082")).is_ok());
    // Port 0: each gets a port of its own.
    let both_any = GOOD.replace("127.0.0.1:8081", "127.0.0.1:0");
    assert!(
        parse(
            Path::new("o.toml"),
            &format!("{both_any}[[gimbal]]\nname = \"mast-2\"\naddress = \"5.1.2\"\nlisten = \"127.0.0.1:0\"\n")
        )
        .is_ok()
    );
}

#[test]
fn the_bounds_have_defaults_and_take_their_keys() {
    let c = parse(Path::new("o.toml"), GOOD).unwrap();
    let g = &c.gimbals[0];
    assert_eq!(g.http.max_connections, 512);
    assert_eq!(g.http.header_timeout, Duration::from_secs(5));
    assert_eq!(c.users.bounds.nonce_cache, 65_536);
    assert_eq!(c.discovery.unwrap().answers_per_s, 20);
    let text = GOOD.replace(
        "[discovery]\n",
        "[http]\nmax_connections = 10\nheader_timeout_ms = 800\n[auth]\nrequests_per_s = 5\nnonce_cache = 100\n[discovery]\nanswers_per_source_per_s = 7\n",
    );
    let c = parse(Path::new("o.toml"), &text).unwrap();
    assert_eq!(c.gimbals[0].http.max_connections, 10);
    assert_eq!(c.gimbals[0].http.header_timeout, Duration::from_millis(800));
    assert_eq!((c.users.bounds.requests_per_s, c.users.bounds.nonce_cache), (5, 100));
    assert_eq!(c.discovery.unwrap().answers_per_source_per_s, 7);
    assert!(
        err(&GOOD.replace("[discovery]\n", "[http]\nmax_connections = 0\n[discovery]\n"))
            .contains("http.max_connections")
    );
}

#[test]
fn a_state_file_in_a_missing_folder_is_refused_naming_it() {
    let dir = tempfile::tempdir().unwrap();
    let missing = dir.path().join("nowhere").join("presets.toml");
    let text = format!("state_file = \"{}\"\n{GOOD}", missing.display());
    let e = err(&text);
    assert!(e.contains("o.toml:1:14: state_file:"), "{e}");
    assert!(e.contains(&format!("{}: its folder", missing.display())), "{e}");
    assert!(e.contains("does not exist"), "{e}");
    let fine = format!("state_file = \"{}\"\n{GOOD}", dir.path().join("presets.toml").display());
    assert!(parse(Path::new("o.toml"), &fine).is_ok());
}

#[test]
fn the_field_of_view_at_the_tele_end_needs_a_lens_and_a_wider_wide_end() {
    let lens = format!("{GOOD}zoom = true\nfov_deg = [60.0, 34.0]\n");
    let c = parse(Path::new("o.toml"), &format!("{lens}fov_tele_deg = [6.0, 3.4]\n")).unwrap();
    assert_eq!(c.gimbals[0].fov_deg, Some((60.0, 34.0)));
    assert_eq!(c.gimbals[0].fov_tele_deg, Some((6.0, 3.4)));
    for bad in [
        format!("{lens}fov_tele_deg = [61.0, 3.4]\n"),
        format!("{GOOD}fov_deg = [60.0, 34.0]\nfov_tele_deg = [6.0, 3.4]\n"),
        format!("{GOOD}zoom = true\nfov_tele_deg = [6.0, 3.4]\n"),
    ] {
        assert!(
            err(&bad).contains("gimbal[0].fov_tele_deg: expected with zoom = true"),
            "{bad}"
        );
    }
    assert!(
        err(&format!("{lens}fov_tele_deg = [0.0, 3.4]\n")).contains("gimbal[0].fov_tele_deg: expected [HORIZONTAL")
    );
}
