//! The Debian package (`[package.metadata.deb]` in Cargo.toml, built once
//! per test run by debian/package.sh with cargo-deb): it holds every
//! program, the units of gcud and the front doors (each running the program
//! and configuration the package installs), the udev rule and the
//! configurations (those under /etc as dpkg configuration files, every
//! address in them loopback), which the packaged programs accept; a manual
//! page per program and subcommand with FILES, SIGNALS, EXIT STATUS,
//! ENVIRONMENT and SEE ALSO naming only pages that ship; bash, zsh and fish
//! completions (bash's tried); the Wireshark dissector where tshark loads
//! it (tried on a capture); the design documents and changelogs; a Depends
//! that names each library once (issue 53). Without cargo-deb the package
//! tests fail (unless SAGEBRUSH_SKIP_MISSING_TOOLS=1; .ci/run installs it).
//! .ci/run also installs the package with `dpkg -i` and checks the
//! installed units, pages and dissector.

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
        match source.strip_suffix("/*") {
            _ if source.starts_with("target/") => {}
            Some(dir) => assert!(
                std::fs::read_dir(root().join(dir)).is_ok_and(|mut d| d.next().is_some()),
                "asset {source} matches nothing"
            ),
            None => assert!(root().join(&source).is_file(), "asset {source} does not exist"),
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

/// The package this test run built once (`debian/package.sh`, as README's
/// "Install" and .ci/run do), extracted: shared by the tests below.
#[derive(Debug)]
struct Package {
    deb: PathBuf,
    /// `dpkg-deb --extract`ed.
    tree: PathBuf,
    /// Every file's absolute path in the package.
    files: Vec<String>,
    listing: String,
}

impl Package {
    /// The package, or `None` (having said why) without cargo-deb or
    /// outside a `--release` build.
    fn get() -> Option<&'static Package> {
        static PACKAGE: std::sync::OnceLock<Option<Package>> = std::sync::OnceLock::new();
        PACKAGE.get_or_init(Package::build).as_ref()
    }

    fn build() -> Option<Package> {
        let probe = Command::new("cargo").args(["deb", "--version"]).output();
        if !probe.is_ok_and(|o| o.status.success()) {
            let missing = "cargo-deb not found: the Debian package is not built nor checked. Install it with \
                           `cargo install cargo-deb --locked` (.ci/run does)";
            support::tool_missing(missing);
            return None;
        }
        // The programs this test run built (`cargo test --release` builds
        // them in target/release, where the package takes them from).
        let gcud = PathBuf::from(env!("CARGO_BIN_EXE_gcud"));
        if gcud.parent() != Some(&root().join("target/release")) {
            eprintln!(
                "warning: not a --release build ({}): the package is not built",
                gcud.display()
            );
            return None;
        }
        let dir = root().join("target/packaging-test");
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(&dir).unwrap();
        let deb = dir.join("sagebrush.deb");
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
        let files = listing
            .lines()
            .filter_map(|l| l.split_whitespace().nth(5))
            .map(|p| p.trim_start_matches('.').to_owned())
            .collect();
        let tree = dir.join("tree");
        run("dpkg-deb", &["--extract".as_ref(), deb.as_os_str(), tree.as_os_str()]);
        Some(Package {
            deb,
            tree,
            files,
            listing,
        })
    }

    fn has(&self, path: &str) -> bool {
        self.files.iter().any(|f| f == path)
    }

    fn assert_has(&self, path: &str) {
        assert!(self.has(path), "the package lacks {path}:\n{}", self.listing);
    }

    /// A control field (`Version`, `Depends`).
    fn field(&self, name: &str) -> String {
        run("dpkg-deb", &["--field".as_ref(), self.deb.as_os_str(), name.as_ref()])
            .trim()
            .to_owned()
    }

    /// A file of the package, gunzipped when it ends in `.gz`.
    fn read(&self, path: &str) -> String {
        let file = self.tree.join(path.trim_start_matches('/'));
        let bytes = if path.ends_with(".gz") {
            let out = Command::new("gzip").arg("-dc").arg(&file).output().expect("gzip");
            assert!(out.status.success(), "gzip -dc {}: {out:?}", file.display());
            out.stdout
        } else {
            std::fs::read(&file).unwrap_or_else(|e| panic!("{}: {e}", file.display()))
        };
        String::from_utf8(bytes).unwrap_or_else(|e| panic!("{path}: {e}"))
    }
}

