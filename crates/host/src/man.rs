//! Manual pages generated from each program's clap definition
//! (clap_mangen): `PROGRAM --generate-man-page` prints the page in roff
//! instead of running; `debian/package.sh` writes them for the Debian
//! package (`man gcud`). The argument is not part of the clap definition,
//! so it appears in no help text and no page.

use std::io::Write;

/// The first argument that asks for the manual page instead of a run.
pub const FLAG: &str = "--generate-man-page";

/// When the program's first argument is [`FLAG`], prints `command`'s
/// manual page on stdout and returns true (the caller exits); otherwise
/// returns false and the program runs as usual.
pub fn print_if_asked(command: impl FnOnce() -> clap::Command) -> bool {
    if std::env::args_os().nth(1).is_none_or(|a| a != FLAG) {
        return false;
    }
    let mut page = Vec::new();
    if let Err(e) = clap_mangen::Man::new(command()).render(&mut page) {
        crate::errln!("{FLAG}: {e}");
        return true;
    }
    let mut out = std::io::stdout().lock();
    let _ = out.write_all(&page).and_then(|()| out.flush());
    true
}
