//! Traffic capture to pcapng files that Wireshark opens with
//! `tools/wireshark/sagebrush.lua` (layout: `docs/capture.md`), one module
//! per concern: the record format (`record`: its header and the kind,
//! direction and role tables) and the pcapng blocks around it (`pcapng`);
//! splitting a direction's bytes into records (`stream`); files, rotation
//! and FIFOs (`files`); the writer thread (`writer`); the handle callers
//! hold (`handle`); and capture switched on and off at run time
//! (`switch`). They depend one way, in that order from the handle down.
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

mod files;
mod handle;
mod pcapng;
mod record;
mod stream;
mod switch;
mod writer;

use std::io;
use std::path::Path;
use std::sync::Arc;

pub use files::rotated_path;
pub use handle::{Capture, CaptureStats, InterfaceId};
pub use pcapng::LINKTYPE;
pub use record::{Direction, RECORD_HEADER_LEN, RECORD_VERSION, RecordKind, Role};
pub use switch::{CaptureSwitch, Tap, Tapped};
pub use writer::CaptureConfig;

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
mod tests;
