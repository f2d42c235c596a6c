//! The shipped deployment files (`config/gcud.service`,
//! `config/99-sagebrush-gimbal.rules`) hold what field installs need, and the
//! units (gcud's and the front doors') are accepted by `systemd-analyze
//! verify` with an exposure at or below 1.6. Without that tool the
//! check fails under CI (`CI` set, as `.ci/run` does; it installs systemd)
//! and says loudly that it was not done elsewhere.

use std::path::PathBuf;
use std::process::Command;

mod support;

fn read(name: &str) -> String {
    let path = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("config").join(name);
    std::fs::read_to_string(&path).unwrap_or_else(|e| panic!("{}: {e}", path.display()))
}

/// The unit's `[Section]` → its `KEY=VALUE` lines (comments and blanks left
/// out, surrounding spaces trimmed).
fn section(unit: &str, name: &str) -> Vec<String> {
    let mut inside = false;
    let mut lines = Vec::new();
    for line in unit.lines().map(str::trim) {
        if line.starts_with('[') {
            inside = line == format!("[{name}]");
        } else if inside && !line.is_empty() && !line.starts_with('#') {
            lines.push(line.to_owned());
        }
    }
    lines
}

fn has(lines: &[String], want: &str) -> bool {
    lines.iter().any(|l| l == want)
}

#[test]
fn unit_allows_every_serial_family_and_waits_for_the_network() {
    let unit = read("gcud.service");
    let service = section(&unit, "Service");
    for family in ["ttyUSB", "ttyS", "ttyACM", "ttyAMA", "ttyTHS", "ttymxc", "ttyO"] {
        let line = format!("DeviceAllow=char-{family} rw");
        assert!(has(&service, &line), "[Service] lacks {line:?}");
    }
    let unit_section = section(&unit, "Unit");
    for line in ["After=network-online.target", "Wants=network-online.target"] {
        assert!(has(&unit_section, line), "[Unit] lacks {line:?}");
    }
    assert!(
        !unit_section.iter().any(|l| l == "After=network.target"),
        "[Unit] still orders only after network.target"
    );
    assert!(
        has(&service, "Restart=on-failure"),
        "[Service] lacks Restart=on-failure"
    );
    // A start limit that lets boot-time retries run for a while: at least
    // a minute's worth of restarts before the unit is failed for good.
    let value = |lines: &[String], key: &str| -> Option<String> {
        lines
            .iter()
            .find_map(|l| l.strip_prefix(&format!("{key}=")).map(str::to_owned))
    };
    let secs = |v: String| -> u64 {
        let v = v.trim();
        v.strip_suffix("min")
            .map(|m| m.parse::<u64>().unwrap() * 60)
            .or_else(|| v.strip_suffix('s').map(|s| s.parse().unwrap()))
            .unwrap_or_else(|| v.parse().unwrap_or_else(|_| panic!("unreadable time {v:?}")))
    };
    let interval = value(&unit_section, "StartLimitIntervalSec")
        .map(secs)
        .expect("[Unit] lacks StartLimitIntervalSec");
    let burst: u64 = value(&unit_section, "StartLimitBurst")
        .expect("[Unit] lacks StartLimitBurst")
        .parse()
        .expect("StartLimitBurst is a number");
    let restart = value(&service, "RestartSec")
        .map(secs)
        .expect("[Service] lacks RestartSec");
    assert!(restart >= 1, "RestartSec={restart}s would spin");
    assert!(
        burst * restart >= 60,
        "{burst} starts {restart}s apart give up in under a minute"
    );
    assert!(
        interval >= burst * restart,
        "StartLimitIntervalSec={interval} is shorter than {burst} restarts {restart}s apart: the limit never trips"
    );
}

