//! MAVLink 2 message signing (mavlink.io/en/guide/message_signing.html),
//! carried out by the `mavlink` crate (`SigningData`, feature
//! `mav2-message-signing`): with a `[signing]` key every frame this door
//! sends is signed, and every intact frame heard is checked before anything
//! reads it (`net::Net::admits`: before a UDP address takes a peer slot,
//! before its sender counts as heard, before the router).
//!
//! Only a frame signed with the key whose timestamp is newer than the last
//! one of its stream (link id, system, component; a new stream at most a
//! minute older than the newest timestamp known) is read. Everything else
//! is refused, HEARTBEAT included: the signing guide lets a system accept
//! some unsigned messages, but here a heartbeat makes its sender heard,
//! which keeps a control owner in control, lets control be given to it, and
//! is where its answers go, so an unsigned one would let anyone on the
//! link keep or divert another's control. MAVLink 1 frames cannot be
//! signed: refused. A refusal is counted by kind and logged once per peer
//! address in [`LOG_EVERY`], with the count held back in between.
//!
//! The key file holds the 32-byte secret key as 64 hexadecimal digits
//! (whitespace around them allowed): the SHA-256 of a passphrase as
//! MAVProxy's `signing setup` and QGroundControl derive it, or random
//! bytes, and the bytes pymavlink's `setup_signing` takes.

use std::fmt;
use std::sync::Mutex;
use std::time::Duration;

use mavlink::consts::MAX_FRAME_SIZE;
use mavlink::{MAVLinkV2MessageRaw, SigningConfig, SigningData};
use sagebrush_service::rate::LogGate;
use tokio::time::Instant;
use tracing::warn;

use crate::stats::{Stats, may_warn, peer_ip};
use crate::transport::wire::{SIGNED, V2_MAGIC};

/// A peer's refusals are logged at most once in this long.
pub const LOG_EVERY: Duration = Duration::from_secs(10);
/// Peer addresses whose last refusal log is remembered.
const LOG_PEERS: usize = 256;

/// The 32-byte secret key. Its `Debug` never shows it.
#[derive(Clone, PartialEq, Eq)]
pub struct Key([u8; 32]);

impl fmt::Debug for Key {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str("Key(..)")
    }
}

impl Key {
    /// A key file's text: 64 hexadecimal digits, whitespace around them
    /// allowed. The error never quotes the text.
    pub fn parse(text: &str) -> Result<Self, String> {
        let hex = text.trim();
        let digits = hex.chars().count();
        if digits != 64 || !hex.bytes().all(|b| b.is_ascii_hexdigit()) {
            return Err(format!(
                "expected 64 hexadecimal digits (the 32-byte secret key) and nothing else, found {digits} characters{}",
                if digits == 64 {
                    " that are not all hexadecimal digits"
                } else {
                    ""
                }
            ));
        }
        let mut key = [0u8; 32];
        for (i, byte) in key.iter_mut().enumerate() {
            *byte = u8::from_str_radix(&hex[2 * i..2 * i + 2], 16).expect("hexadecimal digits");
        }
        if key == [0; 32] {
            return Err("expected a secret key, found all zeros".into());
        }
        Ok(Self(key))
    }
}

/// Why a frame was refused.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Refusal {
    /// Not signed (or MAVLink 1).
    Unsigned,
    /// Signed, but not with the key.
    BadSignature,
    /// Signed with the key, but its timestamp is not newer than the last
    /// of its stream (a replay), or a new stream's is over a minute old.
    Stale,
}

impl Refusal {
    fn why(self) -> &'static str {
        match self {
            Refusal::Unsigned => "not signed (signing is on; MAVLink 1 cannot be signed)",
            Refusal::BadSignature => "signature does not match the key",
            Refusal::Stale => {
                "timestamp not newer than the last of its stream (a replay), or a new stream over a minute old"
            }
        }
    }
}

