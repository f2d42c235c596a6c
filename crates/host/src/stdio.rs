//! Standard output and error for the command-line programs, quiet when the
//! reader has gone: `gimbalctl --json watch | head -1` ends when `head`
//! does, without a panic (Rust's `println!` panics on a closed pipe).
//!
//! - [`outln!`](crate::outln) / [`out!`](crate::out): a closed stdout
//!   (`EPIPE`) ends the program at once with exit 0, since whoever wanted
//!   the output has stopped reading; another write error (a full disk) ends
//!   it with exit 1 and says why on stderr.
//! - [`errln!`](crate::errln): diagnostics; a closed stderr loses them
//!   silently, as there is nowhere left to say anything.

use std::fmt;
use std::io::{self, Write};

/// Exit code when stdout cannot be written for another reason than a
/// closed pipe.
const EXIT_STDOUT_FAILED: i32 = 1;

/// Writes `args` to stdout and flushes; ends the process if stdout is gone
/// (see the module doc).
pub fn write_out(args: fmt::Arguments<'_>) {
    let mut out = io::stdout().lock();
    if let Err(e) = out.write_fmt(args).and_then(|()| out.flush()) {
        if e.kind() == io::ErrorKind::BrokenPipe {
            std::process::exit(0);
        }
        write_err(format_args!("cannot write to stdout: {e}\n"));
        std::process::exit(EXIT_STDOUT_FAILED);
    }
}

/// Writes `args` to stderr, dropping them if stderr is gone.
pub fn write_err(args: fmt::Arguments<'_>) {
    let _ = io::stderr().lock().write_fmt(args);
}

/// `println!` to stdout that ends the program quietly on a closed pipe.
#[macro_export]
macro_rules! outln {
    () => { $crate::stdio::write_out(format_args!("\n")) };
    ($($arg:tt)*) => { $crate::stdio::write_out(format_args!("{}\n", format_args!($($arg)*))) };
}

/// `print!` to stdout (flushed) that ends the program quietly on a closed pipe.
#[macro_export]
macro_rules! out {
    ($($arg:tt)*) => { $crate::stdio::write_out(format_args!($($arg)*)) };
}

/// `eprintln!` that never panics: a closed stderr drops the line.
#[macro_export]
macro_rules! errln {
    ($($arg:tt)*) => { $crate::stdio::write_err(format_args!("{}\n", format_args!($($arg)*))) };
}
