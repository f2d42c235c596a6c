//! The repository's documentation stands on its own: nothing points outside
//! it, every citation of the project's design notes or protocol notes names
//! a section that exists, and every relative Markdown link resolves.
//! Checked over the files git tracks, so a user's clone sees what this sees.

use std::collections::BTreeSet;
use std::path::Path;
use std::process::Command;

const ROOT: &str = env!("CARGO_MANIFEST_DIR");
/// This file spells the patterns it looks for.
const SELF: &str = "tests/docs.rs";

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

/// The headings of a Markdown file, lower case, without the `#`s.
fn headings(file: &str) -> Vec<String> {
    let text = std::fs::read_to_string(Path::new(ROOT).join(file)).unwrap_or_else(|e| panic!("{file}: {e}"));
    text.lines()
        .filter(|l| l.starts_with('#'))
        .map(|l| l.trim_start_matches('#').trim().to_lowercase())
        .collect()
}

/// Every `<prefix> "<name>"` in `text`, with its line number (a name in
/// angle brackets is a placeholder in prose, not a citation).
fn quoted_after<'a>(text: &'a str, prefix: &str) -> Vec<(usize, &'a str)> {
    let mut found = Vec::new();
    for (n, line) in text.lines().enumerate() {
        let mut rest = line;
        while let Some(at) = rest.find(prefix) {
            rest = &rest[at + prefix.len()..];
            if let Some(name) = rest.strip_prefix('"').and_then(|r| r.split('"').next()) {
                found.push((n + 1, name));
            }
        }
    }
    found
}

/// Every `<prefix>E<digits>` in `text`, with its line number.
fn errata_after(text: &str, prefix: &str) -> Vec<(usize, String)> {
    let mut found = Vec::new();
    for (n, line) in text.lines().enumerate() {
        let mut rest = line;
        while let Some(at) = rest.find(prefix) {
            rest = &rest[at + prefix.len()..];
            if let Some(digits) = rest.strip_prefix('E') {
                let number: String = digits.chars().take_while(char::is_ascii_digit).collect();
                if !number.is_empty() {
                    found.push((n + 1, format!("e{number}")));
                }
            }
        }
    }
    found
}

/// What is wrong with the tracked files, as `file:line: why`.
fn problems() -> Vec<String> {
    let files = tracked();
    let notes = headings("docs/protocol-notes.md");
    let design = headings("ARCHITECTURE.md");
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
                "{file}:{n}: cites DESIGN \"{old}\", a file outside the repository"
            ));
        }
        for (n, old) in errata_after(text, "NOTES ") {
            problems.push(format!("{file}:{n}: cites NOTES {old}, a file outside the repository"));
        }
        for (n, number) in errata_after(text, "protocol-notes ") {
            if !notes.contains(&number) {
                problems.push(format!("{file}:{n}: protocol-notes {number} has no heading"));
            }
        }
        for (n, section) in quoted_after(text, "protocol-notes ") {
            let section = section.to_lowercase();
            if !section.starts_with('<') && !notes.iter().any(|h| h.starts_with(&section)) {
                problems.push(format!("{file}:{n}: protocol-notes \"{section}\" has no heading"));
            }
        }
        for (n, section) in quoted_after(text, "ARCHITECTURE ") {
            let section = section.to_lowercase();
            if !section.starts_with('<') && !design.iter().any(|h| h.starts_with(&section)) {
                problems.push(format!("{file}:{n}: ARCHITECTURE \"{section}\" has no heading"));
            }
        }
        if file.ends_with(".md") {
            let dir = Path::new(file).parent().unwrap_or(Path::new(""));
            for (n, line) in text.lines().enumerate() {
                let mut rest = line;
                while let Some(at) = rest.find("](") {
                    rest = &rest[at + 2..];
                    let target = rest.split(')').next().unwrap_or_default();
                    let path = target.split('#').next().unwrap_or_default();
                    let external = target.contains("://") || target.starts_with("mailto:");
                    if !external && !path.is_empty() && !Path::new(ROOT).join(dir).join(path).exists() {
                        problems.push(format!("{file}:{}: link to {target} does not resolve", n + 1));
                    }
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
    let notes: BTreeSet<String> = headings("docs/protocol-notes.md").into_iter().collect();
    for n in 1..=15 {
        assert!(
            notes.contains(&format!("e{n}")),
            "docs/protocol-notes.md has no ### E{n}"
        );
    }
    for section in ["framing", "command disambiguation", "parse leniently"] {
        assert!(
            notes.contains(section),
            "docs/protocol-notes.md has no {section} section"
        );
    }
}
