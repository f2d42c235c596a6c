//! A fresh pseudo-terminal pair in raw mode: the master is
//! an async byte stream for the simulator, the slave a path clients open
//! like a serial port. A pty does not pace bytes at any baud rate.

use std::io;
use std::path::{Path, PathBuf};
use std::pin::Pin;
use std::task::{Context, Poll};

use tokio::io::{AsyncRead, AsyncWrite, ReadBuf};
use tokio_serial::{SerialPort, SerialStream};

/// The simulator's end of a pseudo-terminal.
#[derive(Debug)]
pub struct PtyMaster {
    master: SerialStream,
    /// Kept open so the master never sees a hang-up between clients, and
    /// so the raw settings persist.
    _slave: SerialStream,
    slave_path: PathBuf,
}

impl PtyMaster {
    /// Opens a new pair (`posix_openpt`), the slave in raw mode (no echo,
    /// no line editing, 8-bit clean). Needs a tokio runtime.
    pub fn open() -> io::Result<Self> {
        let (master, slave) =
            SerialStream::pair().map_err(|e| io::Error::other(format!("cannot open a pseudo-terminal: {e}")))?;
        let slave_path = slave
            .name()
            .map(PathBuf::from)
            .ok_or_else(|| io::Error::other("the pseudo-terminal has no slave name"))?;
        Ok(Self {
            master,
            _slave: slave,
            slave_path,
        })
    }

    /// The path clients open (`/dev/pts/N`).
    pub fn slave_path(&self) -> &Path {
        &self.slave_path
    }
}

impl AsyncRead for PtyMaster {
    fn poll_read(self: Pin<&mut Self>, cx: &mut Context<'_>, buf: &mut ReadBuf<'_>) -> Poll<io::Result<()>> {
        Pin::new(&mut self.get_mut().master).poll_read(cx, buf)
    }
}

impl AsyncWrite for PtyMaster {
    fn poll_write(self: Pin<&mut Self>, cx: &mut Context<'_>, buf: &[u8]) -> Poll<io::Result<usize>> {
        Pin::new(&mut self.get_mut().master).poll_write(cx, buf)
    }

    fn poll_flush(self: Pin<&mut Self>, cx: &mut Context<'_>) -> Poll<io::Result<()>> {
        Pin::new(&mut self.get_mut().master).poll_flush(cx)
    }

    fn poll_shutdown(self: Pin<&mut Self>, cx: &mut Context<'_>) -> Poll<io::Result<()>> {
        Pin::new(&mut self.get_mut().master).poll_shutdown(cx)
    }
}

/// A symlink to a pty slave that is removed again on drop (`--link`).
#[derive(Debug)]
pub struct Symlink(PathBuf);

impl Symlink {
    /// Creates `link` -> `target`, replacing an existing symlink (never a file).
    pub fn create(target: &Path, link: &Path) -> io::Result<Self> {
        if let Ok(meta) = std::fs::symlink_metadata(link) {
            if meta.file_type().is_symlink() {
                std::fs::remove_file(link)?;
            } else {
                return Err(io::Error::new(
                    io::ErrorKind::AlreadyExists,
                    format!("{} exists and is not a symlink: not replacing it", link.display()),
                ));
            }
        }
        std::os::unix::fs::symlink(target, link)
            .map_err(|e| io::Error::new(e.kind(), format!("cannot create symlink {}: {e}", link.display())))?;
        Ok(Self(link.to_path_buf()))
    }
}

impl Drop for Symlink {
    fn drop(&mut self) {
        let _ = std::fs::remove_file(&self.0);
    }
}
