//! `--check`, the shipped configuration and unit.

use super::*;

#[test]
fn check_names_the_file_line_column_and_key_and_exits_2() {
    let dir = tempfile::tempdir().expect("temp dir");
    let path = dir.path().join("m.toml");
    std::fs::write(
        &path,
        mavlink_config("127.0.0.1:4001", 1000, "").replace("component_id = 171", "component_id = 154"),
    )
    .expect("write");
    let out = support::door::check(env!("CARGO_BIN_EXE_gimbal-mavlink"), &path);
    assert_eq!(out.status.code(), Some(2), "{out:?}");
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        err.contains("m.toml:17:16: gimbal[1].component_id: expected a component id of its own"),
        "{err}"
    );
}

#[test]
fn check_warns_of_a_serial_device_absent_now_and_still_passes() {
    let dir = tempfile::tempdir().expect("temp dir");
    let path = dir.path().join("m.toml");
    let serial = "[[endpoint]]\nserial = \"/dev/no-such-mavlink-radio\"";
    std::fs::write(&path, mavlink_config("127.0.0.1:4001", 1000, serial)).expect("write");
    let out = support::door::check(env!("CARGO_BIN_EXE_gimbal-mavlink"), &path);
    // Plugged in later, it is opened then: valid, with a warning at its place.
    assert_eq!(out.status.code(), Some(0), "{out:?}");
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.starts_with("gimbal-mavlink: warning: "), "{err}");
    assert!(
        err.contains("m.toml:19:10: endpoint[2].serial: /dev/no-such-mavlink-radio does not exist now"),
        "{err}"
    );
    assert!(
        String::from_utf8_lossy(&out.stdout).contains("valid (2 gimbal(s), 3 endpoint(s))"),
        "{out:?}"
    );
}

#[test]
fn the_shipped_configuration_documents_every_key_and_passes_check() {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("config/gimbal-mavlink.toml");
    let text = std::fs::read_to_string(&path).expect("config/gimbal-mavlink.toml");
    for key in [
        "gcud",
        "system_id",
        "source_group",
        "nic_window_ms",
        "attitude_rate_hz",
        "lease_ms",
        "udp_listen",
        "udp",
        "tcp_listen",
        "tcp",
        "name",
        "address",
        "component_id",
        "pan_deg",
        "tilt_deg",
        "max_rate_dps",
        "mount_latitude_deg",
        "mount_longitude_deg",
        "mount_altitude_m",
        "mount_heading_deg",
        "key_file",
        "link_id",
    ] {
        assert!(
            text.lines()
                .any(|l| l.trim_start_matches(['#', ' ']).starts_with(&format!("{key} ="))),
            "config/gimbal-mavlink.toml does not document {key}"
        );
    }
    let out = support::door::check(env!("CARGO_BIN_EXE_gimbal-mavlink"), &path);
    assert_eq!(out.status.code(), Some(0), "{out:?}");
    assert!(out.stderr.is_empty(), "on loopback, no warning: {out:?}");
}

#[test]
fn check_warns_of_an_endpoint_off_loopback_without_signing() {
    let dir = tempfile::tempdir().expect("temp dir");
    let path = dir.path().join("m.toml");
    let open = mavlink_config("127.0.0.1:4001", 1000, "")
        .replace("udp_listen = \"127.0.0.1:0\"", "udp_listen = \"0.0.0.0:0\"");
    std::fs::write(&path, &open).expect("write");
    let out = support::door::check(env!("CARGO_BIN_EXE_gimbal-mavlink"), &path);
    assert_eq!(out.status.code(), Some(0), "a warning, not an error: {out:?}");
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        err.contains("m.toml:5:14: endpoint[0].udp_listen: 0.0.0.0:0 is off loopback and [signing] is not set"),
        "{err}"
    );
    // Signed with a key only its owner reads: no warning.
    let key = dir.path().join("mavlink.key");
    std::fs::write(
        &key,
        "00112233445566778899aabbccddeeff00112233445566778899aabbccddeeff\n",
    )
    .expect("write");
    use std::os::unix::fs::PermissionsExt;
    std::fs::set_permissions(&key, std::fs::Permissions::from_mode(0o600)).expect("chmod");
    std::fs::write(
        &path,
        format!("{open}[signing]\nkey_file = {:?}\n", key.display().to_string()),
    )
    .expect("write");
    let out = support::door::check(env!("CARGO_BIN_EXE_gimbal-mavlink"), &path);
    assert_eq!(out.status.code(), Some(0), "{out:?}");
    assert!(out.stderr.is_empty(), "{out:?}");
}

#[test]
fn the_shipped_unit_is_hardened_and_checks_its_configuration_first() {
    support::door::assert_unit_has(
        "gimbal-mavlink.service",
        &[
            "Type=notify",
            "ExecStartPre=/usr/bin/gimbal-mavlink --check --config /etc/gimbal-mavlink/gimbal-mavlink.toml",
            "ExecStart=/usr/bin/gimbal-mavlink --config /etc/gimbal-mavlink/gimbal-mavlink.toml",
            "DynamicUser=yes",
            "NoNewPrivileges=yes",
            "CapabilityBoundingSet=",
            "ProtectSystem=strict",
            // Serial endpoints: tty devices only, as gcud.service.
            "SupplementaryGroups=dialout",
            "DevicePolicy=closed",
            "DeviceAllow=char-ttyUSB rw",
            "DeviceAllow=char-ttyS rw",
            "DeviceAllow=char-ttyACM rw",
            "DeviceAllow=char-ttyAMA rw",
            "DeviceAllow=char-ttyTHS rw",
            "DeviceAllow=char-ttymxc rw",
            "DeviceAllow=char-ttyO rw",
            "RestrictAddressFamilies=AF_INET AF_INET6 AF_UNIX",
            "SystemCallFilter=@system-service",
            "MemoryDenyWriteExecute=yes",
            "KillSignal=SIGTERM",
        ],
    );
}
