//! The repository's documentation stands on its own: nothing points outside
//! it, every citation of the project's design notes or protocol notes names
//! a section that exists, every relative Markdown link resolves, and what the
//! protocol crate's README says about itself (MSRV, features, rustdoc,
//! doctests) is true. Checked over the files git tracks, so a user's clone
//! sees what this sees.

use std::collections::BTreeSet;
use std::path::Path;
use std::process::Command;

const ROOT: &str = env!("CARGO_MANIFEST_DIR");
/// This file spells the patterns it looks for.
const SELF: &str = "tests/docs.rs";
/// Where `protocol-notes E<n>` and `protocol-notes "<section>"` point.
const NOTES: &str = "docs/protocol-notes.md";
/// Where `ARCHITECTURE "<section>"` points.
const DESIGN: &str = "ARCHITECTURE.md";
/// The protocol crate's README, also its rustdoc front page.
const CRATE_README: &str = "crates/protocol/README.md";

fn read(file: &str) -> String {
    std::fs::read_to_string(Path::new(ROOT).join(file)).unwrap_or_else(|e| panic!("{file}: {e}"))
}

/// Tracked text files of the kinds that carry docs and citations.
fn tracked() -> Vec<(String, String)> {
    let out = Command::new("git")
        .args(["ls-files"])
        .current_dir(ROOT)
        .output()
        .expect("git ls-files");
    assert!(out.status.success(), "git ls-files failed");
    let kinds = [".md", ".rs", ".toml", ".lua", ".sh", ".service", ".rules"];
    String::from_utf8_lossy(&out.stdout)
        .lines()
        .filter(|f| *f != SELF && kinds.iter().any(|k| f.ends_with(k)))
        .filter_map(|f| Some((f.to_owned(), std::fs::read_to_string(Path::new(ROOT).join(f)).ok()?)))
        .collect()
}

/// The lines of a Markdown text outside fenced code blocks, numbered from 1.
fn prose(text: &str) -> Vec<(usize, &str)> {
    let mut fenced = false;
    let mut lines = Vec::new();
    for (n, line) in text.lines().enumerate() {
        if line.trim_start().starts_with("```") {
            fenced = !fenced;
        } else if !fenced {
            lines.push((n + 1, line));
        }
    }
    lines
}

/// The headings of a Markdown file, lower case, without the `#`s.
fn headings(file: &str) -> Vec<String> {
    prose(&read(file))
        .into_iter()
        .filter(|(_, l)| l.starts_with('#'))
        .map(|(_, l)| l.trim_start_matches('#').trim().to_lowercase())
        .collect()
}

/// Whether a cited section names a heading: the whole heading, or its
/// beginning up to a word boundary ("Delivery contract" names "Delivery
/// contract (what a client of gcud can believe)"; "Safe" names nothing).
fn names_heading(headings: &[String], section: &str) -> bool {
    let section = section.to_lowercase();
    headings.iter().any(|h| {
        h.strip_prefix(&section)
            .is_some_and(|rest| rest.chars().next().is_none_or(|c| !c.is_alphanumeric()))
    })
}

/// Every `<prefix> "<name>"` or `<prefix> '<name>'` in `text`, with its line
/// number (a name in angle brackets is a placeholder in prose, not a
/// citation, and is left out).
fn quoted_after<'a>(text: &'a str, prefix: &str) -> Vec<(usize, &'a str)> {
    let mut found = Vec::new();
    for (n, line) in text.lines().enumerate() {
        let mut rest = line;
        while let Some(at) = rest.find(prefix) {
            rest = &rest[at + prefix.len()..];
            let Some(quote) = rest.chars().next().filter(|c| *c == '"' || *c == '\'') else {
                continue;
            };
            let name = rest[1..].split(quote).next().unwrap_or_default();
            if !name.starts_with('<') {
                found.push((n + 1, name));
            }
        }
    }
    found
}

/// Every erratum cited as `<prefix>E<n>` in `text`, lists included
/// (`E1, E6`, `E3-E7`, `E8 and E12`, `E2/E3`), with its line number, as
/// `e<n>` (a heading's lower-case form).
fn errata_after(text: &str, prefix: &str) -> Vec<(usize, String)> {
    let mut found = Vec::new();
    for (n, line) in text.lines().enumerate() {
        let mut rest = line;
        while let Some(at) = rest.find(prefix) {
            rest = &rest[at + prefix.len()..];
            let mut list = rest;
            while let Some(digits) = list.strip_prefix('E') {
                let number: String = digits.chars().take_while(char::is_ascii_digit).collect();
                if number.is_empty() {
                    break;
                }
                found.push((n + 1, format!("e{number}")));
                list = &digits[number.len()..];
                let Some(next) = [", ", ",", "-", "..", "/", " and ", " or "]
                    .iter()
                    .find_map(|sep| list.strip_prefix(sep))
                else {
                    break;
                };
                list = next;
            }
        }
    }
    found
}