/// The package's programs: Cargo.toml's `[[bin]]` names.
fn programs() -> Vec<String> {
    let manifest: toml::Table = std::fs::read_to_string(root().join("Cargo.toml"))
        .unwrap()
        .parse()
        .unwrap();
    manifest["bin"]
        .as_array()
        .unwrap()
        .iter()
        .map(|b| b["name"].as_str().unwrap().to_owned())
        .collect()
}

#[test]
fn the_package_holds_programs_unit_rule_and_configuration_files() {
    let Some(package) = Package::get() else { return };
    for program in programs() {
        package.assert_has(&format!("/usr/bin/{program}"));
    }
    for unit in UNITS {
        package.assert_has(&format!("/usr/lib/systemd/system/{unit}.service"));
        package.assert_has(&format!("/etc/{unit}/{unit}.toml"));
    }
    package.assert_has("/etc/udev/rules.d/99-sagebrush-gimbal.rules");
    // Everything under /etc is a configuration file: an edited one survives
    // an upgrade.
    let deb = package.deb.as_os_str();
    let conffiles = run("dpkg-deb", &["--info".as_ref(), deb, "conffiles".as_ref()]);
    for etc in package
        .files
        .iter()
        .filter(|f| f.starts_with("/etc/") && !f.ends_with('/'))
    {
        assert!(
            conffiles.lines().any(|l| l.trim() == etc),
            "{etc} is not a conffile:\n{conffiles}"
        );
    }
    // Installed, not enabled: the user edits gcud.toml, then `systemctl enable --now gcud`.
    let postinst = run("dpkg-deb", &["--info".as_ref(), deb, "postinst".as_ref()]);
    assert!(
        !postinst.contains("systemctl --system start") && !postinst.contains("deb-systemd-invoke start"),
        "{postinst}"
    );
    for unit in UNITS {
        assert_eq!(
            package.read(&format!("/usr/lib/systemd/system/{unit}.service")),
            std::fs::read_to_string(root().join(format!("config/{unit}.service"))).unwrap(),
            "the packaged unit is not config/{unit}.service"
        );
    }
    // The packaged gcud accepts the packaged configuration.
    let tree = &package.tree;
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
    for door in UNITS.iter().filter(|u| **u != "gcud") {
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
        assert!(!stderr.contains("demo password"), "{door}: {stderr}");
        assert!(!stderr.contains("plain HTTP"), "{door}: {stderr}");
    }
}

/// Every address in a shipped configuration (a string value that is an
/// IP:PORT, at any depth) is a loopback one: nothing listens on, or
/// connects to, the LAN until the operator says so.
#[test]
fn the_shipped_configurations_name_loopback_addresses_only() {
    let Some(package) = Package::get() else { return };
    fn addresses(value: &toml::Value, key: &str, out: &mut Vec<(String, std::net::SocketAddr)>) {
        match value {
            toml::Value::String(s) => {
                if let Ok(addr) = s.parse() {
                    out.push((key.to_owned(), addr));
                }
            }
            toml::Value::Array(items) => items.iter().for_each(|v| addresses(v, key, out)),
            toml::Value::Table(table) => table.iter().for_each(|(k, v)| addresses(v, &format!("{key}.{k}"), out)),
            _ => {}
        }
    }
    let mut checked = 0;
    for file in package
        .files
        .iter()
        .filter(|f| f.starts_with("/etc/") && f.ends_with(".toml"))
    {
        let table: toml::Value = toml::from_str(&package.read(file)).unwrap_or_else(|e| panic!("{file}: {e}"));
        let mut found = Vec::new();
        addresses(&table, "", &mut found);
        for (key, addr) in &found {
            assert!(
                addr.ip().is_loopback(),
                "{file}: {key} = {addr} is not a loopback address"
            );
        }
        checked += found.len();
    }
    assert!(checked >= 8, "only {checked} addresses in the shipped configurations");
}