/// This door's signing: the key, the crate's signing state (the
/// timestamps of the streams heard and of this door's own), and the
/// refusal logs.
pub struct Signing {
    key: Key,
    data: SigningData,
    link_id: u8,
    logs: Mutex<LogGate<String>>,
}

impl fmt::Debug for Signing {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.debug_struct("Signing")
            .field("link_id", &self.link_id)
            .finish_non_exhaustive()
    }
}

impl Signing {
    /// Signs what this door sends with link id `link_id`; accepts signed frames only.
    pub fn new(key: Key, link_id: u8) -> Self {
        let data = SigningData::from_config(SigningConfig::new(key.0, link_id, true, false));
        Self {
            key,
            data,
            link_id,
            logs: Mutex::new(LogGate::new(LOG_EVERY, LOG_PEERS)),
        }
    }

    /// What `mavlink::write_v2_msg_signed` signs with.
    pub fn data(&self) -> &SigningData {
        &self.data
    }

    /// Whether an intact `frame` (as `wire::scan` found it) may be read.
    pub fn check(&self, frame: &[u8]) -> Result<(), Refusal> {
        if frame[0] != V2_MAGIC || frame[2] & SIGNED == 0 {
            return Err(Refusal::Unsigned);
        }
        let raw = raw(frame);
        if self.data.verify_signature(&raw) {
            return Ok(());
        }
        // The crate says no without saying why: with the key's own
        // signature it was the timestamp.
        let mut signature = [0u8; 6];
        raw.calculate_signature(&self.key.0, &mut signature);
        if signature == raw.signature_value() {
            Err(Refusal::Stale)
        } else {
            Err(Refusal::BadSignature)
        }
    }

    /// Counts `refusal` of `frame` from `from`, and logs it unless this
    /// peer's address had a refusal logged within [`LOG_EVERY`] (at most
    /// the process's throttle of lines in all).
    pub fn refused(&self, refusal: Refusal, frame: &[u8], from: &dyn fmt::Display, stats: &Stats) {
        let total = Stats::count(match refusal {
            Refusal::Unsigned => &stats.unsigned,
            Refusal::BadSignature => &stats.bad_signature,
            Refusal::Stale => &stats.stale_signature,
        });
        let from = from.to_string();
        let address = peer_ip(&from).to_owned();
        let held = self
            .logs
            .lock()
            .unwrap_or_else(|p| p.into_inner())
            .allow(&address, Instant::now());
        let Some(held_back) = held else { return };
        if !may_warn("MAVLink message refused: signing", &"every peer") {
            return;
        }
        let (sender, message_id) = if frame[0] == V2_MAGIC {
            (
                (frame[5], frame[6]),
                u32::from_le_bytes([frame[7], frame[8], frame[9], 0]),
            )
        } else {
            ((frame[3], frame[4]), u32::from(frame[5]))
        };
        warn!(%from, sender = crate::routing::control::sender_name(sender), message_id, why = refusal.why(), total, held_back, "MAVLink message refused: signing is on");
    }

    /// Signs `frame`, a MAVLink 2 frame written by hand with the signed
    /// flag set before its CRC: the signature is appended.
    pub fn sign(&self, frame: &mut Vec<u8>) {
        debug_assert!(frame[0] == V2_MAGIC && frame[2] & SIGNED != 0);
        let mut raw = raw(frame);
        self.data.sign_message(&mut raw);
        frame.clear();
        frame.extend_from_slice(raw.raw_bytes());
    }
}

