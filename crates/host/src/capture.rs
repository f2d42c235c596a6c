//! Traffic capture to pcapng files that Wireshark opens with
//! `tools/wireshark/sagebrush.lua` (layout: `docs/capture.md`).
//!
//! - Link type `LINKTYPE_USER0` (147), one interface (IDB) per port or link
//!   connection, named by the caller (`port 1 /dev/ttyUSB0`).
//! - One record (EPB) per frame, bare ACK/NAK/NIC byte, bad-checksum
//!   candidate or run of noise bytes, split by the protocol crate's
//!   [`Framer`] per interface and direction, stamped with the time the chunk
//!   holding its first byte was read or written; EPB flags say inbound or
//!   outbound. Each record starts with an 8-byte header: version (1), kind
//!   ([`RecordKind`]), direction ([`Direction`]), role ([`Role`]), and the
//!   interface's number in the capturing program (u32, big endian; the same
//!   in every rotated file, so a reader pairs by it without frame fields).
//! - The caller never waits: [`Capture::record`] copies the bytes into a
//!   bounded channel (a full channel drops and counts them); a writer thread
//!   frames them and writes whole blocks, so a file cut short by a killed
//!   process ends on a block boundary. Rotation by size and count, a total
//!   byte budget; a write error stops the capture with one error log.
//! - A FIFO as the file (Wireshark reading live) is opened by the writer
//!   thread, without blocking, once a reader has opened it; until then
//!   chunks wait in the queue (and beyond it are dropped and counted). The
//!   caller never opens or writes the FIFO.
//! - [`CaptureSwitch`] and [`Tap`]: capture started and stopped at run time
//!   (gcud's SIGUSR1); a tap costs one atomic load while capture is off.
//!
//! ```no_run
//! use sagebrush_host::capture::{Capture, CaptureConfig, Direction, Role};
//! let capture = Capture::open("bus.pcapng", CaptureConfig::default())?;
//! let bus = capture.interface("gimbalctl /dev/ttyUSB0", Role::Master);
//! capture.record(bus, Direction::Outbound, std::time::SystemTime::now(), b"\x06");
//! capture.stop(std::time::Duration::from_secs(1));
//! # Ok::<(), std::io::Error>(())
//! ```

use std::collections::{HashMap, VecDeque};
use std::fs::{File, OpenOptions};
use std::io::{self, Write};
use std::path::{Path, PathBuf};
use std::pin::Pin;
use std::sync::atomic::{AtomicBool, AtomicU32, AtomicU64, Ordering};
use std::sync::mpsc::{Receiver, RecvTimeoutError, SyncSender, TrySendError, sync_channel};
use std::sync::{Arc, Condvar, Mutex};
use std::task::{Context, Poll};
use std::time::{Duration, Instant, SystemTime, UNIX_EPOCH};

use sagebrush_protocol::{Event, Framer};
use tokio::io::{AsyncRead, AsyncWrite, ReadBuf};

/// `LINKTYPE_USER0`: the pcap community's link type for private protocols.
pub const LINKTYPE: u16 = 147;
/// First byte of every record.
pub const RECORD_VERSION: u8 = 1;
/// Bytes of the record header before the raw bytes.
pub const RECORD_HEADER_LEN: usize = 8;
/// A stream with an incomplete frame silent this long: the frame is given up (noise).
const IDLE: Duration = Duration::from_millis(200);

/// What a record holds (header byte 1).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
#[repr(u8)]
pub enum RecordKind {
    /// A frame whose checksum holds.
    Frame = 1,
    Ack = 2,
    Nak = 3,
    Nic = 4,
    /// Bytes between frames that are part of nothing.
    Noise = 5,
    /// A frame-sized candidate whose checksum failed: the bytes its length byte claims.
    BadChecksum = 6,
}

/// Which way the bytes went, seen from the capturing program (header byte 2;
/// the same values as the EPB flags' direction bits).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
#[repr(u8)]
pub enum Direction {
    /// Read by the capturing program.
    Inbound = 1,
    /// Written by the capturing program.
    Outbound = 2,
}

