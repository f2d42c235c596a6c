//! The README's quick start, run line by line against the demo.

use super::*;

/// Every `127.0.0.1:PORT` in `text` moved by `shift`.
fn shift_ports(text: &str, shift: u16) -> String {
    let marker = "127.0.0.1:";
    let mut out = String::new();
    let mut rest = text;
    while let Some(at) = rest.find(marker) {
        let after = &rest[at + marker.len()..];
        let digits = after.len() - after.trim_start_matches(|c: char| c.is_ascii_digit()).len();
        let port: u16 = after[..digits].parse().expect("a port");
        out += &format!("{}{marker}{}", &rest[..at], port + shift);
        rest = &after[digits..];
    }
    out + rest
}

/// The README's quick start: the shell lines of its code blocks, in order.
fn quick_start_lines() -> Vec<String> {
    let readme = std::fs::read_to_string(root().join("README.md")).expect("README.md");
    let start = readme
        .find("\n## Quick start")
        .expect("README.md has a \"Quick start\" section");
    let section = &readme[start + 1..];
    let section = &section[..section[3..].find("\n## ").map_or(section.len(), |e| e + 3)];
    let mut lines = Vec::new();
    let mut in_block = false;
    for line in section.lines() {
        if line.starts_with("```") {
            in_block = line == "```sh";
            continue;
        }
        if in_block && !line.trim().is_empty() {
            lines.push(line.to_owned());
        }
    }
    lines
}

/// A README line's command (its `# comment` cut off) and the exit code
/// the comment shows, "(exit N)", else 0.
fn command_and_code(line: &str) -> (String, i32) {
    let (command, comment) = line.split_once(" # ").unwrap_or((line, ""));
    let code = comment
        .split_once("(exit ")
        .and_then(|(_, r)| r.split_once(')'))
        .map_or(0, |(n, _)| n.parse().expect("an exit code"));
    (command.trim().to_owned(), code)
}

#[test]
fn the_quick_start_lines_run_in_order_exit_as_the_readme_shows() {
    let lines = quick_start_lines();
    let after_demo = lines
        .iter()
        .position(|l| l.starts_with("./demo.sh"))
        .expect("the quick start runs ./demo.sh");
    let test_line = lines
        .iter()
        .position(|l| l.starts_with("./test.sh"))
        .expect("the quick start runs ./test.sh");
    let moves = &lines[after_demo + 1..test_line];
    assert!(moves.len() >= 5, "the lines between ./demo.sh and ./test.sh: {moves:?}");
    let demo = Demo::start(0);
    // `cargo run --release --bin X --` is the program this test was built
    // with (cargo may not run inside cargo test); gcud-status's default
    // address moves with the ports.
    let env = [("GIMBALCTL_HTTP", format!("127.0.0.1:{}", demo.port(9187)))];
    for line in moves {
        let (command, want) = command_and_code(line);
        let command = shift_ports(&command, demo.shift).replace(
            "cargo run --release --bin gimbalctl --",
            env!("CARGO_BIN_EXE_gimbalctl"),
        );
        assert!(
            !command.contains("cargo "),
            "a quick-start line this test cannot run: {line}"
        );
        let (code, out) = shell(&command, &env);
        assert_eq!(
            code,
            want,
            "README.md's quick-start line\n  {line}\nexits {code}, the README shows {want}:\n{out}\n{}",
            demo.logs()
        );
    }
}