/// `frame` in the crate's fixed buffer.
fn raw(frame: &[u8]) -> MAVLinkV2MessageRaw {
    let mut bytes = [0u8; MAX_FRAME_SIZE];
    let n = frame.len().min(MAX_FRAME_SIZE);
    bytes[..n].copy_from_slice(&frame[..n]);
    MAVLinkV2MessageRaw::from_bytes_unparsed(bytes)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::transport::wire::{encode, header};
    use mavlink::Message;
    use mavlink::dialects::common::{COMMAND_LONG_DATA, HEARTBEAT_DATA, MavCmd, MavMessage};

    const KEY: &str = "00112233445566778899aabbccddeeff00112233445566778899AABBCCDDEEFF";
    const GCS: (u8, u8) = (255, 190);

    fn key(text: &str) -> Key {
        Key::parse(text).expect("a key")
    }

    fn signed(signing: &Signing, message: &MavMessage) -> Vec<u8> {
        let mut bytes = Vec::new();
        mavlink::write_v2_msg_signed(&mut bytes, header(GCS), message, Some(signing.data())).expect("encode");
        bytes
    }

    fn command() -> MavMessage {
        MavMessage::COMMAND_LONG(COMMAND_LONG_DATA {
            command: MavCmd::MAV_CMD_DO_GIMBAL_MANAGER_PITCHYAW,
            target_system: 1,
            target_component: 154,
            ..COMMAND_LONG_DATA::DEFAULT
        })
    }

    #[test]
    fn a_key_file_is_64_hex_digits_and_its_errors_never_quote_it() {
        assert_eq!(key(&format!("  {KEY}\n")), key(&KEY.to_lowercase()));
        let short = Key::parse("abcd").unwrap_err();
        assert!(
            short.contains("found 4 characters") && !short.contains("abcd"),
            "{short}"
        );
        let not_hex = Key::parse(&KEY.replace('0', "g")).unwrap_err();
        assert!(not_hex.contains("not all hexadecimal"), "{not_hex}");
        assert!(Key::parse(&"0".repeat(64)).unwrap_err().contains("all zeros"));
        assert_eq!(format!("{:?}", key(KEY)), "Key(..)", "never in a log");
    }

    #[test]
    fn only_frames_signed_with_the_key_and_newer_than_their_stream_are_read() {
        let door = Signing::new(key(KEY), 0);
        let gcs = Signing::new(key(KEY), 1);
        let first = signed(&gcs, &command());
        let second = signed(&gcs, &command());
        assert_eq!(door.check(&first), Ok(()));
        assert_eq!(door.check(&second), Ok(()));
        assert_eq!(door.check(&first), Err(Refusal::Stale), "a replay");
        assert_eq!(door.check(&second), Err(Refusal::Stale), "the same frame again");
        let thief = Signing::new(key(&KEY.replace('F', "E")), 1);
        assert_eq!(door.check(&signed(&thief, &command())), Err(Refusal::BadSignature));
        let heartbeat = encode(header(GCS), &MavMessage::HEARTBEAT(HEARTBEAT_DATA::default()));
        assert_eq!(door.check(&heartbeat), Err(Refusal::Unsigned), "a heartbeat too");
        assert_eq!(door.check(&encode(header(GCS), &command())), Err(Refusal::Unsigned));
        let mut v1 = Vec::new();
        mavlink::write_versioned_msg(&mut v1, mavlink::MavlinkVersion::V1, header(GCS), &command()).unwrap();
        assert_eq!(door.check(&v1), Err(Refusal::Unsigned));
        // One byte of a signed frame changed (its CRC mended): not the signature.
        let mut forged = signed(&gcs, &command());
        forged[10] ^= 1;
        let end = 10 + usize::from(forged[1]);
        let crc = mavlink::calculate_crc(&forged[1..end], MavMessage::extra_crc(76));
        forged[end..end + 2].copy_from_slice(&crc.to_le_bytes());
        assert_eq!(door.check(&forged), Err(Refusal::BadSignature));
    }

    #[test]
    fn a_frame_written_by_hand_is_signed_as_the_crate_signs() {
        let door = Signing::new(key(KEY), 3);
        let gcs = Signing::new(key(KEY), 0);
        let mut frame = signed(&door, &command());
        let (len, with_signature) = (frame.len() - 13, frame.len());
        frame.truncate(len);
        door.sign(&mut frame);
        assert_eq!(frame.len(), with_signature);
        assert_eq!(frame[len], 3, "the link id");
        assert_eq!(gcs.check(&frame), Ok(()));
    }
}