#[test]
fn udev_rule_keeps_modemmanager_away() {
    let rules = read("99-sagebrush-gimbal.rules");
    let rules: Vec<&str> = rules
        .lines()
        .map(str::trim)
        .filter(|l| !l.is_empty() && !l.starts_with('#'))
        // The rules that name tty devices (the usb-serial one tunes the adapter).
        .filter(|l| l.contains(r#"SUBSYSTEM=="tty""#))
        .collect();
    assert!(!rules.is_empty(), "no rules");
    for rule in rules {
        assert!(
            rule.contains(r#"ENV{ID_MM_DEVICE_IGNORE}="1""#),
            "rule without ID_MM_DEVICE_IGNORE: {rule}"
        );
    }
}

#[test]
fn udev_rule_sets_the_ftdi_latency_timer_to_one_millisecond() {
    let rules = read("99-sagebrush-gimbal.rules");
    let rule = rules
        .lines()
        .find(|l| !l.trim_start().starts_with('#') && l.contains("latency_timer"))
        .expect("a rule setting the adapters' latency_timer");
    for part in [
        "ACTION==\"add\"",
        "SUBSYSTEM==\"usb-serial\"",
        "DRIVER==\"ftdi_sio\"",
        "ATTR{latency_timer}=\"1\"",
    ] {
        assert!(rule.contains(part), "{rule:?} lacks {part}");
    }
}

#[test]
fn systemd_analyze_verify_accepts_the_units() {
    if !systemd_analyze_present() {
        return;
    }
    for unit in support::PACKAGED_UNITS.map(|name| format!("{name}.service")) {
        let dir = tempfile::tempdir().unwrap();
        let path = unit_copy(dir.path(), &unit);
        let out = Command::new("systemd-analyze")
            .arg("verify")
            .arg("--man=no")
            .arg(&path)
            .output()
            .expect("systemd-analyze runs");
        let stderr = String::from_utf8_lossy(&out.stderr);
        let stdout = String::from_utf8_lossy(&out.stdout);
        // Lines about the unit itself; the host's other units (absent in a
        // container, say) are not ours to judge.
        let ours: Vec<&str> = stderr
            .lines()
            .chain(stdout.lines())
            .filter(|l| l.contains(&unit))
            .collect();
        assert!(
            out.status.success() && ours.is_empty(),
            "systemd-analyze verify refused {unit} (exit {:?}):\n{stdout}{stderr}",
            out.status.code()
        );
    }
}

/// A copy of the unit `name` running /bin/true (the program may not be
/// installed here), for systemd-analyze.
fn unit_copy(dir: &std::path::Path, name: &str) -> PathBuf {
    let unit: String = read(name)
        .lines()
        .map(|line| {
            for key in ["ExecStartPre=", "ExecStart="] {
                if line.starts_with(key) {
                    return format!("{key}/bin/true\n");
                }
            }
            format!("{line}\n")
        })
        .collect();
    let path = dir.join(name);
    std::fs::write(&path, unit).unwrap();
    path
}

/// True when systemd-analyze runs here; otherwise fails under CI and warns.
fn systemd_analyze_present() -> bool {
    let probe = Command::new("systemd-analyze").arg("--version").output();
    if probe.is_ok_and(|o| o.status.success()) {
        return true;
    }
    let missing = "systemd-analyze not found: the unit is not checked. Install it with \
                   `sudo apt-get install -y systemd` (./test.sh does)";
    support::tool_missing(missing);
    false
}

#[test]
fn unit_exposure_stays_at_or_below_1_6() {
    if !systemd_analyze_present() {
        return;
    }
    for unit in support::PACKAGED_UNITS.map(|name| format!("{name}.service")) {
        let dir = tempfile::tempdir().unwrap();
        let path = unit_copy(dir.path(), &unit);
        let out = Command::new("systemd-analyze")
            .args(["security", "--offline=true", "--no-pager"])
            .arg(&path)
            .output()
            .expect("systemd-analyze runs");
        let text = String::from_utf8_lossy(&out.stdout);
        let line = text
            .lines()
            .find(|l| l.contains("Overall exposure level"))
            .unwrap_or_else(|| {
                panic!(
                    "{unit}: no exposure level in:\n{text}{}",
                    String::from_utf8_lossy(&out.stderr)
                )
            });
        let level: f64 = line
            .split(':')
            .nth(1)
            .and_then(|rest| rest.split_whitespace().next())
            .and_then(|n| n.parse().ok())
            .unwrap_or_else(|| panic!("unreadable exposure line {line:?}"));
        assert!(level <= 1.6, "{unit}: exposure rose above 1.6: {line}");
    }
}

/// README.md and docs/capture.md put captures in /var/lib/gcud/, and the
/// unit's ProtectSystem=strict leaves nothing else writable: the unit must
/// make that directory (StateDirectory=gcud, writable by the DynamicUser).
#[test]
fn state_directory_is_where_the_documentation_puts_captures() {
    let root = PathBuf::from(env!("CARGO_MANIFEST_DIR"));
    for doc in ["README.md", "docs/capture.md"] {
        let text = std::fs::read_to_string(root.join(doc)).unwrap();
        assert!(text.contains("/var/lib/gcud/"), "{doc} no longer names /var/lib/gcud/");
    }
    let service = section(&read("gcud.service"), "Service");
    assert!(
        has(&service, "ProtectSystem=strict"),
        "[Service] lacks ProtectSystem=strict"
    );
    assert!(
        has(&service, "StateDirectory=gcud"),
        "[Service] lacks StateDirectory=gcud: /var/lib/gcud/ is read-only under ProtectSystem=strict"
    );
}
