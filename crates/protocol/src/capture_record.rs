//! The capture record header's code tables (docs/capture.md): what a
//! record holds, which way its bytes went and which way commands flow on
//! its line. `sagebrush_host::capture` writes records with them; the
//! Wireshark dissector's tables are generated from them (by the `dissector` module).
//! A format of this workspace, not of the spec: declared here so that the
//! dissector has one source for every table it reads.

/// First byte of every record.
pub const RECORD_VERSION: u8 = 1;
/// Bytes of the record header before the raw bytes.
pub const RECORD_HEADER_LEN: usize = 8;

crate::code_table! {
    /// What a record holds (header byte 1).
    #[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
    pub enum RecordKind: u8 {
        Frame = 1, "frame", "a frame whose checksum holds";
        Ack = 2, "ack", "an ACK byte";
        Nak = 3, "nak", "a NAK byte";
        Nic = 4, "nic", "a NIC byte (?)";
        Noise = 5, "noise", "bytes between frames that are part of nothing";
        BadChecksum = 6, "bad_checksum", "a frame-sized candidate whose checksum failed: the bytes its length byte claims";
    }
}

crate::code_table! {
    /// Which way the bytes went, seen from the capturing program (header
    /// byte 2; the same values as the EPB flags' direction bits).
    #[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
    pub enum Direction: u8 {
        Inbound = 1, "inbound", "read by the capturing program";
        Outbound = 2, "outbound", "written by the capturing program";
    }
}

crate::code_table! {
    /// Which way commands flow on the line (header byte 3), so that a reader
    /// tells commands from results.
    #[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
    pub enum Role: u8 {
        Unknown = 0, "unknown", "not known to the capturing program";
        Master = 1, "master", "the capturing program sends the commands: a gcud device port or downstream link, gimbalctl";
        Responder = 2, "responder", "the capturing program receives the commands: a gcud client or upstream link, gimbalsim";
    }
}