/// The `.SH` sections of a manual page, in order.
fn sections(roff: &str) -> Vec<String> {
    roff.lines()
        .filter_map(|l| l.strip_prefix(".SH "))
        .map(|s| s.trim().trim_matches('"').to_owned())
        .collect()
}

/// The text of one section of a page (up to the next `.SH`).
fn section<'a>(roff: &'a str, name: &str) -> &'a str {
    let start = roff
        .find(&format!(".SH {name}\n"))
        .or_else(|| roff.find(&format!(".SH \"{name}\"\n")))
        .unwrap_or_else(|| panic!("no section {name}"));
    let rest = &roff[start + 4..];
    &rest[..rest.find("\n.SH ").unwrap_or(rest.len())]
}

/// Every `name(N)` a page refers to, roff's `\-` read as `-`.
fn page_references(roff: &str) -> Vec<String> {
    let text = roff.replace("\\-", "-");
    let bytes = text.as_bytes();
    let mut refs = Vec::new();
    for (i, _) in text.match_indices('(') {
        let digit = bytes.get(i + 1).is_some_and(u8::is_ascii_digit) && bytes.get(i + 2) == Some(&b')');
        let start = text[..i]
            .rfind(|c: char| !(c.is_ascii_alphanumeric() || "-_.".contains(c)))
            .map_or(0, |p| p + 1);
        if digit && start < i {
            refs.push(format!("{}({})", &text[start..i], bytes[i + 1] as char));
        }
    }
    refs
}

#[test]
fn every_manual_page_has_its_sections_and_names_only_pages_that_ship() {
    let Some(package) = Package::get() else { return };
    let pages: Vec<&String> = package
        .files
        .iter()
        .filter(|f| f.starts_with("/usr/share/man/man") && f.ends_with(".gz"))
        .collect();
    for program in programs() {
        package.assert_has(&format!("/usr/share/man/man1/{program}.1.gz"));
    }
    let shipped = |reference: &str| {
        let (name, rest) = reference.split_once('(').unwrap();
        let n = rest.trim_end_matches(')');
        package.has(&format!("/usr/share/man/man{n}/{name}.{n}.gz"))
    };
    let mut names = std::collections::BTreeMap::new();
    for page in &pages {
        let roff = package.read(page);
        let have = sections(&roff);
        for want in [
            "NAME",
            "SYNOPSIS",
            "DESCRIPTION",
            "FILES",
            "SIGNALS",
            "EXIT STATUS",
            "ENVIRONMENT",
            "SEE ALSO",
        ] {
            assert!(have.iter().any(|s| s == want), "{page} has no {want} section: {have:?}");
        }
        let see_also = page_references(section(&roff, "SEE ALSO"));
        assert!(!see_also.is_empty(), "{page}: SEE ALSO names no page");
        for reference in page_references(&roff) {
            assert!(
                shipped(&reference),
                "{page} refers to {reference}, which the package does not ship"
            );
        }
        // A page's NAME line is its own (not a flattened struct's doc).
        let name = section(&roff, "NAME").lines().nth(1).unwrap_or_default().to_owned();
        let summary = name.split_once("\\- ").map(|(_, s)| s.to_owned()).unwrap_or_default();
        assert!(!summary.is_empty(), "{page}: NAME has no summary: {name:?}");
        if let Some(other) = names.insert(summary.clone(), page.as_str()) {
            panic!("{page} and {other} share the NAME summary {summary:?}");
        }
        assert!(
            !roff.contains("config/gcud.toml") || roff.contains("/etc/gcud/gcud.toml"),
            "{page}"
        );
    }
    // gimbalctl's subcommands have their own pages, at every depth.
    package.assert_has("/usr/share/man/man1/gimbalctl-goto.1.gz");
    package.assert_has("/usr/share/man/man1/gimbalctl-preset-recall.1.gz");
    assert!(pages.len() > 40, "only {} pages", pages.len());
    manual_page_contents(package);
}