/// Every relative link target `](target)` on the prose lines of a Markdown
/// text (outside code blocks), with its line number.
fn relative_links(text: &str) -> Vec<(usize, &str)> {
    let mut found = Vec::new();
    for (n, line) in prose(text) {
        let mut rest = line;
        while let Some(at) = rest.find("](") {
            rest = &rest[at + 2..];
            let target = rest.split(')').next().unwrap_or_default();
            // `](<path> "title")`: the path alone.
            let target = target.split_whitespace().next().unwrap_or_default();
            let target = target.trim_start_matches('<').trim_end_matches('>');
            let external = target.contains("://") || target.starts_with("mailto:") || target.starts_with('#');
            if !external && !target.is_empty() {
                found.push((n, target));
            }
        }
    }
    found
}

/// What is wrong with the tracked files, as `file:line: why`.
fn problems() -> Vec<String> {
    let files = tracked();
    let notes = headings(NOTES);
    let design = headings(DESIGN);
    let mut problems = Vec::new();
    for (file, text) in &files {
        for (n, line) in text.lines().enumerate() {
            for outside in ["../shared", "shared/spec", "shared/DESIGN"] {
                if line.contains(outside) {
                    problems.push(format!("{file}:{}: points outside the repository ({outside})", n + 1));
                }
            }
        }
        for (n, old) in quoted_after(text, "DESIGN ") {
            problems.push(format!(
                "{file}:{n}: cites DESIGN \"{old}\", a file outside the repository (cite ARCHITECTURE \"<section>\")"
            ));
        }
        for (n, old) in errata_after(text, "NOTES ") {
            problems.push(format!(
                "{file}:{n}: cites NOTES {}, a file outside the repository (cite protocol-notes E<n>)",
                old.to_uppercase()
            ));
        }
        for (n, number) in errata_after(text, "protocol-notes ") {
            if !notes.contains(&number) {
                problems.push(format!(
                    "{file}:{n}: protocol-notes {} has no heading in {NOTES}",
                    number.to_uppercase()
                ));
            }
        }
        for (n, section) in quoted_after(text, "protocol-notes ") {
            if !names_heading(&notes, section) {
                problems.push(format!(
                    "{file}:{n}: protocol-notes \"{section}\" has no heading in {NOTES}"
                ));
            }
        }
        for (n, section) in quoted_after(text, "ARCHITECTURE ") {
            if !names_heading(&design, section) {
                problems.push(format!(
                    "{file}:{n}: ARCHITECTURE \"{section}\" has no heading in {DESIGN}"
                ));
            }
        }
        if file.ends_with(".md") {
            let dir = Path::new(file).parent().unwrap_or(Path::new(""));
            for (n, target) in relative_links(text) {
                let path = target.split('#').next().unwrap_or_default();
                if !path.is_empty() && !Path::new(ROOT).join(dir).join(path).exists() {
                    problems.push(format!("{file}:{n}: link to {target} does not resolve"));
                }
            }
        }
    }
    problems
}

#[test]
fn the_docs_stand_on_their_own() {
    let problems = problems();
    assert!(problems.is_empty(), "{}", problems.join("\n"));
}

#[test]
fn every_erratum_has_its_section() {
    let notes: BTreeSet<String> = headings(NOTES).into_iter().collect();
    for n in 1..=15 {
        assert!(notes.contains(&format!("e{n}")), "{NOTES} has no ### E{n}");
    }
    for section in ["framing", "command disambiguation", "parse leniently"] {
        assert!(notes.contains(section), "{NOTES} has no {section} section");
    }
}

