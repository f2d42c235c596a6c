//! Every program's help texts say what each subcommand is (issue 53): for
//! every binary of the package (`[[bin]]` in Cargo.toml, so a new door is
//! covered without an entry here), the test walks the clap command tree as
//! the programs print it (`PROGRAM [SUB...] -h`, its "Commands:" list) and
//! checks that each subcommand's own help begins with the one-line summary
//! its parent lists for it, in short (`-h`) and long (`help SUB...`) form,
//! and that no two commands of a program share a summary: a flattened
//! option struct's doc comment, which clap would take as the `about` of every
//! subcommand flattening it, shows as the same first line on several pages.

use std::collections::BTreeMap;
use std::path::PathBuf;
use std::process::Command;

/// The names of the package's programs, from Cargo.toml's `[[bin]]`.
fn programs() -> Vec<String> {
    let manifest: toml::Table = std::fs::read_to_string(concat!(env!("CARGO_MANIFEST_DIR"), "/Cargo.toml"))
        .expect("Cargo.toml")
        .parse()
        .expect("Cargo.toml parses");
    manifest["bin"]
        .as_array()
        .expect("[[bin]]")
        .iter()
        .map(|b| b["name"].as_str().expect("bin name").to_owned())
        .collect()
}

/// A program this test run built (cargo builds every `[[bin]]` for an
/// integration test, next to gcud).
fn binary(name: &str) -> PathBuf {
    PathBuf::from(env!("CARGO_BIN_EXE_gcud")).with_file_name(name)
}

/// `program args`: its standard output, which must be a success.
fn help(program: &str, args: &[&str]) -> String {
    let out = Command::new(binary(program))
        .args(args)
        .env_remove("GIMBALCTL_SERIAL")
        .env_remove("GIMBALCTL_TCP")
        .output()
        .unwrap_or_else(|e| panic!("{program}: {e}"));
    assert!(out.status.success(), "`{program} {}` failed: {out:?}", args.join(" "));
    String::from_utf8(out.stdout).expect("help is UTF-8")
}

/// The subcommands a help text lists ("Commands:" up to a blank line), as
/// (name, summary), `help` aside.
fn listed_subcommands(text: &str) -> Vec<(String, String)> {
    text.lines()
        .skip_while(|l| *l != "Commands:")
        .skip(1)
        .take_while(|l| !l.trim().is_empty())
        .filter_map(|l| {
            let l = l.trim();
            let (name, summary) = l.split_once(char::is_whitespace).unwrap_or((l, ""));
            let summary = summary.split(" [aliases:").next().unwrap_or_default().trim();
            (name != "help").then(|| (name.to_owned(), summary.to_owned()))
        })
        .collect()
}

fn first_line(text: &str) -> &str {
    text.lines().next().unwrap_or_default().trim()
}

/// Walks `program`'s command tree from `path`: checks each subcommand's
/// help against the summary listed for it and records every first line
/// (path -> summary) in `seen`.
fn walk(program: &str, path: &[String], seen: &mut BTreeMap<String, String>) {
    let mut args: Vec<&str> = path.iter().map(String::as_str).collect();
    args.push("-h");
    let short = help(program, &args);
    for (name, summary) in listed_subcommands(&short) {
        let mut sub = path.to_vec();
        sub.push(name);
        let shown = sub.join(" ");
        assert!(
            !summary.is_empty(),
            "`{program} {shown}` has no summary in its parent's list"
        );
        let mut args: Vec<&str> = sub.iter().map(String::as_str).collect();
        args.push("-h");
        let own = help(program, &args);
        let parent: Vec<&str> = std::iter::once(program)
            .chain(path.iter().map(String::as_str))
            .collect();
        assert_eq!(
            first_line(&own),
            summary,
            "`{program} {shown} -h` does not begin with its own summary (the one `{} -h` lists)",
            parent.join(" ")
        );
        let mut long_args = vec!["help"];
        long_args.extend(sub.iter().map(String::as_str));
        let long = help(program, &long_args);
        let long_first = first_line(&long);
        assert!(
            long_first == summary || long_first.strip_suffix('.') == Some(summary.as_str()),
            "`{program} help {shown}` begins with {long_first:?}, not its summary {summary:?}"
        );
        seen.insert(shown, summary);
        walk(program, &sub, seen);
    }
}

#[test]
fn every_subcommand_of_every_program_begins_its_help_with_its_own_summary() {
    let mut roots = BTreeMap::new();
    let mut walked = 0;
    for program in programs() {
        let root = help(&program, &["-h"]);
        let summary = first_line(&root).to_owned();
        assert!(
            !summary.is_empty() && !summary.starts_with("Usage:"),
            "{program} -h has no summary:\n{root}"
        );
        if let Some(other) = roots.insert(summary.clone(), program.clone()) {
            panic!("{program} and {other} share the summary {summary:?}");
        }
        let mut seen = BTreeMap::new();
        walk(&program, &[], &mut seen);
        // A summary shared by two subcommands is a shared struct's doc, not theirs.
        let mut by_summary: BTreeMap<&str, Vec<&str>> = BTreeMap::new();
        for (path, summary) in &seen {
            by_summary.entry(summary.as_str()).or_default().push(path.as_str());
        }
        for (summary, paths) in by_summary {
            assert!(
                paths.len() == 1,
                "{program}: {paths:?} all begin their help with {summary:?}"
            );
        }
        walked += seen.len();
    }
    // gimbalctl alone has more than 40 (preset store, zoom in, ...).
    assert!(walked > 40, "only {walked} subcommands walked");
}