/// What the main pages say in their own sections: the installed files,
/// the signals each program handles, gimbalctl's every exit code and its
/// environment variables.
fn manual_page_contents(package: &Package) {
    let page = |program: &str| {
        package
            .read(&format!("/usr/share/man/man1/{program}.1.gz"))
            .replace("\\-", "-")
    };
    for program in UNITS {
        let roff = page(program);
        let files = section(&roff, "FILES");
        for path in [
            format!("/etc/{program}/{program}.toml"),
            format!("/usr/lib/systemd/system/{program}.service"),
        ] {
            assert!(files.contains(&path), "{program}.1 FILES lacks {path}:\n{files}");
        }
        let signals = section(&roff, "SIGNALS");
        for signal in ["SIGHUP", "SIGUSR1", "SIGTERM"] {
            assert!(
                signals.contains(signal),
                "{program}.1 SIGNALS lacks {signal}:\n{signals}"
            );
        }
        assert!(section(&roff, "ENVIRONMENT").contains("RUST_LOG"), "{program}.1");
    }
    let gcud = page("gcud");
    assert!(section(&gcud, "SIGNALS").contains("Reload the configuration"), "{gcud}");
    let ctl = page("gimbalctl");
    let exit_status = section(&ctl, "EXIT STATUS");
    let codes: Vec<u32> = exit_status
        .split(|c: char| !c.is_ascii_digit())
        .filter_map(|w| w.parse().ok())
        .collect();
    for code in (0..=32).chain([130, 143]) {
        assert!(
            codes.contains(&code),
            "gimbalctl.1 EXIT STATUS lacks {code}:\n{exit_status}"
        );
    }
    let environment = section(&ctl, "ENVIRONMENT");
    for var in [
        "GIMBALCTL_SERIAL",
        "GIMBALCTL_TCP",
        "GIMBALCTL_TLS_CA",
        "GIMBALCTL_TLS_CERT",
        "GIMBALCTL_TLS_KEY",
        "RUST_LOG",
    ] {
        assert!(
            environment.contains(var),
            "gimbalctl.1 ENVIRONMENT lacks {var}:\n{environment}"
        );
    }
}

/// `PROGRAM -h`'s "Commands:" list, `help` aside.
fn subcommands(program: &Path, path: &[&str]) -> Vec<String> {
    let out = Command::new(program).args(path).arg("-h").output().expect("-h");
    String::from_utf8_lossy(&out.stdout)
        .lines()
        .skip_while(|l| *l != "Commands:")
        .skip(1)
        .take_while(|l| !l.trim().is_empty())
        .filter_map(|l| l.split_whitespace().next().map(str::to_owned))
        .filter(|name| name != "help")
        .collect()
}

/// What bash completes for `words` (the last being the one typed), with
/// the packaged completion script of `program` loaded.
fn bash_completes(script: &Path, program: &str, words: &[&str]) -> Vec<String> {
    let line: Vec<String> = std::iter::once(program)
        .chain(words.iter().copied())
        .map(|w| format!("'{w}'"))
        .collect();
    // The function the script registers for the program (`complete -F`).
    let probe = format!(
        "source '{}'; f=$(complete -p {program} | sed -n 's/.* -F \\([^ ]*\\) .*/\\1/p'); \
         COMP_WORDS=({}); COMP_CWORD={}; COMP_LINE=\"${{COMP_WORDS[*]}}\"; COMP_POINT=${{#COMP_LINE}}; \
         \"$f\" {program} \"${{COMP_WORDS[COMP_CWORD]}}\" \"${{COMP_WORDS[COMP_CWORD-1]}}\"; printf '%s\\n' \"${{COMPREPLY[@]}}\"",
        script.display(),
        line.join(" "),
        words.len(),
    );
    let out = Command::new("bash")
        .args(["--norc", "-c", &probe])
        .output()
        .expect("bash");
    assert!(out.status.success(), "bash completion of {program} {words:?}: {out:?}");
    String::from_utf8_lossy(&out.stdout)
        .lines()
        .map(str::to_owned)
        .collect()
}

