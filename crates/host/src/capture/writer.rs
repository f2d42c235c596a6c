//! The writer thread: takes the chunks the handle queued, splits each
//! interface's directions into records (module `stream`), wraps them in
//! pcapng blocks (module `pcapng`) and writes whole blocks, so a file cut
//! short by a killed process ends on a block boundary; rotates by size and
//! count, stops at the byte budget, and on a write error stops the
//! capture with one error log.

use std::collections::HashMap;
use std::fs::File;
use std::io::{self, Write};
use std::path::PathBuf;
use std::sync::atomic::{AtomicBool, AtomicU32, AtomicU64, Ordering};
use std::sync::mpsc::{Receiver, RecvTimeoutError};
use std::sync::{Arc, Condvar, Mutex};
use std::time::{Duration, SystemTime};

use super::files::{create, open_fifo_when_read, rotate_files};
use super::pcapng::{interface_block, packet_block, packet_block_len, section_header};
use super::record::{Direction, RecordKind, Role, record};
use super::stream::Stream;

/// A stream with an incomplete frame silent this long: the frame is given up (noise).
const IDLE: Duration = Duration::from_millis(200);

/// File handling of a capture.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct CaptureConfig {
    /// Start a new file once the current one would grow past this; `None`: one file.
    pub rotate_bytes: Option<u64>,
    /// Files kept, the current one included (`capture.pcapng`,
    /// `capture.1.pcapng`, ...); at least 1.
    pub rotate_count: u32,
    /// Stop capturing once this many bytes were written in all files.
    pub budget_bytes: Option<u64>,
    /// Chunks waiting for the writer; more are dropped and counted.
    pub queue: usize,
    /// The SHB's `shb_userappl`.
    pub application: String,
}

impl Default for CaptureConfig {
    fn default() -> Self {
        Self {
            rotate_bytes: None,
            rotate_count: 4,
            budget_bytes: None,
            queue: 4096,
            application: "sagebrush".to_owned(),
        }
    }
}

/// What the capture's handle sends the writer thread.
#[derive(Debug)]
pub enum Msg {
    Bytes {
        iface: u32,
        dir: Direction,
        at: SystemTime,
        bytes: Vec<u8>,
    },
    Close(u32),
    Wake,
}

/// What the handle and the writer thread share.
#[derive(Debug, Default)]
pub struct Shared {
    pub active: AtomicBool,
    pub stopping: AtomicBool,
    /// A FIFO without a reader yet: the writer thread polls for one.
    pub waiting_for_reader: AtomicBool,
    pub records: AtomicU64,
    pub bytes: AtomicU64,
    pub dropped: AtomicU64,
    pub next_iface: AtomicU32,
    pub interfaces: Mutex<Vec<(String, Role)>>,
    pub stopped: Mutex<Option<String>>,
    pub done: Mutex<bool>,
    pub done_cv: Condvar,
}

/// The writer thread's state.
pub struct Writer {
    path: PathBuf,
    config: CaptureConfig,
    file: Option<File>,
    /// Bytes in the current file (written).
    file_bytes: u64,
    /// Interfaces declared in the current file: global id -> id in the file.
    file_ifaces: HashMap<u32, u32>,
    streams: HashMap<(u32, Direction), Stream>,
    /// Whole blocks not yet written.
    out: Vec<u8>,
    shared: Arc<Shared>,
    interfaces: Vec<(String, Role)>,
}

impl Writer {
    pub fn new(path: PathBuf, config: CaptureConfig, file: Option<File>, shared: Arc<Shared>) -> Self {
        let mut w = Self {
            path,
            config,
            file,
            file_bytes: 0,
            file_ifaces: HashMap::new(),
            streams: HashMap::new(),
            out: Vec::new(),
            shared,
            interfaces: Vec::new(),
        };
        let shb = section_header(&w.config.application);
        w.out.extend_from_slice(&shb);
        w
    }