/// Which way commands flow on the line (header byte 3), so that a reader
/// tells commands from results.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
#[repr(u8)]
pub enum Role {
    Unknown = 0,
    /// The capturing program sends the commands: a gcud device port or
    /// downstream link, gimbalctl.
    Master = 1,
    /// The capturing program receives the commands: a gcud client or
    /// upstream link, gimbalsim.
    Responder = 2,
}

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

#[derive(Debug)]
enum Msg {
    Bytes {
        iface: u32,
        dir: Direction,
        at: SystemTime,
        bytes: Vec<u8>,
    },
    Close(u32),
    Wake,
}

#[derive(Debug, Default)]
struct Shared {
    active: AtomicBool,
    stopping: AtomicBool,
    /// A FIFO without a reader yet: the writer thread polls for one.
    waiting_for_reader: AtomicBool,
    records: AtomicU64,
    bytes: AtomicU64,
    dropped: AtomicU64,
    next_iface: AtomicU32,
    interfaces: Mutex<Vec<(String, Role)>>,
    stopped: Mutex<Option<String>>,
    done: Mutex<bool>,
    done_cv: Condvar,
}

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

fn create(path: &Path) -> io::Result<File> {
    OpenOptions::new().write(true).create(true).truncate(true).open(path)
}

fn is_fifo(path: &Path) -> bool {
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
fn open_fifo_when_read(path: &Path, stopping: &AtomicBool) -> io::Result<Option<File>> {
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
fn rotate_files(path: &Path, count: u32) -> io::Result<()> {
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

/// One direction of one interface, split into records.
struct Stream {
    framer: Box<Framer>,
    /// Bytes from stream offset `base` on, kept until recorded.
    raw: Vec<u8>,
    base: u64,
    /// Bytes before this offset are in a record.
    covered: u64,
    /// Stream offset and time of each chunk still in `raw`.
    chunks: VecDeque<(u64, SystemTime)>,
    last: Instant,
}

impl Stream {
    fn new() -> Self {
        Self {
            framer: Box::new(Framer::new()),
            raw: Vec::new(),
            base: 0,
            covered: 0,
            chunks: VecDeque::new(),
            last: Instant::now(),
        }
    }

    fn time_of(&self, offset: u64) -> SystemTime {
        self.chunks
            .iter()
            .rev()
            .find(|(start, _)| *start <= offset)
            .or(self.chunks.front())
            .map_or_else(SystemTime::now, |(_, t)| *t)
    }

    fn bytes(&self, from: u64, to: u64) -> &[u8] {
        let a = (from.saturating_sub(self.base) as usize).min(self.raw.len());
        let b = (to.saturating_sub(self.base) as usize).min(self.raw.len());
        &self.raw[a..b.max(a)]
    }

    /// Collects the framer's decisions as (kind, start, end) records.
    fn drain(&mut self, out: &mut Vec<(RecordKind, u64, u64)>) {
        // Each event consumes at least one byte of a bounded buffer.
        for _ in 0..=self.raw.len() + 1 {
            let (kind, bad_at, len) = match self.framer.next_event() {
                None => break,
                Some(Event::Frame(f)) => (RecordKind::Frame, None, f.wire_len() as u64),
                Some(Event::Ack) => (RecordKind::Ack, None, 1),
                Some(Event::Nak) => (RecordKind::Nak, None, 1),
                Some(Event::Nic) => (RecordKind::Nic, None, 1),
                Some(Event::BadChecksum(b)) => (RecordKind::BadChecksum, Some(b.offset), 7 + b.payload_len as u64),
            };
            let end_consumed = self.framer.stream_offset();
            let start = bad_at.unwrap_or_else(|| end_consumed.saturating_sub(len));
            if start > self.covered {
                out.push((RecordKind::Noise, self.covered, start));
            }
            out.push((kind, start, start + len));
            self.covered = self.covered.max(start + len);
        }
        let decided = self.framer.stream_offset();
        if decided > self.covered {
            out.push((RecordKind::Noise, self.covered, decided));
            self.covered = decided;
        }
    }

    /// Forgets bytes no record can need any more.
    fn trim(&mut self) {
        let keep = self.covered.min(self.framer.stream_offset());
        if keep > self.base {
            let n = ((keep - self.base) as usize).min(self.raw.len());
            self.raw.drain(..n);
            self.base += n as u64;
        }
        while self.chunks.len() > 1 && self.chunks[1].0 <= self.base {
            self.chunks.pop_front();
        }
    }
}

struct Writer {
    path: PathBuf,
    config: CaptureConfig,
    file: Option<File>,
    /// Bytes in the current file (written).
    file_bytes: u64,
    /// Interfaces declared in the current file: global id -> id in the file.
    file_ifaces: HashMap<u32, u32>,
    streams: HashMap<(u32, u8), Stream>,
    /// Whole blocks not yet written.
    out: Vec<u8>,
    shared: Arc<Shared>,
    interfaces: Vec<(String, Role)>,
}

impl Writer {
    fn new(path: PathBuf, config: CaptureConfig, file: Option<File>, shared: Arc<Shared>) -> Self {
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

    fn run(mut self, rx: Receiver<Msg>) {
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
            let idle: Vec<(u32, u8)> = self
                .streams
                .iter()
                .filter(|(_, s)| (ended || s.last.elapsed() >= IDLE) && s.framer.buffered() > 0)
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
                let key = (iface, dir as u8);
                let stream = self.streams.entry(key).or_insert_with(Stream::new);
                let offset = stream.base + stream.raw.len() as u64;
                stream.chunks.push_back((offset, at));
                stream.raw.extend_from_slice(&bytes);
                stream.last = Instant::now();
                let mut records = Vec::new();
                let mut input = bytes.as_slice();
                // Each round pushes at least one byte (the framer drains to make room).
                for _ in 0..=bytes.len() {
                    if input.is_empty() {
                        break;
                    }
                    let n = stream.framer.push(input);
                    input = &input[n..];
                    stream.drain(&mut records);
                    if n == 0 && stream.framer.buffered() > 0 {
                        // Full of an undecidable candidate: give it up.
                        stream.framer.line_idle();
                        stream.drain(&mut records);
                    }
                }
                self.emit(key, dir, &records);
            }
            Msg::Close(iface) => {
                for dir in [Direction::Inbound as u8, Direction::Outbound as u8] {
                    self.flush_stream((iface, dir), true);
                }
            }
            Msg::Wake => {}
        }
    }

    /// Gives up an incomplete candidate (line silent or closed).
    fn flush_stream(&mut self, key: (u32, u8), remove: bool) {
        let Some(stream) = self.streams.get_mut(&key) else {
            return;
        };
        let mut records = Vec::new();
        stream.framer.line_idle();
        stream.drain(&mut records);
        let dir = if key.1 == Direction::Inbound as u8 {
            Direction::Inbound
        } else {
            Direction::Outbound
        };
        self.emit(key, dir, &records);
        if remove {
            self.streams.remove(&key);
        }
    }

    fn emit(&mut self, key: (u32, u8), dir: Direction, records: &[(RecordKind, u64, u64)]) {
        for &(kind, from, to) in records {
            let Some(stream) = self.streams.get(&key) else { return };
            let at = stream.time_of(from);
            let data = stream.bytes(from, to).to_vec();
            self.packet(key.0, dir, kind, at, &data);
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
        let mut record = Vec::with_capacity(RECORD_HEADER_LEN + data.len());
        record.extend_from_slice(&[RECORD_VERSION, kind as u8, dir as u8, role as u8]);
        record.extend_from_slice(&iface.to_be_bytes());
        record.extend_from_slice(data);
        let epb_len = (32 + pad4(record.len()) + 12 + 4) as u64;
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

fn pad4(n: usize) -> usize {
    n.div_ceil(4) * 4
}

fn option(out: &mut Vec<u8>, code: u16, value: &[u8]) {
    out.extend_from_slice(&code.to_le_bytes());
    out.extend_from_slice(&(value.len() as u16).to_le_bytes());
    out.extend_from_slice(value);
    out.resize(pad4(out.len()), 0);
}

/// A block: type, total length, body (padded), total length.
fn block(kind: u32, body: &[u8]) -> Vec<u8> {
    let total = (12 + pad4(body.len())) as u32;
    let mut b = Vec::with_capacity(total as usize);
    b.extend_from_slice(&kind.to_le_bytes());
    b.extend_from_slice(&total.to_le_bytes());
    b.extend_from_slice(body);
    b.resize(8 + pad4(body.len()), 0);
    b.extend_from_slice(&total.to_le_bytes());
    b
}

fn section_header(application: &str) -> Vec<u8> {
    let mut body = Vec::new();
    body.extend_from_slice(&0x1A2B_3C4Du32.to_le_bytes());
    body.extend_from_slice(&1u16.to_le_bytes());
    body.extend_from_slice(&0u16.to_le_bytes());
    body.extend_from_slice(&(-1i64).to_le_bytes());
    option(&mut body, 4, application.as_bytes()); // shb_userappl
    option(&mut body, 0, &[]);
    block(0x0A0D_0D0A, &body)
}

fn interface_block(name: &str) -> Vec<u8> {
    let mut body = Vec::new();
    body.extend_from_slice(&LINKTYPE.to_le_bytes());
    body.extend_from_slice(&0u16.to_le_bytes());
    body.extend_from_slice(&0u32.to_le_bytes()); // snaplen: no limit
    option(&mut body, 2, name.as_bytes()); // if_name
    option(&mut body, 9, &[6]); // if_tsresol: microseconds
    option(&mut body, 0, &[]);
    block(1, &body)
}

fn packet_block(iface: u32, dir: Direction, at: SystemTime, record: &[u8]) -> Vec<u8> {
    let micros = at.duration_since(UNIX_EPOCH).map_or(0, |d| d.as_micros() as u64);
    let mut body = Vec::with_capacity(32 + record.len());
    body.extend_from_slice(&iface.to_le_bytes());
    body.extend_from_slice(&((micros >> 32) as u32).to_le_bytes());
    body.extend_from_slice(&(micros as u32).to_le_bytes());
    body.extend_from_slice(&(record.len() as u32).to_le_bytes());
    body.extend_from_slice(&(record.len() as u32).to_le_bytes());
    body.extend_from_slice(record);
    body.resize(pad4(body.len()), 0);
    option(&mut body, 2, &(dir as u32).to_le_bytes()); // epb_flags: 1 inbound, 2 outbound
    option(&mut body, 0, &[]);
    block(6, &body)
}

// ---- run-time switch -----------------------------------------------------------

/// The capture a program may start and stop while it runs; [`Tap`]s follow it.
#[derive(Debug, Default)]
pub struct CaptureSwitch {
    on: AtomicBool,
    generation: AtomicU64,
    current: Mutex<Option<Capture>>,
}

impl CaptureSwitch {
    pub fn new() -> Arc<Self> {
        Arc::new(Self::default())
    }

    /// Records into `capture` from now on; returns the capture it replaces (stop it).
    pub fn start(&self, capture: Capture) -> Option<Capture> {
        let mut current = self.current.lock().unwrap_or_else(|e| e.into_inner());
        let old = current.replace(capture);
        self.generation.fetch_add(1, Ordering::AcqRel);
        self.on.store(true, Ordering::Release);
        old
    }

    /// Stops recording; returns the capture to [`Capture::stop`].
    pub fn stop(&self) -> Option<Capture> {
        let mut current = self.current.lock().unwrap_or_else(|e| e.into_inner());
        self.on.store(false, Ordering::Release);
        self.generation.fetch_add(1, Ordering::AcqRel);
        current.take()
    }

    /// Whether a capture is running (it may have stopped itself: see [`Capture::is_active`]).
    pub fn current(&self) -> Option<Capture> {
        self.current.lock().unwrap_or_else(|e| e.into_inner()).clone()
    }

    /// A tap for one interface named `name`.
    pub fn tap(self: &Arc<Self>, name: impl Into<String>, role: Role) -> Tap {
        Tap {
            switch: self.clone(),
            name: name.into(),
            role,
            bound: None,
        }
    }
}

/// One interface's hook into a [`CaptureSwitch`]: call [`Tap::inbound`]
/// with what was read and [`Tap::outbound`] with what is written. While
/// capture is off each call is one atomic load.
#[derive(Debug)]
pub struct Tap {
    switch: Arc<CaptureSwitch>,
    name: String,
    role: Role,
    bound: Option<(u64, Capture, InterfaceId)>,
}

impl Tap {
    #[inline]
    pub fn inbound(&mut self, bytes: &[u8]) {
        if self.switch.on.load(Ordering::Relaxed) {
            self.record(Direction::Inbound, bytes);
        }
    }

    #[inline]
    pub fn outbound(&mut self, bytes: &[u8]) {
        if self.switch.on.load(Ordering::Relaxed) {
            self.record(Direction::Outbound, bytes);
        }
    }

    #[cold]
    fn record(&mut self, dir: Direction, bytes: &[u8]) {
        let at = SystemTime::now();
        let generation = self.switch.generation.load(Ordering::Acquire);
        if self.bound.as_ref().is_none_or(|(g, _, _)| *g != generation) {
            if let Some((_, old, id)) = self.bound.take() {
                old.close_interface(id);
            }
            let Some(capture) = self.switch.current() else { return };
            let id = capture.interface(&self.name, self.role);
            self.bound = Some((generation, capture, id));
        }
        if let Some((_, capture, id)) = &self.bound {
            capture.record(*id, dir, at, bytes);
        }
    }
}

impl Drop for Tap {
    fn drop(&mut self) {
        if let Some((_, capture, id)) = &self.bound {
            capture.close_interface(*id);
        }
    }
}

/// A stream whose bytes a [`Tap`] records: what is read as inbound, what is
/// written as outbound. For programs whose line is one stream (gimbalctl,
/// gimbalsim); gcud taps its pumps directly.
#[derive(Debug)]
pub struct Tapped<S> {
    inner: S,
    tap: Tap,
}

impl<S> Tapped<S> {
    pub fn new(inner: S, tap: Tap) -> Self {
        Self { inner, tap }
    }

    pub fn get_ref(&self) -> &S {
        &self.inner
    }

    pub fn get_mut(&mut self) -> &mut S {
        &mut self.inner
    }
}

impl<S: AsyncRead + Unpin> AsyncRead for Tapped<S> {
    fn poll_read(self: Pin<&mut Self>, cx: &mut Context<'_>, buf: &mut ReadBuf<'_>) -> Poll<io::Result<()>> {
        let this = self.get_mut();
        let before = buf.filled().len();
        let polled = Pin::new(&mut this.inner).poll_read(cx, buf);
        if let Poll::Ready(Ok(())) = &polled {
            let read = &buf.filled()[before..];
            if !read.is_empty() {
                this.tap.inbound(read);
            }
        }
        polled
    }
}

impl<S: AsyncWrite + Unpin> AsyncWrite for Tapped<S> {
    fn poll_write(self: Pin<&mut Self>, cx: &mut Context<'_>, buf: &[u8]) -> Poll<io::Result<usize>> {
        let this = self.get_mut();
        let polled = Pin::new(&mut this.inner).poll_write(cx, buf);
        if let Poll::Ready(Ok(n)) = &polled {
            this.tap.outbound(&buf[..*n]);
        }
        polled
    }

    fn poll_flush(self: Pin<&mut Self>, cx: &mut Context<'_>) -> Poll<io::Result<()>> {
        Pin::new(&mut self.get_mut().inner).poll_flush(cx)
    }

    fn poll_shutdown(self: Pin<&mut Self>, cx: &mut Context<'_>) -> Poll<io::Result<()>> {
        Pin::new(&mut self.get_mut().inner).poll_shutdown(cx)
    }
}

/// A capture to `path` from start to exit, for a program's `--capture
/// FILE`: the switch its [`Tap`]s follow, already on, and the capture to
/// [`Capture::stop`] before the program exits (so the file is complete).
/// `application` names the program in the file's section header.
pub fn capture_to(path: &Path, application: &str) -> io::Result<(Arc<CaptureSwitch>, Capture)> {
    let config = CaptureConfig {
        application: application.to_owned(),
        ..CaptureConfig::default()
    };
    let capture = Capture::open(path, config)?;
    let switch = CaptureSwitch::new();
    switch.start(capture.clone());
    Ok((switch, capture))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// (interface id, EPB flags, record) of each EPB.
    type Packets = Vec<(u32, u32, Vec<u8>)>;

    /// The IDB names and the EPBs of a file.
    fn read(path: &Path) -> (Vec<String>, Packets) {
        let data = std::fs::read(path).unwrap();
        let (mut names, mut packets, mut at) = (Vec::new(), Vec::new(), 0);
        let u32_at = |i: usize| u32::from_le_bytes(data[i..i + 4].try_into().unwrap());
        while at + 12 <= data.len() {
            let (kind, len) = (u32_at(at), u32_at(at + 4) as usize);
            assert_eq!(u32_at(at + len - 4) as usize, len, "trailing length");
            if kind == 1 {
                assert_eq!(u16::from_le_bytes([data[at + 8], data[at + 9]]), LINKTYPE);
                let nlen = u16::from_le_bytes([data[at + 18], data[at + 19]]) as usize;
                names.push(String::from_utf8(data[at + 20..at + 20 + nlen].to_vec()).unwrap());
            }
            if kind == 6 {
                let cap = u32_at(at + 20) as usize;
                let rec = data[at + 28..at + 28 + cap].to_vec();
                let flags = u32_at(at + 28 + pad4(cap) + 4);
                packets.push((u32_at(at + 8), flags, rec));
            }
            at += len;
        }
        assert_eq!(at, data.len(), "whole blocks only");
        (names, packets)
    }

    #[test]
    fn frames_acks_noise_and_bad_checksums_become_records_across_chunks() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("t.pcapng");
        let c = Capture::open(&path, CaptureConfig::default()).unwrap();
        let port = c.interface("port 1 /dev/x", Role::Master);
        let now = SystemTime::now();
        // P? to 5.1.1 from 0, split over two chunks, then noise, ACK, a bad frame, NIC.
        let frame = [0xF8, 5, 1, 1, 0, 2, b'P', b'?', 0x98];
        c.record(port, Direction::Outbound, now, &frame[..4]);
        c.record(port, Direction::Outbound, now, &frame[4..]);
        c.record(port, Direction::Inbound, now, &[b'x', b'y', 0x06]);
        c.record(port, Direction::Inbound, now, &[0xF8, 5, 1, 1, 0, 1, b'A', 0x00, b'?']);
        let stats = c.stop(Duration::from_secs(5));
        assert_eq!(stats.stopped, None);
        let (names, packets) = read(&path);
        assert_eq!(names, ["port 1 /dev/x"]);
        let kinds: Vec<(u32, u8, u8, u8)> = packets.iter().map(|(_, f, r)| (*f, r[1], r[2], r[3])).collect();
        assert_eq!(
            kinds,
            [(2, 1, 2, 1), (1, 5, 1, 1), (1, 2, 1, 1), (1, 6, 1, 1), (1, 4, 1, 1)],
            "{packets:?}"
        );
        assert_eq!(&packets[0].2[4..8], &[0, 0, 0, 0], "interface number");
        assert_eq!(&packets[0].2[8..], &frame);
        assert_eq!(&packets[1].2[8..], b"xy");
        assert_eq!(&packets[3].2[8..], &[0xF8, 5, 1, 1, 0, 1, b'A', 0x00]);
    }

    #[test]
    fn an_incomplete_frame_becomes_noise_when_the_interface_closes() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("t.pcapng");
        let c = Capture::open(&path, CaptureConfig::default()).unwrap();
        let i = c.interface("link a", Role::Responder);
        c.record(i, Direction::Inbound, SystemTime::now(), &[0xF8, 5, 1]);
        c.close_interface(i);
        c.stop(Duration::from_secs(5));
        let (_, packets) = read(&path);
        assert_eq!(packets.len(), 1);
        assert_eq!(packets[0].2, [1, 5, 1, 2, 0, 0, 0, 0, 0xF8, 5, 1]);
    }

    #[test]
    fn files_rotate_by_size_and_count_and_the_budget_stops_the_capture() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("r.pcapng");
        let config = CaptureConfig {
            rotate_bytes: Some(1000),
            rotate_count: 3,
            budget_bytes: Some(5000),
            ..CaptureConfig::default()
        };
        let c = Capture::open(&path, config).unwrap();
        let i = c.interface("port 1", Role::Master);
        for _ in 0..200 {
            c.record(i, Direction::Inbound, SystemTime::now(), &[0x06]);
        }
        let stats = c.stop(Duration::from_secs(5));
        assert!(stats.stopped.as_deref().unwrap_or("").contains("budget"), "{stats:?}");
        assert!(stats.bytes_written <= 5000, "{stats:?}");
        for n in 0..3 {
            let p = rotated_path(&path, n);
            let len = std::fs::metadata(&p).unwrap().len();
            assert!(len <= 1000, "{} is {len} bytes", p.display());
            let (names, packets) = read(&p);
            assert_eq!(names, ["port 1"], "each file declares its interface");
            assert!(!packets.is_empty());
        }
        assert!(!rotated_path(&path, 3).exists());
    }

    #[test]
    fn a_write_error_stops_the_capture_without_blocking_the_caller() {
        let c = Capture::open("/dev/full", CaptureConfig::default()).unwrap();
        let i = c.interface("port 1", Role::Master);
        let started = Instant::now();
        for _ in 0..10_000 {
            c.record(i, Direction::Inbound, SystemTime::now(), &[0x06]);
        }
        assert!(started.elapsed() < Duration::from_secs(5));
        let stats = c.stop(Duration::from_secs(5));
        assert!(
            stats.stopped.as_deref().unwrap_or("").contains("cannot write"),
            "{stats:?}"
        );
        assert!(!c.is_active());
    }

    #[test]
    fn a_fifo_is_opened_by_the_writer_once_it_has_a_reader() {
        let dir = tempfile::tempdir().unwrap();
        let fifo = dir.path().join("live.pcapng");
        nix::unistd::mkfifo(&fifo, nix::sys::stat::Mode::from_bits_truncate(0o600)).unwrap();
        // Nobody reads: open returns at once, and so does stop.
        let c = Capture::open(&fifo, CaptureConfig::default()).unwrap();
        assert!(c.waits_for_reader());
        let i = c.interface("port 1", Role::Master);
        c.record(i, Direction::Inbound, SystemTime::now(), &[0x06]);
        let stats = c.stop(Duration::from_secs(5));
        assert_eq!(
            (stats.records, stats.dropped, stats.stopped),
            (0, 1, None),
            "nothing written, what waited counted, no error"
        );

        let c = Capture::open(&fifo, CaptureConfig::default()).unwrap();
        let i = c.interface("port 1", Role::Master);
        c.record(i, Direction::Inbound, SystemTime::now(), &[0x06]);
        let copy = dir.path().join("copy.pcapng");
        let (from, to) = (fifo.clone(), copy.clone());
        let reader = std::thread::spawn(move || std::fs::write(to, std::fs::read(from).unwrap()).unwrap());
        let started = Instant::now();
        while c.waits_for_reader() && started.elapsed() < Duration::from_secs(30) {
            std::thread::sleep(Duration::from_millis(10));
        }
        assert!(!c.waits_for_reader(), "the writer opened the FIFO");
        c.record(i, Direction::Outbound, SystemTime::now(), &[0x15]);
        let stats = c.stop(Duration::from_secs(5));
        reader.join().unwrap();
        let (names, packets) = read(&copy);
        assert_eq!(names, ["port 1"]);
        assert_eq!(packets.len(), 2, "{stats:?}");
    }

    #[test]
    fn taps_follow_the_switch() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("s.pcapng");
        let switch = CaptureSwitch::new();
        let mut tap = switch.tap("port 2", Role::Master);
        tap.outbound(&[0x06]); // off: nothing
        assert!(
            switch
                .start(Capture::open(&path, CaptureConfig::default()).unwrap())
                .is_none()
        );
        tap.outbound(&[0x15]);
        let c = switch.stop().unwrap();
        tap.outbound(&[0x06]);
        c.stop(Duration::from_secs(5));
        let (names, packets) = read(&path);
        assert_eq!(names, ["port 2"]);
        assert_eq!(packets.len(), 1);
        assert_eq!(packets[0].2, [1, 3, 2, 1, 0, 0, 0, 0, 0x15]);
    }
}