#[test]
fn every_program_has_bash_zsh_and_fish_completions_that_know_its_subcommands() {
    let Some(package) = Package::get() else { return };
    for program in programs() {
        let bash = format!("/usr/share/bash-completion/completions/{program}");
        for path in [
            bash.clone(),
            format!("/usr/share/zsh/vendor-completions/_{program}"),
            format!("/usr/share/fish/vendor_completions.d/{program}.fish"),
        ] {
            package.assert_has(&path);
            assert!(package.read(&path).contains(program.as_str()), "{path}");
        }
        let binary = package.tree.join(format!("usr/bin/{program}"));
        let script = package.tree.join(bash.trim_start_matches('/'));
        // bash completes each subcommand from its first letters, and each
        // nested one (`preset re` -> recall) after its parent.
        for sub in subcommands(&binary, &[]) {
            let typed = &sub[..2.min(sub.len())];
            let offered = bash_completes(&script, &program, &[typed]);
            assert!(
                offered.contains(&sub),
                "`{program} {typed}<TAB>` offers {offered:?}, not {sub}"
            );
            for nested in subcommands(&binary, &[&sub]) {
                let offered = bash_completes(&script, &program, &[&sub, ""]);
                assert!(
                    offered.contains(&nested),
                    "`{program} {sub} <TAB>` offers {offered:?}, not {nested}"
                );
            }
        }
    }
    // Long options too: `gimbalctl --tls-<TAB>`.
    let script = package.tree.join("usr/share/bash-completion/completions/gimbalctl");
    let offered = bash_completes(&script, "gimbalctl", &["--tls-"]);
    for option in ["--tls-ca", "--tls-cert", "--tls-key"] {
        assert!(offered.iter().any(|o| o == option), "{offered:?}");
    }
}

/// The design documents, both changelogs and the examples, under
/// /usr/share/doc/sagebrush; the Debian changelog names the package's version.
#[test]
fn the_package_ships_the_documents_and_changelogs() {
    let Some(package) = Package::get() else { return };
    let doc = "/usr/share/doc/sagebrush";
    for file in [
        "README.md",
        "ARCHITECTURE.md",
        "CHANGELOG.md",
        "copyright",
        "examples/demo.toml",
    ] {
        package.assert_has(&format!("{doc}/{file}"));
    }
    for entry in std::fs::read_dir(root().join("docs")).unwrap() {
        let name = entry.unwrap().file_name();
        package.assert_has(&format!("{doc}/docs/{}", name.to_string_lossy()));
    }
    let changelog = package.read(&format!("{doc}/changelog.Debian.gz"));
    let version = package.field("Version");
    assert!(
        changelog.starts_with(&format!("sagebrush ({version}) ")),
        "changelog.Debian.gz does not begin with this version ({version}):\n{changelog}"
    );
    let summary = package.read(&format!("{doc}/CHANGELOG.md"));
    let upstream = version.split('-').next().unwrap();
    assert!(
        summary.contains(&format!("## {upstream}")),
        "CHANGELOG.md has no {upstream}"
    );
}

/// Depends lists each package once, as dpkg-shlibdeps finds it for all
/// the packaged programs together (cargo-deb's "$auto" gave libc6 twice).
#[test]
fn depends_lists_each_library_once_as_dpkg_shlibdeps_finds_it() {
    let Some(package) = Package::get() else { return };
    let depends = package.field("Depends");
    let names: Vec<&str> = depends
        .split(',')
        .map(|d| d.split_whitespace().next().unwrap_or_default())
        .collect();
    let mut unique = names.clone();
    unique.sort_unstable();
    unique.dedup();
    assert_eq!(names.len(), unique.len(), "Depends lists a package twice: {depends}");
    assert!(names.contains(&"libc6"), "{depends}");
    let work = tempfile::tempdir().unwrap();
    std::fs::create_dir(work.path().join("debian")).unwrap();
    std::fs::write(work.path().join("debian/control"), "").unwrap();
    let binaries: Vec<PathBuf> = programs()
        .iter()
        .map(|p| package.tree.join(format!("usr/bin/{p}")))
        .collect();
    let out = Command::new("dpkg-shlibdeps")
        .arg("-O")
        .args(&binaries)
        .current_dir(work.path())
        .output()
        .expect("dpkg-shlibdeps (dpkg-dev)");
    let found = String::from_utf8_lossy(&out.stdout);
    let found = found
        .trim()
        .strip_prefix("shlibs:Depends=")
        .unwrap_or_else(|| panic!("{out:?}"));
    assert_eq!(depends, found, "Depends is not what the programs need");
}

