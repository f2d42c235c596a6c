//! The Debian package (`[package.metadata.deb]` in Cargo.toml, built with
//! cargo-deb): it holds every program, the units of gcud and the front doors
//! (each running the program and configuration the package installs), the udev rule and the
//! configurations (those under /etc as dpkg configuration files), and the
//! configuration it installs passes `gcud --check` run from the package.
//! Without cargo-deb the package test fails under CI (`CI` set; .ci/run
//! installs it) and says loudly that it was not done elsewhere. .ci/run also
//! installs the package with `dpkg -i` and checks the installed unit.

use std::path::{Path, PathBuf};
use std::process::Command;

mod support;

fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

/// `[package.metadata.deb] assets`: (source, destination) pairs.
fn assets() -> Vec<(String, String)> {
    let manifest: toml::Table = std::fs::read_to_string(root().join("Cargo.toml"))
        .unwrap()
        .parse()
        .unwrap();
    manifest["package"]["metadata"]["deb"]["assets"]
        .as_array()
        .expect("[package.metadata.deb] assets")
        .iter()
        .map(|a| {
            let a = a.as_array().expect("an asset is [source, destination, mode]");
            (a[0].as_str().unwrap().to_owned(), a[1].as_str().unwrap().to_owned())
        })
        .collect()
}

/// Where the package puts `source`: the destination, with a trailing `/`
/// meaning "in this directory under the same name".
fn installed_path(source: &str) -> Option<String> {
    assets()
        .into_iter()
        .find(|(s, _)| s == source)
        .map(|(s, d)| match d.strip_suffix('/') {
            Some(dir) => format!("/{dir}/{}", Path::new(&s).file_name().unwrap().to_str().unwrap()),
            None => format!("/{d}"),
        })
}

#[test]
fn package_metadata_ships_every_program_and_the_unit_finds_them() {
    let manifest: toml::Table = std::fs::read_to_string(root().join("Cargo.toml"))
        .unwrap()
        .parse()
        .unwrap();
    let bins: Vec<&str> = manifest["bin"]
        .as_array()
        .unwrap()
        .iter()
        .map(|b| b["name"].as_str().unwrap())
        .collect();
    assert!(bins.len() >= 4, "{bins:?}");
    for bin in &bins {
        assert_eq!(
            installed_path(&format!("target/release/{bin}")).as_deref(),
            Some(format!("/usr/bin/{bin}").as_str()),
            "the package does not install {bin} as /usr/bin/{bin}"
        );
    }
    for (source, _) in assets() {
        if !source.starts_with("target/") {
            assert!(root().join(&source).is_file(), "asset {source} does not exist");
        }
    }
    // Each unit runs what the package installs, on the configuration it installs.
    let units: Vec<&str> = manifest["package"]["metadata"]["deb"]["systemd-units"]
        .as_array()
        .expect("[[package.metadata.deb.systemd-units]]")
        .iter()
        .map(|u| u["unit-name"].as_str().expect("unit-name"))
        .collect();
    assert_eq!(units, UNITS, "the package's units");
    for unit_name in UNITS {
        let program = installed_path(&format!("target/release/{unit_name}")).unwrap();
        let config = installed_path(&format!("config/{unit_name}.toml"))
            .unwrap_or_else(|| panic!("{unit_name}.toml is not packaged"));
        assert_eq!(config, format!("/etc/{unit_name}/{unit_name}.toml"));
        let unit = std::fs::read_to_string(root().join(format!("config/{unit_name}.service"))).unwrap();
        for key in ["ExecStartPre=", "ExecStart="] {
            let line = unit
                .lines()
                .find(|l| l.starts_with(key))
                .unwrap_or_else(|| panic!("{unit_name}.service: no {key}"));
            let words: Vec<&str> = line[key.len()..].split_whitespace().collect();
            assert_eq!(
                words[0], program,
                "{unit_name}.service: {line}: the package installs {unit_name} as {program}"
            );
            assert!(
                words.windows(2).any(|w| w == ["--config", config.as_str()]),
                "{unit_name}.service: {line}: not {config}"
            );
        }
    }
}

