//! Parsing the command line as `Cli::try_parse` does, with the global
//! arguments given to the one subcommand named instead of to all of them.
//!
//! clap copies every global argument into every top-level subcommand before
//! it parses (`_propagate_global_args`): 14 arguments into some 45
//! subcommands, about 370 KB of fresh heap and 630 clones for the one
//! subcommand that is used, a fifth of gimbalctl's start. Here the
//! subcommand the arguments name gets the global arguments (still global
//! there, so its nested subcommands take them too, and clap carries their
//! values up to the top, where `Global` reads them), and the top keeps them
//! as plain arguments (`gimbalctl --to 5.1.1 slew right`). Arguments that
//! name no subcommand plainly (`--help`, a typo, an unknown option) are
//! parsed the standard way, with every subcommand. `tests` checks that both
//! ways parse, fail and print help alike.

use std::ffi::OsString;

use clap::{Arg, Command, CommandFactory, FromArgMatches};

use super::Cli;

/// [`Cli`] from the command line `args` (program name first).
pub fn parse(args: Vec<OsString>) -> Result<Cli, clap::Error> {
    let mut cmd = Cli::command();
    if let Some(name) = named_subcommand(&cmd, &args) {
        cmd = globals_to(cmd, &name);
    }
    let mut matches = cmd.try_get_matches_from_mut(args)?;
    Cli::from_arg_matches_mut(&mut matches).map_err(|e| e.format(&mut cmd))
}

/// The top-level subcommand `args` name (by its name, an alias resolved),
/// when every argument before it is a known global option; `help` and
/// anything unclear name none.
fn named_subcommand(cmd: &Command, args: &[OsString]) -> Option<String> {
    let mut i = 1;
    loop {
        let arg = args.get(i)?.to_str()?;
        if arg.starts_with('-') {
            i += option_words(cmd, arg)?;
        } else {
            let sub = cmd.find_subcommand(arg)?;
            return (sub.get_name() != "help").then(|| sub.get_name().to_owned());
        }
    }
}

/// The words `arg` takes when it is one of `cmd`'s long options: 2 when
/// its value is the next word, else 1 (`--json`, `--to=5.1.1`); `None`
/// for anything else (a short option, `--`, an unknown one).
fn option_words(cmd: &Command, arg: &str) -> Option<usize> {
    let long = arg.strip_prefix("--")?;
    let (name, inline_value) = match long.split_once('=') {
        Some((name, _)) => (name, true),
        None => (long, false),
    };
    let option = cmd.get_arguments().find(|a| a.get_long() == Some(name))?;
    Some(if !inline_value && option.get_action().takes_values() {
        2
    } else {
        1
    })
}

/// `cmd` with its global arguments given to subcommand `name` only.
fn globals_to(cmd: Command, name: &str) -> Command {
    let globals: Vec<Arg> = cmd.get_arguments().filter(|a| a.is_global_set()).cloned().collect();
    let ids: Vec<_> = globals.iter().map(|a| a.get_id().clone()).collect();
    let mut cmd = cmd.mut_subcommand(name, |sub| sub.args(globals));
    for id in ids {
        cmd = cmd.mut_arg(id, |a| a.global(false));
    }
    cmd
}

#[cfg(test)]
mod tests {
    use clap::Parser;

    use super::*;

    /// A line's words, quotes removed (the examples' shell quoting).
    fn words(line: &str) -> Vec<String> {
        let (mut words, mut word, mut quote, mut quoted) = (Vec::new(), String::new(), None, false);
        for c in line.chars() {
            match quote {
                Some(q) if c == q => quote = None,
                Some(_) => word.push(c),
                None if c == '"' || c == '\'' => (quote, quoted) = (Some(c), true),
                None if c.is_whitespace() => {
                    if !word.is_empty() || quoted {
                        words.push(std::mem::take(&mut word));
                        quoted = false;
                    }
                }
                None => word.push(c),
            }
        }
        if !word.is_empty() || quoted {
            words.push(word);
        }
        words
    }

    /// Every subcommand's path (`["preset", "store"]`), `help` aside, of a built tree.
    fn paths(cmd: &Command, prefix: &[String], out: &mut Vec<Vec<String>>) {
        for sub in cmd.get_subcommands().filter(|s| s.get_name() != "help") {
            let mut path = prefix.to_vec();
            path.push(sub.get_name().to_owned());
            out.push(path.clone());
            paths(sub, &path, out);
        }
    }