/// The protocol crate's README is its rustdoc front page, says the MSRV
/// and features the manifests declare, and every code block in it is
/// either a doctest that runs or tagged as another language.
#[test]
fn the_crate_readme_tells_the_truth() {
    let readme = read(CRATE_README);
    let mut problems = Vec::new();

    let lib = read("crates/protocol/src/lib.rs");
    if !lib.contains("#![doc = include_str!(\"../README.md\")]") {
        problems.push("crates/protocol/src/lib.rs: the README is not the crate's rustdoc".to_owned());
    }

    let workspace: toml::Table = read("Cargo.toml").parse().expect("Cargo.toml");
    let msrv = workspace["workspace"]["package"]["rust-version"]
        .as_str()
        .expect("workspace.package.rust-version");
    if !readme.contains(&format!("**MSRV**: Rust {msrv} ")) {
        problems.push(format!(
            "{CRATE_README}: no \"**MSRV**: Rust {msrv} \" (the workspace's rust-version)"
        ));
    }

    // Cargo features: the [features] table and every optional dependency.
    let manifest: toml::Table = read("crates/protocol/Cargo.toml").parse().expect("protocol Cargo.toml");
    let mut features: Vec<String> = manifest
        .get("features")
        .and_then(toml::Value::as_table)
        .map(|t| t.keys().cloned().collect())
        .unwrap_or_default();
    for deps in ["dependencies", "build-dependencies"] {
        for (name, dep) in manifest.get(deps).and_then(toml::Value::as_table).into_iter().flatten() {
            if dep.get("optional").and_then(toml::Value::as_bool) == Some(true) {
                features.push(name.clone());
            }
        }
    }
    let said = readme
        .lines()
        .find(|l| l.contains("**Features**"))
        .unwrap_or_else(|| panic!("{CRATE_README}: no **Features** item"));
    if features.is_empty() && !said.contains("**Features**: none") {
        problems.push(format!(
            "{CRATE_README}: the crate has no cargo features; say \"**Features**: none\""
        ));
    }
    if !features.is_empty() && said.contains("**Features**: none") {
        problems.push(format!("{CRATE_README}: says no features, Cargo.toml has {features:?}"));
    }
    for feature in features.iter().filter(|f| !readme.contains(&format!("`{f}`"))) {
        problems.push(format!("{CRATE_README}: cargo feature `{feature}` is not described"));
    }

    // Code blocks: a language on every block; Rust runs (no `ignore`).
    let mut fenced = false;
    for (n, line) in readme.lines().enumerate() {
        let Some(info) = line.trim_start().strip_prefix("```") else {
            continue;
        };
        fenced = !fenced;
        if !fenced {
            continue;
        }
        let info = info.trim();
        if info.is_empty() {
            problems.push(format!(
                "{CRATE_README}:{}: a code block without a language is a Rust doctest; tag it",
                n + 1
            ));
        }
        if info.split(',').any(|a| a.trim() == "ignore") {
            problems.push(format!("{CRATE_README}:{}: an ignored doctest", n + 1));
        }
    }

    // Rustdoc renders the README outside the repository: a relative link
    // there points nowhere.
    for (n, target) in relative_links(&readme) {
        problems.push(format!(
            "{CRATE_README}:{n}: relative link {target} breaks in rustdoc (use plain text or a full URL)"
        ));
    }

    assert!(problems.is_empty(), "{}", problems.join("\n"));
}

/// The texts a user reads for which way a gimbal turns: the Markdown docs,
/// the shipped configurations' comments and every program's help.
fn direction_texts() -> Vec<(String, String)> {
    let mut texts: Vec<(String, String)> = tracked()
        .into_iter()
        .filter(|(f, _)| {
            (f.ends_with(".md") && !f.starts_with("crates/protocol/CHANGELOG"))
                || (f.starts_with("config/") && f.ends_with(".toml"))
        })
        .map(|(f, t)| {
            let prose = if f.ends_with(".md") {
                prose(&t).into_iter().map(|(_, l)| l).collect::<Vec<_>>().join("\n")
            } else {
                t
            };
            (f, prose)
        })
        .collect();
    for (bin, exe) in [
        ("gcud", env!("CARGO_BIN_EXE_gcud")),
        ("gimbalctl", env!("CARGO_BIN_EXE_gimbalctl")),
        ("gimbal-onvif", env!("CARGO_BIN_EXE_gimbal-onvif")),
        ("gimbal-mavlink", env!("CARGO_BIN_EXE_gimbal-mavlink")),
        ("gimbal-web", env!("CARGO_BIN_EXE_gimbal-web")),
        ("gimbal-mqtt", env!("CARGO_BIN_EXE_gimbal-mqtt")),
        ("gimbal-visca", env!("CARGO_BIN_EXE_gimbal-visca")),
        ("gimbal-pelco", env!("CARGO_BIN_EXE_gimbal-pelco")),
        ("gimbalsim", env!("CARGO_BIN_EXE_gimbalsim")),
    ] {
        help_texts(bin, exe, &mut Vec::new(), &mut texts);
    }
    texts
}

