use super::*;

const GOOD: &str = r#"
gcud = "127.0.0.1:4001"
[[input]]
serial = "/dev/ttyUSB0"
baud = 4800
protocol = "pelco-d"
[[input]]
tcp_listen = "127.0.0.1:4100"
protocol = "pelco-p"
principal = "dvr"
[[gimbal]]
name = "mast-1"
address = "5.1.1"
pelco_address = 1
"#;

fn err(text: &str) -> String {
    parse(Path::new("p.toml"), text).unwrap_err().to_string()
}

#[test]
fn a_good_file_and_its_defaults() {
    let c = parse(Path::new("p.toml"), GOOD).unwrap();
    assert_eq!(
        c.inputs[0].transport,
        Transport::Serial {
            path: "/dev/ttyUSB0".into(),
            baud: 4800
        }
    );
    assert_eq!(c.inputs[0].protocol, Protocol::D);
    assert_eq!(c.inputs[0].principal, None);
    assert_eq!(c.inputs[1].protocol, Protocol::P);
    assert_eq!(c.inputs[1].principal.as_deref(), Some("dvr"));
    assert_eq!(c.inputs[1].name, "input[1] tcp_listen 127.0.0.1:4100");
    assert_eq!(c.gimbals[0].address, Address::new(5, 1, 1));
    assert_eq!(c.gimbals[0].pelco_address, 1);
    assert!(!c.gimbals[0].zoom);
    assert_eq!(
        c.lease,
        Some(Duration::from_secs(1)),
        "the motion lease is on by default"
    );
    let off = parse(Path::new("p.toml"), &format!("motion_lease_ms = 0\n{GOOD}")).unwrap();
    assert_eq!(off.lease, None);
}

#[test]
fn errors_name_the_file_line_key_and_what_was_expected() {
    assert_eq!(
        err(&GOOD.replace("\"pelco-p\"", "\"pelco-x\"")),
        "p.toml:9:12: input[1].protocol: expected \"pelco-d\" or \"pelco-p\", found \"pelco-x\""
    );
    assert!(
        err(&GOOD.replace("baud = 4800", "baud = 4801")).starts_with("p.toml:5:8: input[0].baud: expected"),
        "{}",
        err(&GOOD.replace("baud = 4800", "baud = 4801"))
    );
    let both = GOOD.replace(
        "protocol = \"pelco-p\"",
        "protocol = \"pelco-p\"\nudp_listen = \"127.0.0.1:4101\"",
    );
    assert!(
        err(&both).starts_with("p.toml:7:1: input[1]: expected exactly one of serial, tcp_listen or udp_listen"),
        "{}",
        err(&both)
    );
    let baud_on_tcp = GOOD.replace("protocol = \"pelco-p\"", "protocol = \"pelco-p\"\nbaud = 9600");
    assert!(err(&baud_on_tcp).contains("input[1].baud: baud applies to a serial input only"));
    let twice = format!("{GOOD}[[gimbal]]\nname = \"mast-2\"\naddress = \"5.1.2\"\npelco_address = 1\n");
    assert_eq!(
        err(&twice),
        "p.toml:18:17: gimbal[1].pelco_address: expected an address of its own: 1 is mast-1's"
    );
    assert!(
        err(&GOOD.replace("pelco_address = 1", "pelco_address = 0"))
            .starts_with("p.toml:14:17: gimbal[0].pelco_address")
    );
    assert!(
        err(&GOOD.replace("tcp_listen = \"127.0.0.1:4100\"", "tcp_listen = \"4100\"")).contains("input[1].tcp_listen")
    );
    assert!(
        err(&format!("motion_lease_ms = 50\n{GOOD}"))
            .starts_with("p.toml:1:19: motion_lease_ms: expected 0 (off) or 100")
    );
    assert!(err(&GOOD.replace("pelco_address", "pelco_addr")).contains("unknown field `pelco_addr`"));
    assert!(
        err("gcud = \"127.0.0.1:4001\"\n[[gimbal]]\nname = \"a\"\naddress = \"5.1.1\"\npelco_address = 1\n")
            .contains("expected at least one [[input]]")
    );
}

#[test]
fn the_shipped_configuration_is_valid_and_on_loopback() {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("config/gimbal-pelco.toml");
    let text = std::fs::read_to_string(&path).expect("config/gimbal-pelco.toml");
    let c = parse(&path, &text).unwrap_or_else(|e| panic!("{e}"));
    for i in &c.inputs {
        if let Transport::TcpListen(a) | Transport::UdpListen(a) = i.transport {
            assert!(a.ip().is_loopback(), "{}", i.name);
        }
    }
}
