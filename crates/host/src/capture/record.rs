//! The record inside each packet block (docs/capture.md): an 8-byte header
//! (version [`RECORD_VERSION`], [`RecordKind`], [`Direction`], [`Role`],
//! and the interface's number in the capturing program, u32 big endian),
//! then the raw bytes of the frame, byte or noise. The three code tables
//! are the protocol crate's (`sagebrush_protocol::capture_record`), where
//! the Wireshark dissector's tables are written from.

pub use sagebrush_protocol::capture_record::{Direction, RECORD_HEADER_LEN, RECORD_VERSION, RecordKind, Role};

/// A record: its header, then `data`.
pub fn record(kind: RecordKind, dir: Direction, role: Role, iface: u32, data: &[u8]) -> Vec<u8> {
    let mut record = Vec::with_capacity(RECORD_HEADER_LEN + data.len());
    record.extend_from_slice(&[RECORD_VERSION, kind.code(), dir.code(), role.code()]);
    record.extend_from_slice(&iface.to_be_bytes());
    record.extend_from_slice(data);
    record
}
