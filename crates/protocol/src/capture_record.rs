//! The capture record header's code tables (docs/capture.md): what a
//! record holds, which way its bytes went and which way commands flow on
//! its line. `sagebrush_host::capture` writes records with them; the
//! Wireshark dissector's tables are generated from them (by the `dissector` module).
//! A format of this workspace, not of the spec: declared here so that the
//! dissector has one source for every table it reads.
//!
//! Each table gives its first code; the others run on in row order, so a
//! new row goes at the end and files written before it keep their meaning.

/// First byte of every record.
pub const RECORD_VERSION: u8 = 1;
/// Bytes of the record header before the raw bytes.
pub const RECORD_HEADER_LEN: usize = 8;

crate::code_table! {
    /// What a record holds (header byte 1).
    pub enum RecordKind: u8 {
        /// a frame whose checksum holds
        Frame = 1,
        /// an ACK byte
        Ack,
        /// a NAK byte
        Nak,
        /// a NIC byte (?)
        Nic,
        /// bytes between frames that are part of nothing
        Noise,
        /// a frame-sized candidate whose checksum failed: the bytes its length byte claims
        BadChecksum,
    }
}

crate::code_table! {
    /// Which way the bytes went, seen from the capturing program (header
    /// byte 2; the same values as the EPB flags' direction bits).
    pub enum Direction: u8 {
        /// read by the capturing program
        Inbound = 1,
        /// written by the capturing program
        Outbound,
    }
}

crate::code_table! {
    /// Which way commands flow on the line (header byte 3), so that a reader
    /// tells commands from results.
    pub enum Role: u8 {
        /// not known to the capturing program
        Unknown = 0,
        /// the capturing program sends the commands: a gcud device port or downstream link, gimbalctl
        Master,
        /// the capturing program receives the commands: a gcud client or upstream link, gimbalsim
        Responder,
    }
}
