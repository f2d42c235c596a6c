//! What [`crate::Router::handle`] asks of its caller: the actions in the
//! order they must be executed, and the bytes of every write in one buffer
//! that the caller owns and reuses (no allocation per frame once it has
//! grown). A write action names its bytes by span ([`Outbox::bytes`]);
//! consecutive writes to the same port or link merge into one, so a frame
//! and the ACK after it leave in one write.

use std::ops::{Deref, Range};

use sagebrush_protocol::{ACK, FrameBuf, NAK, NIC};

use crate::boundary::Action;
use crate::types::LineId;

/// The actions of one or more [`crate::Router::handle`] calls; executed,
/// then [`Outbox::clear`]ed (capacity kept).
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct Outbox {
    actions: Vec<Action>,
    bytes: Vec<u8>,
}

impl Outbox {
    pub fn new() -> Self {
        Self::default()
    }

    /// The actions, in order.
    pub fn actions(&self) -> &[Action] {
        &self.actions
    }

    /// The bytes of an [`Action::Write`] span.
    pub fn bytes(&self, span: &Range<usize>) -> &[u8] {
        self.bytes.get(span.clone()).unwrap_or_default()
    }

    /// Forgets the actions and bytes, keeping the memory for the next call.
    pub fn clear(&mut self) {
        self.actions.clear();
        self.bytes.clear();
    }

    pub(crate) fn push(&mut self, action: Action) {
        self.actions.push(action);
    }

    /// Appends a write to `line`, merged into the previous action when
    /// that wrote to the same line just before.
    pub(crate) fn write(&mut self, line: LineId, wire: &Wire) {
        let start = self.bytes.len();
        self.bytes.extend_from_slice(wire.as_bytes());
        let end = self.bytes.len();
        match self.actions.last_mut() {
            Some(Action::Write { line: last, bytes }) if *last == line && bytes.end == start => bytes.end = end,
            _ => self.actions.push(Action::Write {
                line,
                bytes: start..end,
            }),
        }
    }
}

impl Deref for Outbox {
    type Target = [Action];

    fn deref(&self) -> &[Action] {
        &self.actions
    }
}

/// One write a port or link asks for: a bare byte of 1.4.2 or a frame,
/// held without an allocation of its own.
#[expect(
    clippy::large_enum_variant,
    reason = "a frame to write is held inline, without an allocation of its own, on its short way to the Outbox"
)]
#[derive(Clone, Debug, PartialEq, Eq)]
pub(crate) enum Wire {
    Ack,
    Nak,
    Nic,
    Frame(FrameBuf),
}

impl Wire {
    pub fn as_bytes(&self) -> &[u8] {
        match self {
            Wire::Ack => &[ACK],
            Wire::Nak => &[NAK],
            Wire::Nic => &[NIC],
            Wire::Frame(frame) => frame.as_bytes(),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::types::LinkId;
    use sagebrush_protocol::Address;

    #[test]
    fn consecutive_writes_to_one_line_merge_and_order_is_kept() {
        let frame = FrameBuf::new(Address::new(5, 1, 3), 0, b"P?").unwrap();
        let mut out = Outbox::new();
        out.write(LineId::Port(1), &Wire::Ack);
        out.write(LineId::Port(1), &Wire::Frame(frame.clone()));
        out.push(Action::SetPortRate { port: 1, bps: 19_200 });
        out.write(LineId::Port(1), &Wire::Nak);
        out.write(LineId::Link(LinkId(7)), &Wire::Nic);
        out.write(LineId::Port(2), &Wire::Ack);
        let mut first = vec![ACK];
        first.extend_from_slice(frame.as_bytes());
        let writes: Vec<(String, Vec<u8>)> = out
            .actions()
            .iter()
            .map(|a| match a {
                Action::Write { line, bytes } => (format!("{line}"), out.bytes(bytes).to_vec()),
                other => (format!("{other:?}"), Vec::new()),
            })
            .collect();
        assert_eq!(writes[0], ("port 1".to_owned(), first), "ACK and frame in one write");
        assert_eq!(
            writes[1].0, "SetPortRate { port: 1, bps: 19200 }",
            "the rate switch after them"
        );
        assert_eq!(
            writes[2],
            ("port 1".to_owned(), vec![NAK]),
            "not merged across the switch"
        );
        assert_eq!(writes[4], ("port 2".to_owned(), vec![ACK]));
        assert_eq!(writes.len(), 5);
        out.clear();
        assert!(out.is_empty());
    }
}
