//! The pcapng blocks a capture file is made of (pcapng, IETF draft
//! `draft-ietf-opsawg-pcapng`): a section header (SHB) naming the program,
//! an interface description (IDB) per interface, of link type
//! [`LINKTYPE`], and an enhanced packet block (EPB) per record, stamped in
//! microseconds, its flags saying inbound or outbound.

use std::time::{SystemTime, UNIX_EPOCH};

use super::record::Direction;

/// `LINKTYPE_USER0`: the pcap community's link type for private protocols.
pub const LINKTYPE: u16 = 147;

/// The length of [`packet_block`] for a record of `record_len` bytes: the
/// block's 12 bytes of type and lengths, 20 of interface, time and
/// lengths, the padded record and 12 of options (flags, end).
pub fn packet_block_len(record_len: usize) -> u64 {
    (12 + 20 + pad4(record_len) + 12) as u64
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

pub fn section_header(application: &str) -> Vec<u8> {
    let mut body = Vec::new();
    body.extend_from_slice(&0x1A2B_3C4Du32.to_le_bytes());
    body.extend_from_slice(&1u16.to_le_bytes());
    body.extend_from_slice(&0u16.to_le_bytes());
    body.extend_from_slice(&(-1i64).to_le_bytes());
    option(&mut body, 4, application.as_bytes()); // shb_userappl
    option(&mut body, 0, &[]);
    block(0x0A0D_0D0A, &body)
}

pub fn interface_block(name: &str) -> Vec<u8> {
    let mut body = Vec::new();
    body.extend_from_slice(&LINKTYPE.to_le_bytes());
    body.extend_from_slice(&0u16.to_le_bytes());
    body.extend_from_slice(&0u32.to_le_bytes()); // snaplen: no limit
    option(&mut body, 2, name.as_bytes()); // if_name
    option(&mut body, 9, &[6]); // if_tsresol: microseconds
    option(&mut body, 0, &[]);
    block(1, &body)
}

pub fn packet_block(iface: u32, dir: Direction, at: SystemTime, record: &[u8]) -> Vec<u8> {
    let micros = at.duration_since(UNIX_EPOCH).map_or(0, |d| d.as_micros() as u64);
    let mut body = Vec::with_capacity(32 + record.len());
    body.extend_from_slice(&iface.to_le_bytes());
    body.extend_from_slice(&((micros >> 32) as u32).to_le_bytes());
    body.extend_from_slice(&(micros as u32).to_le_bytes());
    body.extend_from_slice(&(record.len() as u32).to_le_bytes());
    body.extend_from_slice(&(record.len() as u32).to_le_bytes());
    body.extend_from_slice(record);
    body.resize(pad4(body.len()), 0);
    option(&mut body, 2, &u32::from(dir.code()).to_le_bytes()); // epb_flags: 1 inbound, 2 outbound
    option(&mut body, 0, &[]);
    block(6, &body)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_packet_block_is_as_long_as_said() {
        for n in 0..9 {
            let block = packet_block(0, Direction::Inbound, SystemTime::now(), &vec![0; n]);
            assert_eq!(block.len() as u64, packet_block_len(n), "{n}-byte record");
        }
    }
}