    /// Writes what comes on `rx` until the capture stops or every sender is gone.
    pub fn run(mut self, rx: Receiver<Msg>) {
        if self.file.is_none() {
            // A FIFO: chunks wait in the queue until it has a reader.
            match open_fifo_when_read(&self.path, &self.shared.stopping) {
                Ok(Some(file)) => {
                    tracing::info!(file = %self.path.display(), "capture: the FIFO has a reader; writing");
                    self.file = Some(file);
                }
                Ok(None) => {
                    // Stopped before anyone read: what waited is dropped, and counted.
                    let waited = rx.try_iter().filter(|m| matches!(m, Msg::Bytes { .. })).count();
                    self.shared.dropped.fetch_add(waited as u64, Ordering::Relaxed);
                }
                Err(e) => self.give_up(format!("cannot open {}: {e}", self.path.display()), true),
            }
            self.shared.waiting_for_reader.store(false, Ordering::Release);
        }
        let mut ended = false;
        while !ended && self.file.is_some() {
            match rx.recv_timeout(Duration::from_millis(50)) {
                Ok(msg) => {
                    self.handle(msg);
                    // Bounded: what is queued now, at most the queue's size.
                    for _ in 0..self.config.queue {
                        match rx.try_recv() {
                            Ok(msg) => self.handle(msg),
                            Err(_) => break,
                        }
                    }
                }
                Err(RecvTimeoutError::Timeout) => {}
                Err(RecvTimeoutError::Disconnected) => ended = true,
            }
            if self.shared.stopping.load(Ordering::Acquire) {
                for _ in 0..self.config.queue {
                    match rx.try_recv() {
                        Ok(msg) => self.handle(msg),
                        Err(_) => break,
                    }
                }
                ended = true;
            }
            let idle: Vec<(u32, Direction)> = self
                .streams
                .iter()
                .filter(|(_, s)| s.silent_for(IDLE) || (ended && s.holds_bytes()))
                .map(|(k, _)| *k)
                .collect();
            for key in idle {
                self.flush_stream(key, false);
            }
            self.write_out();
        }
        self.shared.active.store(false, Ordering::Release);
        *self.shared.done.lock().unwrap_or_else(|e| e.into_inner()) = true;
        self.shared.done_cv.notify_all();
    }

    fn handle(&mut self, msg: Msg) {
        match msg {
            Msg::Bytes { iface, dir, at, bytes } => {
                let key = (iface, dir);
                let mut records = Vec::new();
                let stream = self.streams.entry(key).or_insert_with(Stream::new);
                stream.push(at, &bytes, &mut records);
                self.emit(key, &records);
            }
            Msg::Close(iface) => {
                for dir in Direction::ALL {
                    self.flush_stream((iface, dir), true);
                }
            }
            Msg::Wake => {}
        }
    }

    /// Gives up an incomplete candidate (line silent or closed).
    fn flush_stream(&mut self, key: (u32, Direction), remove: bool) {
        let Some(stream) = self.streams.get_mut(&key) else {
            return;
        };
        let mut records = Vec::new();
        stream.give_up(&mut records);
        self.emit(key, &records);
        if remove {
            self.streams.remove(&key);
        }
    }

    fn emit(&mut self, key: (u32, Direction), records: &[(RecordKind, u64, u64)]) {
        for &(kind, from, to) in records {
            let Some(stream) = self.streams.get(&key) else { return };
            let at = stream.time_of(from);
            let data = stream.bytes(from, to).to_vec();
            self.packet(key.0, key.1, kind, at, &data);
        }
        if let Some(stream) = self.streams.get_mut(&key) {
            stream.trim();
        }
    }

    fn role_of(&mut self, iface: u32) -> (String, Role) {
        if self.interfaces.len() <= iface as usize {
            let list = self.shared.interfaces.lock().unwrap_or_else(|e| e.into_inner());
            self.interfaces = list.clone();
        }
        self.interfaces
            .get(iface as usize)
            .cloned()
            .unwrap_or_else(|| (format!("interface {iface}"), Role::Unknown))
    }

