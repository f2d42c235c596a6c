//! A capture's files: created (truncated), rotated by renaming
//! (`capture.pcapng` -> `capture.1.pcapng` ...), and a FIFO opened for
//! writing only once it has a reader, without blocking.

use std::fs::{File, OpenOptions};
use std::io;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::Duration;

/// Creates (or truncates) `path` for writing.
pub fn create(path: &Path) -> io::Result<File> {
    OpenOptions::new().write(true).create(true).truncate(true).open(path)
}

/// Whether `path` is a FIFO.
pub fn is_fifo(path: &Path) -> bool {
    use std::os::unix::fs::FileTypeExt;
    std::fs::metadata(path).is_ok_and(|m| m.file_type().is_fifo())
}

/// How often the writer thread looks for a FIFO's reader.
const READER_POLL: Duration = Duration::from_millis(50);

/// Opens a FIFO for writing once it has a reader, without ever blocking in
/// `open(2)`: a non-blocking open fails with `ENXIO` while nobody reads, so
/// it is retried every [`READER_POLL`] until `stopping` is set (then
/// `Ok(None)`). The open file blocks on writes again (on the writer
/// thread only).
pub fn open_fifo_when_read(path: &Path, stopping: &AtomicBool) -> io::Result<Option<File>> {
    use nix::fcntl::{FcntlArg, OFlag, fcntl};
    use std::os::unix::fs::OpenOptionsExt;
    loop {
        if stopping.load(Ordering::Acquire) {
            return Ok(None);
        }
        match OpenOptions::new()
            .write(true)
            .custom_flags(OFlag::O_NONBLOCK.bits())
            .open(path)
        {
            Ok(file) => {
                fcntl(&file, FcntlArg::F_SETFL(OFlag::empty()))?;
                return Ok(Some(file));
            }
            Err(e) if e.raw_os_error() == Some(nix::errno::Errno::ENXIO as i32) => std::thread::sleep(READER_POLL),
            Err(e) => return Err(e),
        }
    }
}

/// `capture.pcapng` -> `capture.N.pcapng` (N = 0: the path itself).
pub fn rotated_path(path: &Path, n: u32) -> PathBuf {
    if n == 0 {
        return path.to_owned();
    }
    let stem = path
        .file_stem()
        .map(|s| s.to_string_lossy().into_owned())
        .unwrap_or_default();
    let name = match path.extension() {
        Some(ext) => format!("{stem}.{n}.{}", ext.to_string_lossy()),
        None => format!("{stem}.{n}"),
    };
    path.with_file_name(name)
}

/// Shifts `path` to `.1`, `.1` to `.2` ... keeping `count` files in all,
/// the one about to be created included. Only regular files are renamed
/// (a capture to a device such as `/dev/null` is never moved).
pub fn rotate_files(path: &Path, count: u32) -> io::Result<()> {
    if !std::fs::metadata(path).is_ok_and(|m| m.is_file()) || count <= 1 {
        return Ok(());
    }
    let last = rotated_path(path, count - 1);
    if last.exists() {
        std::fs::remove_file(&last)?;
    }
    for n in (0..count - 1).rev() {
        let from = rotated_path(path, n);
        if from.exists() {
            std::fs::rename(&from, rotated_path(path, n + 1))?;
        }
    }
    Ok(())
}
