//! Manual pages and shell completions from each program's clap definition
//! (clap_mangen, clap_complete), with what clap does not know: the files a
//! program reads, its signals, exit status and environment ([`Manual`]).
//!
//! Two first arguments, not part of the clap definition (so in no help
//! text nor page), make a program write them instead of running:
//! - `PROGRAM --generate-man-pages DIR [SIBLING...]` writes `PROGRAM.1`
//!   and one page per subcommand at every depth (`gimbalctl-preset-recall.1`)
//!   into DIR; every page ends with FILES, SIGNALS, EXIT STATUS,
//!   ENVIRONMENT and SEE ALSO, which names the parent page and the
//!   SIBLING programs' pages (the package's other programs: only pages
//!   that ship);
//! - `PROGRAM --generate-completions SHELL` prints the bash, zsh or fish
//!   completion script.
//!
//! `debian/package.sh` runs both for every `[[bin]]` of the package.

use std::io::Write;
use std::path::Path;

use clap_complete::Shell;
use roff::{Roff, bold, roman};

/// The first argument that asks for the manual pages instead of a run.
pub const MAN_FLAG: &str = "--generate-man-pages";
/// The first argument that asks for a completion script instead of a run.
pub const COMPLETIONS_FLAG: &str = "--generate-completions";

/// What a program's manual says beyond its clap definition: each list is
/// (term, what it means), rendered as the page's tagged paragraphs.
#[derive(Debug, Clone, Default)]
pub struct Manual {
    /// FILES: the installed paths the program reads or writes.
    pub files: Vec<(String, String)>,
    /// SIGNALS: what each signal does to the program.
    pub signals: Vec<(String, String)>,
    /// EXIT STATUS.
    pub exit_status: ExitStatus,
    /// ENVIRONMENT beyond the options' own variables (`[env: ...]`, which
    /// the page lists from the clap definition).
    pub environment: Vec<(String, String)>,
}

/// A manual's EXIT STATUS section.
#[derive(Debug, Clone)]
pub enum ExitStatus {
    /// Each code (or range) and its meaning, as tagged paragraphs.
    Codes(Vec<(String, String)>),
    /// A table the program also prints in its `--help`, kept line for line.
    Table(&'static str),
}

impl Default for ExitStatus {
    fn default() -> Self {
        Self::Codes(Vec::new())
    }
}

impl Manual {
    /// `(term, meaning)` pairs from string literals.
    pub fn pairs(items: &[(&str, &str)]) -> Vec<(String, String)> {
        items.iter().map(|(t, m)| ((*t).to_owned(), (*m).to_owned())).collect()
    }
}

/// The environment every program reads through `sagebrush_host::logging`.
pub fn logging_environment() -> Vec<(String, String)> {
    Manual::pairs(&[
        (
            "RUST_LOG",
            "The log filter (e.g. info or gcud=debug,info); it wins over the program's own filter when set.",
        ),
        (
            "JOURNAL_STREAM",
            "Set by systemd: log lines carry no timestamp and start with the syslog priority (journalctl -p warning).",
        ),
    ])
}

/// When the program's first argument is [`MAN_FLAG`] or
/// [`COMPLETIONS_FLAG`], writes what it asks for and returns the exit code
/// (the caller exits with it); otherwise `None` and the program runs.
pub fn generate_if_asked(
    command: impl FnOnce() -> clap::Command,
    manual: impl FnOnce() -> Manual,
) -> Option<std::process::ExitCode> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let result = match args.first().map(String::as_str) {
        Some(MAN_FLAG) => match args.get(1) {
            Some(dir) => write_pages(command(), &manual(), Path::new(dir), &args[2..]),
            None => Err(format!("{MAN_FLAG} DIR [SIBLING...]: no directory")),
        },
        Some(COMPLETIONS_FLAG) => match args.get(1).map(|s| s.parse::<Shell>()) {
            Some(Ok(shell)) => print_completions(command(), shell),
            _ => Err(format!("{COMPLETIONS_FLAG} SHELL: bash, zsh or fish")),
        },
        _ => return None,
    };
    Some(match result {
        Ok(()) => std::process::ExitCode::SUCCESS,
        Err(e) => {
            crate::errln!("{e}");
            std::process::ExitCode::from(2)
        }
    })
}

fn print_completions(mut command: clap::Command, shell: Shell) -> Result<(), String> {
    let name = command.get_name().to_owned();
    let mut script = Vec::new();
    clap_complete::generate(shell, &mut command, name, &mut script);
    let mut out = std::io::stdout().lock();
    out.write_all(&script)
        .and_then(|()| out.flush())
        .map_err(|e| format!("{COMPLETIONS_FLAG}: {e}"))
}