    fn packet(&mut self, iface: u32, dir: Direction, kind: RecordKind, at: SystemTime, data: &[u8]) {
        if !self.shared.active.load(Ordering::Relaxed) && !self.shared.stopping.load(Ordering::Relaxed) {
            return;
        }
        let (name, role) = self.role_of(iface);
        let record = record(kind, dir, role, iface, data);
        let epb_len = packet_block_len(record.len());
        let idb_len = interface_block(&name).len() as u64;
        let pending = self.file_bytes + self.out.len() as u64;
        let declared = self.file_ifaces.contains_key(&iface);
        let needed = epb_len + if declared { 0 } else { idb_len };
        let rotate = self
            .config
            .rotate_bytes
            .is_some_and(|limit| pending + needed > limit && !self.file_ifaces.is_empty());
        if let Some(budget) = self.config.budget_bytes {
            let total = self.shared.bytes.load(Ordering::Relaxed) + self.out.len() as u64;
            let needed = match rotate {
                true => section_header(&self.config.application).len() as u64 + idb_len + epb_len,
                false => needed,
            };
            if total + needed > budget {
                return self.give_up(format!("capture budget of {budget} bytes reached"), false);
            }
        }
        if rotate {
            if let Err(e) = self.rotate() {
                return self.give_up(format!("cannot rotate {}: {e}", self.path.display()), true);
            }
        }
        let idb = (!self.file_ifaces.contains_key(&iface)).then(|| interface_block(&name));
        if let Some(idb) = idb {
            let id = self.file_ifaces.len() as u32;
            self.file_ifaces.insert(iface, id);
            self.out.extend_from_slice(&idb);
        }
        let file_id = self.file_ifaces[&iface];
        self.out.extend_from_slice(&packet_block(file_id, dir, at, &record));
        self.shared.records.fetch_add(1, Ordering::Relaxed);
        if self.out.len() >= 64 * 1024 {
            self.write_out();
        }
    }

    fn rotate(&mut self) -> io::Result<()> {
        self.write_out();
        if self.file.is_none() {
            return Err(io::Error::other("write failed"));
        }
        self.file = None;
        rotate_files(&self.path, self.config.rotate_count)?;
        self.file = Some(create(&self.path)?);
        self.file_bytes = 0;
        self.file_ifaces.clear();
        self.out.extend_from_slice(&section_header(&self.config.application));
        Ok(())
    }

    /// Writes the whole blocks gathered; on an error cuts a partial block
    /// off and stops.
    fn write_out(&mut self) {
        if self.out.is_empty() {
            return;
        }
        let Some(file) = self.file.as_mut() else {
            self.out.clear();
            return;
        };
        match file.write_all(&self.out) {
            Ok(()) => {
                self.file_bytes += self.out.len() as u64;
                self.shared.bytes.fetch_add(self.out.len() as u64, Ordering::Relaxed);
                self.out.clear();
            }
            Err(e) => {
                let _ = file.set_len(self.file_bytes);
                let why = format!("cannot write {}: {e}", self.path.display());
                self.give_up(why, true);
            }
        }
    }

    /// Stops capturing for good, with one log line.
    fn give_up(&mut self, why: String, error: bool) {
        let mut stopped = self.shared.stopped.lock().unwrap_or_else(|e| e.into_inner());
        if stopped.is_some() {
            // Records already queued meet the same end: said once.
            if error {
                self.out.clear();
                self.file = None;
            }
            return;
        }
        *stopped = Some(why.clone());
        drop(stopped);
        if error {
            tracing::error!(file = %self.path.display(), "capture stopped: {why}");
        } else {
            tracing::warn!(file = %self.path.display(), "capture stopped: {why}");
        }
        self.shared.active.store(false, Ordering::Release);
        if error {
            self.out.clear();
            self.file = None;
        } else {
            // Budget: what was gathered is whole; write it and end.
            self.shared.stopping.store(true, Ordering::Release);
        }
    }
}
