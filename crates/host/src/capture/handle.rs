//! A running capture as its callers hold it: declare interfaces, record
//! chunks without ever waiting (a full queue drops and counts them), read
//! the counters, stop.

use std::io;
use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::sync::atomic::Ordering;
use std::sync::mpsc::{SyncSender, TrySendError, sync_channel};
use std::time::{Duration, Instant, SystemTime};

use super::files::{create, is_fifo, rotate_files};
use super::record::{Direction, Role};
use super::writer::{CaptureConfig, Msg, Shared, Writer};

/// Counters of a capture.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct CaptureStats {
    pub records: u64,
    pub bytes_written: u64,
    /// Chunks dropped because the writer was behind (or stopped).
    pub dropped: u64,
    /// Why the capture stopped by itself (write error, budget), if it did.
    pub stopped: Option<String>,
}

/// An interface of a capture ([`Capture::interface`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct InterfaceId(u32);

/// A running capture; cheap to clone. The file is complete once
/// [`Capture::stop`] returned or every clone was dropped and the writer ended.
#[derive(Clone, Debug)]
pub struct Capture {
    tx: SyncSender<Msg>,
    shared: Arc<Shared>,
    path: PathBuf,
}

impl Capture {
    /// Creates `path` (an existing regular file is rotated away first, kept as
    /// `NAME.1.EXT` when `rotate_count` > 1) and starts the writer thread.
    /// Errors creating the file are returned here; later write errors stop the
    /// capture with one error log. A FIFO is not opened here: the writer
    /// thread opens it once it has a reader ([`Capture::waits_for_reader`];
    /// it is never rotated).
    pub fn open(path: impl AsRef<Path>, config: CaptureConfig) -> io::Result<Capture> {
        let path = path.as_ref().to_owned();
        let fifo = is_fifo(&path);
        let config = CaptureConfig {
            rotate_count: config.rotate_count.max(1),
            queue: config.queue.max(1),
            rotate_bytes: config.rotate_bytes.filter(|_| !fifo),
            ..config
        };
        let file = match fifo {
            true => None,
            false => {
                rotate_files(&path, config.rotate_count)?;
                Some(create(&path)?)
            }
        };
        let (tx, rx) = sync_channel(config.queue);
        let shared = Arc::new(Shared::default());
        shared.active.store(true, Ordering::Release);
        shared.waiting_for_reader.store(fifo, Ordering::Release);
        let writer = Writer::new(path.clone(), config, file, shared.clone());
        std::thread::Builder::new()
            .name("capture".to_owned())
            .spawn(move || writer.run(rx))?;
        Ok(Capture { tx, shared, path })
    }

    /// The file written (the current one of a rotation).
    pub fn path(&self) -> &Path {
        &self.path
    }

    /// Whether the file is a FIFO that no reader has opened yet.
    pub fn waits_for_reader(&self) -> bool {
        self.shared.waiting_for_reader.load(Ordering::Acquire)
    }

    /// Declares an interface (a port, a link connection, a serial line).
    pub fn interface(&self, name: &str, role: Role) -> InterfaceId {
        let mut list = self.shared.interfaces.lock().unwrap_or_else(|e| e.into_inner());
        let id = self.shared.next_iface.fetch_add(1, Ordering::Relaxed);
        list.push((name.to_owned(), role));
        InterfaceId(id)
    }

    /// Records bytes read (inbound) or written (outbound) on `iface` at
    /// `at`. Never blocks: with the writer behind, the bytes are dropped and counted.
    pub fn record(&self, iface: InterfaceId, dir: Direction, at: SystemTime, bytes: &[u8]) {
        if bytes.is_empty() || !self.shared.active.load(Ordering::Relaxed) {
            return;
        }
        let msg = Msg::Bytes {
            iface: iface.0,
            dir,
            at,
            bytes: bytes.to_vec(),
        };
        if let Err(TrySendError::Full(_) | TrySendError::Disconnected(_)) = self.tx.try_send(msg) {
            self.shared.dropped.fetch_add(1, Ordering::Relaxed);
        }
    }

    /// The interface is gone: its incomplete bytes are written as noise.
    pub fn close_interface(&self, iface: InterfaceId) {
        let _ = self.tx.try_send(Msg::Close(iface.0));
    }

    /// Whether the capture still records (not stopped, no write error, budget left).
    pub fn is_active(&self) -> bool {
        self.shared.active.load(Ordering::Relaxed)
    }

    pub fn stats(&self) -> CaptureStats {
        let s = &self.shared;
        CaptureStats {
            records: s.records.load(Ordering::Relaxed),
            bytes_written: s.bytes.load(Ordering::Relaxed),
            dropped: s.dropped.load(Ordering::Relaxed),
            stopped: s.stopped.lock().unwrap_or_else(|e| e.into_inner()).clone(),
        }
    }

    /// Stops recording; the writer writes what is queued and ends. Waits up
    /// to `wait` for that (a stuck disk cannot hold the caller longer).
    pub fn stop(&self, wait: Duration) -> CaptureStats {
        self.shared.active.store(false, Ordering::Release);
        self.shared.stopping.store(true, Ordering::Release);
        let _ = self.tx.try_send(Msg::Wake);
        let until = Instant::now() + wait;
        let mut done = self.shared.done.lock().unwrap_or_else(|e| e.into_inner());
        while !*done {
            let left = until.saturating_duration_since(Instant::now());
            if left.is_zero() {
                break;
            }
            done = match self.shared.done_cv.wait_timeout(done, left) {
                Ok((d, _)) => d,
                Err(e) => e.into_inner().0,
            };
        }
        drop(done);
        self.stats()
    }
}