    /// Every example line of every subcommand's help, as arguments (a
    /// trailing `# comment` dropped).
    fn examples(cmd: &Command, out: &mut Vec<Vec<String>>) {
        for text in [cmd.get_after_help(), cmd.get_after_long_help()].into_iter().flatten() {
            for line in text.to_string().lines() {
                if let Some(example) = line.trim_start().strip_prefix("gimbalctl ") {
                    out.push(words(example.split('#').next().unwrap_or_default()));
                }
            }
        }
        for sub in cmd.get_subcommands() {
            examples(sub, out);
        }
    }

    /// The example with the global options before its subcommand moved to its end.
    fn globals_last(cmd: &Command, args: &[String]) -> Vec<String> {
        let mut i = 0;
        while let Some(words) = args.get(i).and_then(|a| option_words(cmd, a)) {
            i += words;
        }
        let i = i.min(args.len());
        args[i..].iter().chain(&args[..i]).cloned().collect()
    }

    /// Parsed here and by clap's own way alike: the same `Cli`, or the
    /// same error, help or version text.
    fn parses_alike(args: &[String]) {
        let argv: Vec<OsString> = std::iter::once("gimbalctl".into())
            .chain(args.iter().map(OsString::from))
            .collect();
        match (parse(argv.clone()), Cli::try_parse_from(&argv)) {
            (Ok(ours), Ok(clap)) => assert_eq!(format!("{ours:?}"), format!("{clap:?}"), "{args:?}"),
            (Err(ours), Err(clap)) => {
                assert_eq!(ours.kind(), clap.kind(), "{args:?}");
                assert_eq!(ours.render().to_string(), clap.render().to_string(), "{args:?}");
            }
            (ours, clap) => panic!("{args:?}: here {ours:?}, clap's way {clap:?}"),
        }
    }

    #[test]
    fn every_example_parses_as_clap_parses_it_with_the_global_options_first_or_last() {
        let mut cli = Cli::command();
        cli.build();
        let mut all = Vec::new();
        examples(&cli, &mut all);
        assert!(all.len() > 100, "{} examples", all.len());
        for example in &all {
            parses_alike(example);
            parses_alike(&globals_last(&cli, example));
        }
    }

    #[test]
    fn every_subcommands_help_and_usage_errors_read_as_clap_writes_them() {
        let mut cli = Cli::command();
        cli.build();
        let mut all = Vec::new();
        paths(&cli, &[], &mut all);
        assert!(all.len() > 40, "{} subcommands", all.len());
        for path in &all {
            for extra in [
                &["--help"][..],
                &["-h"],
                &["--to"],
                &["--to", "5.1.300"],
                &["--bogus"],
                &[],
            ] {
                let args: Vec<String> = path
                    .iter()
                    .map(String::as_str)
                    .chain(extra.iter().copied())
                    .map(Into::into)
                    .collect();
                parses_alike(&args);
            }
            let mut help = vec!["help".to_owned()];
            help.extend(path.iter().cloned());
            parses_alike(&help);
        }
        let odd: &[&[&str]] = &[
            &[],
            &["--help"],
            &["--version"],
            &["slw", "right"],
            &["--to"],
            &["--to", "5.1.1"],
            &["--to=5.1.1", "--json", "position"],
            &["--bogus", "position"],
            &["--bogus=1", "position"],
            &["--json=1", "position"],
            &["-x", "position"],
            &["--", "position"],
            &["--log", "debug", "stop", "pan", "--json"],
            &["--baud", "7", "position"],
            &["position", "--baud", "7"],
            &["--serial", "/dev/x", "slew", "right", "--tcp", "127.0.0.1:4001"],
            &["slew", "--to", "5.1.1", "right"],
            &["--to", "5.1.1", "slew", "right", "--to", "5.1.2"],
            &["stop", "--tcp", "127.0.0.1:4001", "pan", "--to", "5.1.1"],
        ];
        for args in odd {
            parses_alike(&args.iter().map(|a| a.to_string()).collect::<Vec<_>>());
        }
    }
}
