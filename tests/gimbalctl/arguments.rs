//! The command line itself: `--help` documents the dead-man, examples,
//! ranges and exit codes; bad arguments exit 2 with a hint, in JSON too.

use super::*;

#[test]
fn help_documents_the_dead_man_examples_ranges_and_exit_codes() {
    for sub in [&["slew", "--help"][..], &["zoom", "--help"], &["focus", "--help"]] {
        let out = gimbalctl(sub);
        assert_eq!(out.code, 0, "{out:?}");
        assert!(
            out.stdout.contains("dead-man") && out.stdout.contains("--for") && out.stdout.contains("--hold"),
            "{sub:?}: {}",
            out.stdout
        );
    }
    let slew = gimbalctl(&["slew", "--help"]).stdout;
    assert!(!slew.contains("until `stop`)"), "no unconditional claim: {slew}");
    let every = [
        "position",
        "goto",
        "preset",
        "slew",
        "stop",
        "halt",
        "recall-halt",
        "speed",
        "rate",
        "accel",
        "vector",
        "home",
        "verify-home",
        "init",
        "limits",
        "gains",
        "relay",
        "lens",
        "camera",
        "focus",
        "zoom",
        "id",
        "status",
        "errors",
        "status-bits",
        "data-rate",
        "set-address",
        "aux",
        "raw",
        "watch",
        "scan",
        "encode",
        "decode",
    ];
    for sub in every {
        let out = gimbalctl(&["help", sub]);
        assert!(
            out.stdout.contains("Examples:"),
            "{sub} has no examples: {}",
            out.stdout
        );
        // Global options are grouped under their headings, once each.
        assert_eq!(
            out.stdout.matches("Connection (global):").count(),
            1,
            "{sub}: {}",
            out.stdout
        );
    }
    for nested in [
        &["preset", "store"][..],
        &["preset", "recall"],
        &["preset", "query"],
        &["preset", "stored"],
        &["limits", "set"],
        &["limits", "clear"],
        &["gains", "set"],
        &["relay", "open"],
        &["relay", "close"],
        &["lens", "goto"],
        &["focus", "far"],
        &["focus", "near"],
        &["focus", "stop"],
        &["focus", "speed"],
        &["zoom", "in"],
        &["zoom", "out"],
        &["zoom", "stop"],
        &["zoom", "speed"],
        &["zoom", "digital"],
        &["aux", "configure"],
        &["aux", "send"],
        &["aux", "read"],
        &["aux", "count"],
        &["aux", "flush"],
    ] {
        let mut args = vec!["help"];
        args.extend_from_slice(nested);
        let out = gimbalctl(&args);
        assert!(out.stdout.contains("Examples:"), "{nested:?} has no examples: {out:?}");
    }
    for (sub, range) in [
        (&["help", "speed"][..], "0..=15"),
        (&["help", "goto"], "-327.68..=327.67"),
        (&["help", "rate"], "0..=655.35"),
        (&["help", "accel"], "0..=655.35"),
        (&["help", "lens", "goto"], "0..=4095"),
        (&["help", "zoom", "speed"], "0..=9"),
        (&["help", "preset", "store"], "0..=255"),
        (&["help", "gains", "set"], "0.3..=3.0"),
    ] {
        let out = gimbalctl(sub);
        assert!(
            out.stdout.contains(range),
            "{sub:?} should give {range}: {}",
            out.stdout
        );
    }
    let help = gimbalctl(&["--help"]).stdout;
    for code in [
        "20  --wait: the mount stopped short",
        "21  --wait: still moving",
        "22  --for/--hold",
    ] {
        assert!(help.contains(code), "exit code table lacks {code:?}: {help}");
    }
    let readme = std::fs::read_to_string(concat!(env!("CARGO_MANIFEST_DIR"), "/README.md")).expect("README");
    let section = readme.split("## gimbalctl").nth(1).expect("gimbalctl section");
    let section = section.split("\n## ").next().unwrap_or_default();
    for needle in ["dead-man", "--for", "--hold", "| 20 |", "| 22 |", "scan", "### JSON"] {
        assert!(section.contains(needle), "README gimbalctl section lacks {needle:?}");
    }
}

#[test]
fn bad_arguments_exit_2_with_a_hint_and_to_is_required() {
    let s = ["--serial", "/nonexistent"];
    for (args, needle) in [
        (
            &["--tcp", "127.0.0.1", "--to", "5.1.1", "position"][..],
            "expected HOST:PORT, e.g. 127.0.0.1:4001",
        ),
        (&["--tcp", "127.0.0.1:0", "--to", "5.1.1", "position"], "1..=65535"),
        (&[s[0], s[1], "position"], "needs --to"),
        (&[s[0], s[1], "goto", "10", "5"], "needs --to"),
        (&[s[0], s[1], "--to", "5.1", "id"], "GROUP.PORT.DEVICE"),
        (
            &[s[0], s[1], "--to", "1.1.1", "goto", "0", "-400"],
            "tilt -400 degrees is out of range -327.68..=327.67",
        ),
        (
            &[s[0], s[1], "--to", "1.1.1", "goto", "328", "0"],
            "pan 328 degrees is out of range",
        ),
        (&[s[0], s[1], "--to", "1.1.1", "speed", "pan", "16"], "0..=15"),
        (&[s[0], s[1], "--to", "1.1.1", "rate", "pan", "700"], "0..=655.35"),
        (&[s[0], s[1], "--to", "1.1.1", "accel", "tilt", "-1"], "0..=655.35"),
        (&[s[0], s[1], "--to", "1.1.1", "preset", "store", "256"], "0..=255"),
        (&[s[0], s[1], "--to", "1.1.1", "lens", "goto", "4096", "0"], "0..=4095"),
        (&[s[0], s[1], "--to", "1.1.1", "zoom", "speed", "10"], "0..=9"),
        (
            &[s[0], s[1], "--to", "1.1.1", "slew", "left", "--for", "2"],
            "2s, 500ms",
        ),
        (
            &[s[0], s[1], "--to", "1.1.1", "slew", "left", "--for", "1s", "--hold"],
            "--hold",
        ),
        (&[s[0], s[1], "--to", "1.1.255", "goto", "1", "1", "--wait"], "wildcard"),
        (&[s[0], s[1], "scan", "--devices", "0-3"], "1..=254"),
    ] {
        let out = gimbalctl(args);
        assert_eq!(out.code, 2, "{args:?}: {out:?}");
        assert!(
            out.stderr.contains(needle),
            "{args:?} should say {needle:?}: {}",
            out.stderr
        );
    }
}

#[test]
fn json_failures_of_bad_arguments_are_json_too() {
    for args in [
        &["--json", "--tcp", "127.0.0.1", "--to", "5.1.1", "position"][..],
        &[
            "--json",
            "--serial",
            "/nonexistent",
            "--to",
            "1.1.1",
            "speed",
            "pan",
            "16",
        ],
        &["--json", "--serial", "/nonexistent", "goto", "1", "2"],
    ] {
        let out = gimbalctl(args);
        assert_eq!(out.code, 2, "{args:?}: {out:?}");
        let v = out.json();
        assert_eq!(
            (v["ok"].as_bool(), v["outcome"].as_str(), v["exit_code"].as_u64()),
            (Some(false), Some("usage"), Some(2))
        );
        assert!(v["error"].as_str().is_some_and(|e| !e.is_empty()), "{v}");
    }
}