/// Writes the program's page and one per subcommand into `dir`.
fn write_pages(command: clap::Command, manual: &Manual, dir: &Path, siblings: &[String]) -> Result<(), String> {
    let mut command = command.disable_help_subcommand(true);
    command.build();
    let see_also: Vec<String> = siblings
        .iter()
        .filter(|s| s.as_str() != command.get_name())
        .map(|s| format!("{s}(1)"))
        .collect();
    write_tree(&command, None, manual, dir, &see_also)
}

fn write_tree(
    command: &clap::Command,
    parent: Option<&str>,
    manual: &Manual,
    dir: &Path,
    see_also: &[String],
) -> Result<(), String> {
    let page_name = command.get_display_name().unwrap_or(command.get_name()).to_owned();
    let file = dir.join(format!("{page_name}.1"));
    let mut text = Vec::new();
    render(command, parent, manual, see_also, &mut text).map_err(|e| format!("{}: {e}", file.display()))?;
    std::fs::write(&file, text).map_err(|e| format!("{}: {e}", file.display()))?;
    for sub in command.get_subcommands().filter(|s| !s.is_hide_set()) {
        write_tree(sub, Some(&page_name), manual, dir, see_also)?;
    }
    Ok(())
}

/// One page: clap_mangen's sections, the subcommands (each its own page),
/// the notes and examples, then the [`Manual`]'s sections and SEE ALSO.
fn render(
    command: &clap::Command,
    parent: Option<&str>,
    manual: &Manual,
    see_also: &[String],
    w: &mut dyn Write,
) -> std::io::Result<()> {
    let man = clap_mangen::Man::new(command.clone()).manual("Sagebrush gimbal stack");
    man.render_title(w)?;
    man.render_name_section(w)?;
    man.render_synopsis_section(w)?;
    man.render_description_section(w)?;
    if command.get_arguments().any(|a| !a.is_hide_set()) {
        man.render_options_section(w)?;
    }
    if command.has_subcommands() {
        man.render_subcommands_section(w)?;
    }
    let mut roff = Roff::new();
    if let Some(notes) = command.get_after_help() {
        section(&mut roff, "NOTES");
        preformatted(&mut roff, &notes.to_string());
    }
    tagged(&mut roff, "FILES", &manual.files);
    tagged(&mut roff, "SIGNALS", &manual.signals);
    match &manual.exit_status {
        ExitStatus::Codes(codes) => tagged(&mut roff, "EXIT STATUS", codes),
        ExitStatus::Table(table) => {
            section(&mut roff, "EXIT STATUS");
            preformatted(&mut roff, table);
        }
    }
    let mut environment: Vec<(String, String)> = Vec::new();
    for arg in command.get_arguments().filter(|a| !a.is_hide_set()) {
        if let (Some(var), Some(long)) = (arg.get_env(), arg.get_long()) {
            environment.push((var.to_string_lossy().into_owned(), format!("The default of --{long}.")));
        }
    }
    environment.extend(manual.environment.iter().cloned());
    tagged(&mut roff, "ENVIRONMENT", &environment);
    section(&mut roff, "SEE ALSO");
    let mut names: Vec<String> = parent.map(|p| format!("{p}(1)")).into_iter().collect();
    names.extend(see_also.iter().cloned());
    roff.text([roman(format!(
        "{}. The documentation in /usr/share/doc/sagebrush: README.md, ARCHITECTURE.md, docs/.",
        names.join(", ")
    ))]);
    if let Some(version) = command.get_version() {
        section(&mut roff, "VERSION");
        roff.text([roman(format!("v{version}"))]);
    }
    roff.to_writer(w)
}

fn section(roff: &mut Roff, title: &str) {
    roff.control("SH", [title]);
}

/// A section of tagged paragraphs (term in bold); none when empty.
fn tagged(roff: &mut Roff, title: &str, items: &[(String, String)]) {
    if items.is_empty() {
        return;
    }
    section(roff, title);
    for (term, meaning) in items {
        roff.control("TP", []);
        roff.text([bold(term.as_str())]);
        roff.text([roman(meaning.as_str())]);
    }
}

/// Text kept line for line (examples, aligned tables).
fn preformatted(roff: &mut Roff, text: &str) {
    roff.control("nf", []);
    for line in text.lines() {
        roff.text([roman(line)]);
    }
    roff.control("fi", []);
}
