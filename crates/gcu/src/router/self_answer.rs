//! The GCU itself as a destination (ARCHITECTURE "Routing semantics": port 0 is
//! addressed to the GCU itself, which answers at least `AW` and `D?`, NIC
//! otherwise). `AW` answers status 0 (Table 5: all well); `D?` answers
//! Table 6 with the group as ID, revision `19` and the configured name and
//! serial. The answer's header follows Table 3: destination group = the
//! command's source, port 0, device as addressed (a wildcard replaced by 0,
//! the control unit, so the answer names who answered), source = our group.

use sagebrush_protocol::{Address, AwakeStatus, CONTROL_UNIT, Frame, FrameBuf, Identity, Reply, Row, WILDCARD};

/// The GCU's own answer to `frame`, a command of table row `row` (read
/// when it was accepted): its result, or `None` for a NIC.
pub(crate) fn answer(group: u8, name: &str, serial: &str, frame: &Frame<'_>, row: Row) -> Option<FrameBuf> {
    let reply = match row {
        Row::AwakeStatus => AwakeStatus::new(0).map(Reply::AwakeStatus).ok(),
        Row::Identify => Identity::new(group, *b"19", name.trim_end().as_bytes(), serial.trim_end().as_bytes())
            .map(Reply::Identity)
            .ok(),
        _ => None,
    };
    let reply = reply?;
    let device = if frame.dest.device == WILDCARD {
        CONTROL_UNIT
    } else {
        frame.dest.device
    };
    let dest = Address::new(frame.source, frame.dest.port, device);
    FrameBuf::build(dest, group, |buf| reply.encode(buf).map(<[u8]>::len)).ok()
}

#[cfg(test)]
mod tests {
    use super::*;
    use sagebrush_protocol::Command;

    #[test]
    fn answers_aw_and_id_nic_otherwise() {
        let aw = Frame::new(Address::new(5, 0, 255), 2, b"AW").unwrap();
        let Some(r) = answer(5, "gcu five", "SN1", &aw, Row::AwakeStatus) else {
            panic!("AW must be answered")
        };
        assert_eq!(r.frame().dest, Address::new(2, 0, 0));
        assert_eq!(r.frame().source, 5);
        assert_eq!(
            Reply::parse(&Command::AwakeStatus, r.frame().payload()),
            Ok(Reply::AwakeStatus(AwakeStatus::new(0).unwrap()))
        );
        let id = Frame::new(Address::new(5, 0, 0), 2, b"D?").unwrap();
        let Some(r) = answer(5, "gcu five", "SN1", &id, Row::Identify) else {
            panic!("D? must be answered")
        };
        let Ok(Reply::Identity(ident)) = Reply::parse(&Command::Identify, r.frame().payload()) else {
            panic!("not an identity")
        };
        assert_eq!(
            (ident.id, ident.name(), ident.serial()),
            (5, &b"gcu five"[..], &b"SN1"[..])
        );
        let other = Frame::new(Address::new(5, 0, 0), 2, b"PL").unwrap();
        assert_eq!(answer(5, "x", "y", &other, Row::PanLeft), None);
    }
}
