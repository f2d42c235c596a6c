//! `tracing` set-up for the binaries: human or JSON lines on stderr, level
//! from a filter string (`RUST_LOG` syntax, e.g. `info,sagebrush_sim=debug`);
//! the `RUST_LOG` environment variable wins when set. Under systemd
//! (`JOURNAL_STREAM` set, see systemd.exec(5)) lines carry no timestamp (the
//! journal adds its own) and start with the syslog priority prefix (`<3>`
//! error, `<4>` warn, `<6>` info, `<7>` debug and trace), which journald
//! strips and records as the entry's priority (`journalctl -p warning`).

use std::fmt;
use std::io::IsTerminal;

use tracing::{Event, Level, Subscriber};
use tracing_subscriber::EnvFilter;
use tracing_subscriber::fmt::format::Writer;
use tracing_subscriber::fmt::{FmtContext, FormatEvent, FormatFields};
use tracing_subscriber::registry::LookupSpan;

/// Checks a log filter (`"info"`, `"warn,sagebrush_gcu=debug"`) as
/// [`init`] would read it; the error says what is wrong with it.
pub fn check_filter(filter: &str) -> Result<(), String> {
    EnvFilter::try_new(filter).map(drop).map_err(|e| e.to_string())
}

/// Installs the global subscriber. `default_filter` applies when `RUST_LOG`
/// is unset; a malformed filter is reported, not ignored.
pub fn init(default_filter: &str, json: bool) -> Result<(), String> {
    let filter = match std::env::var("RUST_LOG") {
        Ok(env) if !env.is_empty() => EnvFilter::try_new(&env).map_err(|e| format!("RUST_LOG={env:?}: {e}"))?,
        _ => EnvFilter::try_new(default_filter).map_err(|e| format!("log filter {default_filter:?}: {e}"))?,
    };
    let builder = tracing_subscriber::fmt()
        .with_env_filter(filter)
        .with_writer(std::io::stderr)
        .with_ansi(std::io::stderr().is_terminal())
        .with_target(false)
        // A closed stderr (the reader of a pipe gone) loses the lines; the
        // default would report that with `eprintln!`, which panics there.
        .log_internal_errors(false);
    let journal = std::env::var_os("JOURNAL_STREAM").is_some();
    let result = match (json, journal) {
        (true, false) => builder.json().try_init(),
        (true, true) => builder.json().map_event_format(JournalPriority).try_init(),
        (false, true) => builder
            .without_time()
            .with_ansi(false)
            .map_event_format(JournalPriority)
            .try_init(),
        (false, false) => builder.try_init(),
    };
    result.map_err(|e| format!("cannot install the logger: {e}"))
}

/// The syslog priority journald reads from a line's `<N>` prefix.
fn priority(level: &Level) -> u8 {
    match *level {
        Level::ERROR => 3,
        Level::WARN => 4,
        Level::INFO => 6,
        Level::DEBUG | Level::TRACE => 7,
    }
}

/// Wraps an event format: each line starts with `<N>`, the event's syslog
/// priority, then whatever the inner format writes.
struct JournalPriority<F>(F);

impl<S, N, F> FormatEvent<S, N> for JournalPriority<F>
where
    S: Subscriber + for<'a> LookupSpan<'a>,
    N: for<'a> FormatFields<'a> + 'static,
    F: FormatEvent<S, N>,
{
    fn format_event(&self, ctx: &FmtContext<'_, S, N>, mut writer: Writer<'_>, event: &Event<'_>) -> fmt::Result {
        write!(writer, "<{}>", priority(event.metadata().level()))?;
        self.0.format_event(ctx, writer, event)
    }
}

#[cfg(test)]
mod tests {
    use std::sync::{Arc, Mutex};

    use super::*;

    /// A writer into a shared buffer.
    #[derive(Clone, Default)]
    struct Buffer(Arc<Mutex<Vec<u8>>>);

    impl std::io::Write for Buffer {
        fn write(&mut self, buf: &[u8]) -> std::io::Result<usize> {
            self.0.lock().unwrap().extend_from_slice(buf);
            Ok(buf.len())
        }
        fn flush(&mut self) -> std::io::Result<()> {
            Ok(())
        }
    }

    fn emit_each_level() {
        tracing::error!("e-line");
        tracing::warn!("w-line");
        tracing::info!(key = 1, "i-line");
        tracing::debug!("d-line");
        tracing::trace!("t-line");
    }

    fn lines(buf: &Buffer) -> Vec<String> {
        String::from_utf8(buf.0.lock().unwrap().clone())
            .unwrap()
            .lines()
            .map(str::to_owned)
            .collect()
    }

    #[test]
    fn journal_lines_start_with_their_syslog_priority() {
        let buf = Buffer::default();
        let writer = buf.clone();
        let subscriber = tracing_subscriber::fmt()
            .with_max_level(Level::TRACE)
            .with_writer(move || writer.clone())
            .with_ansi(false)
            .with_target(false)
            .without_time()
            .map_event_format(JournalPriority)
            .finish();
        tracing::subscriber::with_default(subscriber, emit_each_level);
        let lines = lines(&buf);
        assert_eq!(lines.len(), 5, "{lines:?}");
        for (line, (prefix, level, text)) in lines.iter().zip([
            ("<3>", "ERROR", "e-line"),
            ("<4>", " WARN", "w-line"),
            ("<6>", " INFO", "i-line"),
            ("<7>", "DEBUG", "d-line"),
            ("<7>", "TRACE", "t-line"),
        ]) {
            // The prefix, then the line the plain format writes.
            assert!(line.starts_with(&format!("{prefix}{level} {text}")), "{line:?}");
        }
        assert!(lines[2].ends_with("i-line key=1"), "{:?}", lines[2]);
    }

    #[test]
    fn journal_json_lines_are_json_after_the_prefix() {
        let buf = Buffer::default();
        let writer = buf.clone();
        let subscriber = tracing_subscriber::fmt()
            .with_max_level(Level::TRACE)
            .with_writer(move || writer.clone())
            .json()
            .map_event_format(JournalPriority)
            .finish();
        tracing::subscriber::with_default(subscriber, emit_each_level);
        let lines = lines(&buf);
        assert_eq!(lines.len(), 5, "{lines:?}");
        for (line, prefix) in lines.iter().zip(["<3>", "<4>", "<6>", "<7>", "<7>"]) {
            let json = line
                .strip_prefix(prefix)
                .unwrap_or_else(|| panic!("no {prefix}: {line:?}"));
            assert!(json.starts_with('{') && json.ends_with('}'), "{line:?}");
        }
    }

    #[test]
    fn priorities_follow_syslog() {
        assert_eq!(priority(&Level::ERROR), 3);
        assert_eq!(priority(&Level::WARN), 4);
        assert_eq!(priority(&Level::INFO), 6);
        assert_eq!(priority(&Level::DEBUG), 7);
        assert_eq!(priority(&Level::TRACE), 7);
    }
}