/// `exe [path..] --help` and, recursively (two levels at most), every
/// subcommand's help listed under its "Commands:".
fn help_texts(bin: &str, exe: &str, path: &mut Vec<String>, texts: &mut Vec<(String, String)>) {
    let out = Command::new(exe)
        .args(path.iter())
        .arg("--help")
        .output()
        .expect("run --help");
    assert!(out.status.success(), "{bin} {} --help failed", path.join(" "));
    let help = String::from_utf8_lossy(&out.stdout).into_owned();
    let subcommands: Vec<String> = help
        .split("Commands:")
        .nth(1)
        .map(|rest| {
            rest.lines()
                .skip(1)
                .take_while(|l| l.starts_with("  "))
                .filter_map(|l| l.split_whitespace().next().map(str::to_owned))
                .filter(|c| c != "help")
                .collect()
        })
        .unwrap_or_default();
    texts.push((format!("`{bin} {} --help`", path.join(" ")), help));
    if path.len() < 2 {
        for c in subcommands {
            path.push(c);
            help_texts(bin, exe, path, texts);
            path.pop();
        }
    }
}

/// The sentences of a text (table rows count as one each), whitespace
/// folded, lower case.
fn sentences(text: &str) -> Vec<String> {
    let mut found = Vec::new();
    for paragraph in text.split("\n\n") {
        let mut current = String::new();
        for line in paragraph.lines() {
            if line.trim_start().starts_with('|') {
                found.push(line.to_lowercase());
                continue;
            }
            for word in line.split_whitespace() {
                if !current.is_empty() {
                    current.push(' ');
                }
                current.push_str(&word.to_lowercase());
                if word.ends_with(['.', '!', '?', ';']) {
                    found.push(std::mem::take(&mut current));
                }
            }
        }
        if !current.is_empty() {
            found.push(current);
        }
    }
    found
}

/// What a sentence says wrong about the turning sense, if anything
/// (protocol-notes "Directions, in one place"): the spec calls positive pan
/// counter-clockwise, which is clockwise seen from above, so a bare
/// "clockwise" is ambiguous, and "counter-clockwise seen from above" for
/// positive or right is the other direction.
fn direction_problem(sentence: &str) -> Option<&'static str> {
    let s = sentence.replace("counterclockwise", "counter-clockwise");
    if !s.contains("clockwise") {
        return None;
    }
    let from_above = s.contains("seen from above");
    if !from_above && !s.contains("spec") {
        return Some("a bare clockwise/counter-clockwise: say \"seen from above\" or that it is the spec's word");
    }
    let right_or_positive = ["right", "positive", "+"].iter().any(|w| s.contains(w));
    let left_or_negative = ["left", "negative"].iter().any(|w| s.contains(w));
    if s.contains("counter-clockwise seen from above") && right_or_positive && !left_or_negative {
        return Some("positive/right pan is clockwise seen from above, not counter-clockwise");
    }
    let plain = s.replace("counter-clockwise", "");
    if plain.contains("clockwise seen from above") && left_or_negative && !right_or_positive {
        return Some("negative/left pan is counter-clockwise seen from above, not clockwise");
    }
    None
}

/// Every text gives the same pan direction (issue: gimbalctl's help said
/// counter-clockwise where the README said clockwise seen from above).
#[test]
fn one_word_for_directions() {
    for (bad, why) in [
        ("positive pan is counter-clockwise (right).", "bare"),
        ("pan right (positive, counter-clockwise seen from above).", "contrary"),
        ("pan left (negative, clockwise seen from above).", "contrary"),
    ] {
        assert!(
            direction_problem(bad).is_some(),
            "the check misses a {why} direction: {bad}"
        );
    }
    let good = "mavlink's yaw to the right (positive, clockwise seen from above) is the sagebrush pan right.";
    assert_eq!(direction_problem(good), None);
    let mut problems = Vec::new();
    for (what, text) in direction_texts() {
        for sentence in sentences(&text) {
            if let Some(why) = direction_problem(&sentence) {
                problems.push(format!("{what}: {why}: \"{sentence}\""));
            }
        }
    }
    assert!(problems.is_empty(), "{}", problems.join("\n"));
}