use support::PACKAGED_UNITS as UNITS;

/// Runs `program args`, panicking with its output unless it succeeds.
fn run(program: &str, args: &[&std::ffi::OsStr]) -> String {
    let out = Command::new(program)
        .args(args)
        .output()
        .unwrap_or_else(|e| panic!("{program}: {e}"));
    let text = format!(
        "{}{}",
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    );
    assert!(
        out.status.success(),
        "{program} {args:?} failed ({:?}):\n{text}",
        out.status.code()
    );
    text
}

#[test]
fn the_package_holds_programs_unit_rule_and_configuration_files() {
    let probe = Command::new("cargo").args(["deb", "--version"]).output();
    if !probe.is_ok_and(|o| o.status.success()) {
        let missing = "cargo-deb not found: the Debian package is not built nor checked. Install it with \
                       `cargo install cargo-deb --locked` (./test.sh does)";
        support::tool_missing(missing);
        return;
    }
    // The programs this test run built (`cargo test --release` builds them
    // in target/release, where the package takes them from).
    let gcud = PathBuf::from(env!("CARGO_BIN_EXE_gcud"));
    if gcud.parent() != Some(&root().join("target/release")) {
        eprintln!(
            "warning: not a --release build ({}): the package is not built",
            gcud.display()
        );
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let deb = dir.path().join("sagebrush.deb");
    // README's way: debian/package.sh writes the manual pages, then cargo deb.
    let out = Command::new("bash")
        .args(["debian/package.sh", "--no-build", "--output"])
        .arg(&deb)
        .current_dir(root())
        .output()
        .expect("debian/package.sh runs");
    assert!(
        out.status.success(),
        "debian/package.sh failed:\n{}{}",
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    );

    let listing = run("dpkg-deb", &["--contents".as_ref(), deb.as_os_str()]);
    let files: Vec<&str> = listing
        .lines()
        .filter_map(|l| l.split_whitespace().nth(5))
        .map(|p| p.trim_start_matches('.'))
        .collect();
    for want in [
        "/usr/bin/gcud",
        "/usr/bin/gimbalctl",
        "/usr/bin/gimbal-onvif",
        "/usr/bin/gimbal-mavlink",
        "/usr/bin/gimbal-web",
        "/usr/bin/gimbal-mqtt",
        "/usr/bin/gimbal-visca",
        "/usr/bin/gimbal-pelco",
        "/usr/bin/gimbalsim",
        "/usr/lib/systemd/system/gcud.service",
        "/usr/lib/systemd/system/gimbal-onvif.service",
        "/usr/lib/systemd/system/gimbal-mavlink.service",
        "/usr/lib/systemd/system/gimbal-web.service",
        "/usr/lib/systemd/system/gimbal-mqtt.service",
        "/usr/lib/systemd/system/gimbal-visca.service",
        "/usr/lib/systemd/system/gimbal-pelco.service",
        "/etc/gcud/gcud.toml",
        "/etc/gimbal-onvif/gimbal-onvif.toml",
        "/etc/gimbal-mavlink/gimbal-mavlink.toml",
        "/etc/gimbal-web/gimbal-web.toml",
        "/etc/gimbal-mqtt/gimbal-mqtt.toml",
        "/etc/gimbal-visca/gimbal-visca.toml",
        "/etc/gimbal-pelco/gimbal-pelco.toml",
        "/etc/udev/rules.d/99-sagebrush-gimbal.rules",
        "/usr/share/man/man1/gcud.1.gz",
        "/usr/share/man/man1/gimbalctl.1.gz",
        "/usr/share/man/man1/gimbal-onvif.1.gz",
        "/usr/share/man/man1/gimbal-mavlink.1.gz",
        "/usr/share/man/man1/gimbal-web.1.gz",
        "/usr/share/man/man1/gimbal-mqtt.1.gz",
        "/usr/share/man/man1/gimbal-visca.1.gz",
        "/usr/share/man/man1/gimbal-pelco.1.gz",
        "/usr/share/man/man1/gimbalsim.1.gz",
        "/usr/share/doc/sagebrush/wiring.md",
        "/usr/share/doc/sagebrush/fleet.md",
    ] {
        assert!(files.contains(&want), "the package lacks {want}:\n{listing}");
    }
    // Everything under /etc is a configuration file: an edited one survives
    // an upgrade.
    let conffiles = run("dpkg-deb", &["--info".as_ref(), deb.as_os_str(), "conffiles".as_ref()]);
    for etc in files.iter().filter(|f| f.starts_with("/etc/") && !f.ends_with('/')) {
        assert!(
            conffiles.lines().any(|l| l.trim() == *etc),
            "{etc} is not a conffile:\n{conffiles}"
        );
    }
    // Installed, not enabled: the user edits gcud.toml, then `systemctl enable --now gcud`.
    let postinst = run("dpkg-deb", &["--info".as_ref(), deb.as_os_str(), "postinst".as_ref()]);
    assert!(
        !postinst.contains("systemctl --system start") && !postinst.contains("deb-systemd-invoke start"),
        "{postinst}"
    );

    let tree = dir.path().join("tree");
    run("dpkg-deb", &["--extract".as_ref(), deb.as_os_str(), tree.as_os_str()]);
    for unit in UNITS {
        assert_eq!(
            std::fs::read_to_string(tree.join(format!("usr/lib/systemd/system/{unit}.service"))).unwrap(),
            std::fs::read_to_string(root().join(format!("config/{unit}.service"))).unwrap(),
            "the packaged unit is not config/{unit}.service"
        );
    }
    // The packaged gcud accepts the packaged configuration.
    let check = run(
        tree.join("usr/bin/gcud").to_str().unwrap(),
        &[
            "--check".as_ref(),
            "--config".as_ref(),
            tree.join("etc/gcud/gcud.toml").as_os_str(),
        ],
    );
    assert!(check.contains("valid"), "{check}");
    // Each door accepts its packaged configuration as installed (no file it
    // names is missing); each listens on loopback as shipped, so --check
    // warns of neither its demo passwords nor plain HTTP (issue 49).
    for (door, warns) in [
        ("gimbal-onvif", false),
        ("gimbal-mavlink", false),
        ("gimbal-web", false),
        ("gimbal-mqtt", false),
        ("gimbal-visca", false),
        ("gimbal-pelco", false),
    ] {
        let config = tree.join(format!("etc/{door}/{door}.toml"));
        let out = Command::new(tree.join(format!("usr/bin/{door}")))
            .args(["--check".as_ref(), "--config".as_ref(), config.as_os_str()])
            .output()
            .expect("door --check");
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert_eq!(
            out.status.code(),
            Some(0),
            "{door} --check of its packaged configuration: {out:?}"
        );
        assert_eq!(stderr.contains("demo password"), warns, "{door}: {stderr}");
        assert!(!stderr.contains("plain HTTP"), "{door}: {stderr}");
    }
    // The manual pages are clap's own definitions, rendered.
    for program in [
        "gcud",
        "gimbalctl",
        "gimbal-onvif",
        "gimbal-mavlink",
        "gimbal-web",
        "gimbal-mqtt",
        "gimbal-visca",
        "gimbal-pelco",
        "gimbalsim",
    ] {
        let page = tree.join(format!("usr/share/man/man1/{program}.1.gz"));
        let roff = Command::new("sh")
            .arg("-c")
            .arg(format!("gzip -dc '{}'", page.display()))
            .output()
            .expect("gzip");
        let roff = String::from_utf8_lossy(&roff.stdout);
        assert!(roff.contains(&format!(".TH {program} 1")), "{program}.1: {roff}");
        assert!(roff.contains("\\-\\-help"), "{program}.1 has no options: {roff}");
    }
}