/// The dissector lies where tshark looks for Lua plugins for all users
/// (`tshark -G folders`, "Global Lua Plugins", subfolders one deep), and
/// tshark decodes a capture with the package's folder, with no `-X
/// lua_script`: as a personal plugin folder (tshark loads both kinds
/// alike, and the global one is the system's), or, where the package is
/// installed (after .ci/run's `dpkg -i`), from the global one itself.
/// .ci/run decodes target/packaging-test/sample.pcapng after `dpkg -i`.
#[test]
fn tshark_decodes_a_capture_with_the_packaged_dissector() {
    let Some(package) = Package::get() else { return };
    support::capture::require_tshark();
    let lua: Vec<&String> = package.files.iter().filter(|f| f.ends_with(".lua")).collect();
    let plugin = lua
        .iter()
        .find(|f| f.ends_with("/sagebrush/sagebrush.lua"))
        .unwrap_or_else(|| panic!("no sagebrush.lua in the package:\n{}", package.listing));
    assert!(
        lua.iter().any(|f| f.ends_with("/sagebrush/sagebrush_tables.lua")),
        "{lua:?}"
    );
    let folders = run("tshark", &["-G".as_ref(), "folders".as_ref()]);
    let global = folders
        .lines()
        .find_map(|l| l.strip_prefix("Global Lua Plugins:"))
        .map(str::trim)
        .unwrap_or_else(|| panic!("tshark -G folders: {folders}"));
    assert_eq!(
        plugin.as_str(),
        format!("{global}/sagebrush/sagebrush.lua"),
        "tshark loads Lua plugins for all users from {global}"
    );
    let capture = package.tree.with_file_name("sample.pcapng");
    write_sample_capture(&capture);
    let home = tempfile::tempdir().unwrap();
    let installed = Path::new(plugin.as_str()).is_file();
    if !installed {
        let personal = home.path().join(".local/lib/wireshark/plugins");
        std::fs::create_dir_all(&personal).unwrap();
        let packaged = package.tree.join(global.trim_start_matches('/')).join("sagebrush");
        std::os::unix::fs::symlink(packaged, personal.join("sagebrush")).unwrap();
    }
    let out = Command::new("tshark")
        .env("HOME", home.path())
        .env_remove("XDG_CONFIG_HOME")
        .arg("-r")
        .arg(&capture)
        .args([
            "-T",
            "fields",
            "-E",
            "separator=|",
            "-e",
            "sagebrush.type",
            "-e",
            "sagebrush.payload",
        ])
        .output()
        .expect("tshark");
    let rows = String::from_utf8_lossy(&out.stdout);
    assert!(out.status.success(), "tshark: {out:?}");
    let from = if installed { "installed" } else { "packaged" };
    assert!(
        rows.lines().any(|r| r == "command|P?") && rows.lines().any(|r| r == "result|00640000"),
        "tshark did not decode with the {from} plugin:\n{rows}\n{}",
        String::from_utf8_lossy(&out.stderr)
    );
}

/// A capture as gcud writes it (`sagebrush_host::capture`): a master's
/// `P?` to 5.1.1, its ACK and the position result.
fn write_sample_capture(path: &Path) {
    use sagebrush_host::capture::{Capture, CaptureConfig, Direction, Role};
    use sagebrush_protocol::{ACK, Address, Frame};
    use std::time::{Duration, SystemTime};

    let frame = |dest: Address, source: u8, payload: &str| {
        let mut buf = [0u8; 64];
        let frame = Frame::new(dest, source, payload.as_bytes()).expect("frame");
        frame.encode(&mut buf).expect("encode").to_vec()
    };
    let capture = Capture::open(path, CaptureConfig::default()).expect("open capture");
    let port = capture.interface("port 1", Role::Master);
    let at = |ms: u64| SystemTime::UNIX_EPOCH + Duration::from_secs(1_000_000) + Duration::from_millis(ms);
    capture.record(port, Direction::Outbound, at(0), &frame(Address::new(5, 1, 1), 0, "P?"));
    capture.record(port, Direction::Inbound, at(20), &[ACK]);
    capture.record(
        port,
        Direction::Inbound,
        at(40),
        &frame(Address::new(0, 1, 1), 5, "00640000"),
    );
    capture.record(port, Direction::Outbound, at(60), &[ACK]);
    capture.stop(Duration::from_secs(10));
}
