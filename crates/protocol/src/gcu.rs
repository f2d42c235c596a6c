//! Commands to the GCU itself about the gimbals it governs: a project
//! extension of port 0 (Table 2: port 0 is the control unit itself, which
//! answers at least `AW` and `D?`), written down in the project's
//! `ARCHITECTURE.md`, "Governance". They never reach a bus, and their first
//! byte, `~`, starts no command of Tables 4, 11 and 16 (a GCU that does not
//! know them answers NIC, as the spec asks).
//!
//! ```text
//! ~R PPDD        release control of local gimbal PP.DD   ACK, or a delivery report (not in control)
//! ~C PPDD        who controls it                         result ~C PPDD then '-' (nobody),
//!                                                        'L' PR name (a link of priority PR), 'T' name (a tour), 'K' (park)
//! ~T+name        start a tour                            result ~T S [holder]: S = 'R' running,
//! ~T-name        stop a tour                                     'W' waiting for the holder named, 'S' stopped
//! ~T?            list the tours                          result ~L name=S,name=S,...   (as many as fit)
//! ```
//! `PP`, `DD` and `PR` are two upper-case hex digits; names are 1..=32
//! bytes of `A-Z a-z 0-9 _ -`. An unknown tour is answered NIC; `~C` of a
//! gimbal nobody holds answers `-`, and `~R` of it is acknowledged.

use crate::hex::{hex_digit, hex_value};

/// First payload byte of a GCU command and of its result.
pub const GCU_MARK: u8 = b'~';
/// Longest tour or link name a GCU command carries.
pub const NAME_MAX: usize = 32;

/// Whether `name` may name a tour or link in a GCU command.
pub fn valid_name(name: &[u8]) -> bool {
    (1..=NAME_MAX).contains(&name.len())
        && name
            .iter()
            .all(|b| b.is_ascii_alphanumeric() || *b == b'_' || *b == b'-')
}

/// A command to the GCU itself (module documentation).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum GcuCommand<'a> {
    /// `~R PPDD`: release control of the gimbal on port `.0`, device `.1`.
    Release(u8, u8),
    /// `~C PPDD`: who controls the gimbal.
    Controller(u8, u8),
    /// `~T+name`: start a tour.
    TourStart(&'a [u8]),
    /// `~T-name`: stop a tour.
    TourStop(&'a [u8]),
    /// `~T?`: list the tours.
    TourList,
}

impl<'a> GcuCommand<'a> {
    /// Whether a payload is a GCU command (its first byte), without parsing it.
    pub fn is_gcu(payload: &[u8]) -> bool {
        payload.first() == Some(&GCU_MARK)
    }

    /// Parses a payload; `None` when it is no GCU command of this table.
    pub fn parse(payload: &'a [u8]) -> Option<Self> {
        match payload {
            [GCU_MARK, b'R', rest @ ..] => address(rest).map(|(p, d)| GcuCommand::Release(p, d)),
            [GCU_MARK, b'C', rest @ ..] => address(rest).map(|(p, d)| GcuCommand::Controller(p, d)),
            [GCU_MARK, b'T', b'+', name @ ..] if valid_name(name) => Some(GcuCommand::TourStart(name)),
            [GCU_MARK, b'T', b'-', name @ ..] if valid_name(name) => Some(GcuCommand::TourStop(name)),
            [GCU_MARK, b'T', b'?'] => Some(GcuCommand::TourList),
            _ => None,
        }
    }

    /// Writes the payload into `buf`; its length, or `None` when it does not fit.
    pub fn encode(&self, buf: &mut [u8]) -> Option<usize> {
        let mut w = Put { buf, len: 0 };
        w.put(&[GCU_MARK])?;
        match *self {
            GcuCommand::Release(p, d) => {
                w.put(b"R")?;
                w.hex(p)?;
                w.hex(d)?;
            }
            GcuCommand::Controller(p, d) => {
                w.put(b"C")?;
                w.hex(p)?;
                w.hex(d)?;
            }
            GcuCommand::TourStart(name) => {
                w.put(b"T+")?;
                w.put(name)?;
            }
            GcuCommand::TourStop(name) => {
                w.put(b"T-")?;
                w.put(name)?;
            }
            GcuCommand::TourList => w.put(b"T?")?,
        }
        Some(w.len)
    }

    /// Whether a result frame follows the ACK (every command but `~R`).
    pub fn has_result(&self) -> bool {
        !matches!(self, GcuCommand::Release(..))
    }
}

/// Who controls a gimbal, as `~C` answers it.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum ControllerReply<'a> {
    /// Nobody holds control.
    Nobody,
    /// A configured link of this priority and name.
    Link {
        /// The link's priority, 0..=100.
        priority: u8,
        /// The link's configured name.
        name: &'a [u8],
    },
    /// The named tour (gcud's own, lowest priority).
    Tour(&'a [u8]),
    /// Park (gcud's own, lowest priority).
    Park,
}

impl<'a> ControllerReply<'a> {
    /// Writes `~C PPDD ...` for the gimbal `port`.`device` into `buf`.
    pub fn encode(&self, port: u8, device: u8, buf: &mut [u8]) -> Option<usize> {
        let mut w = Put { buf, len: 0 };
        w.put(b"~C")?;
        w.hex(port)?;
        w.hex(device)?;
        match *self {
            ControllerReply::Nobody => w.put(b"-")?,
            ControllerReply::Link { priority, name } => {
                w.put(b"L")?;
                w.hex(priority)?;
                w.put(name)?;
            }
            ControllerReply::Tour(name) => {
                w.put(b"T")?;
                w.put(name)?;
            }
            ControllerReply::Park => w.put(b"K")?,
        }
        Some(w.len)
    }

    /// Parses a `~C` result: the gimbal's port and device, and who controls it.
    pub fn parse(payload: &'a [u8]) -> Option<(u8, u8, Self)> {
        let [b'~', b'C', rest @ ..] = payload else { return None };
        let (p, d) = address(rest.get(..4)?)?;
        let reply = match rest.get(4..)? {
            [b'-'] => ControllerReply::Nobody,
            [b'L', h, l, name @ ..] if valid_name(name) => ControllerReply::Link {
                priority: (hex_value(*h)? << 4) | hex_value(*l)?,
                name,
            },
            [b'T', name @ ..] if valid_name(name) => ControllerReply::Tour(name),
            [b'K'] => ControllerReply::Park,
            _ => return None,
        };
        Some((p, d, reply))
    }
}

/// A tour's state, as `~T` and `~L` answer it.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum TourState {
    /// Running its steps (`R`).
    Running,
    /// Started, waiting for control to lapse (`W`).
    Waiting,
    /// Not running (`S`).
    Stopped,
}

impl TourState {
    /// The state's letter.
    pub const fn letter(self) -> u8 {
        match self {
            TourState::Running => b'R',
            TourState::Waiting => b'W',
            TourState::Stopped => b'S',
        }
    }

    /// The state of a letter.
    pub const fn from_letter(letter: u8) -> Option<Self> {
        match letter {
            b'R' => Some(TourState::Running),
            b'W' => Some(TourState::Waiting),
            b'S' => Some(TourState::Stopped),
            _ => None,
        }
    }
}

/// Writes the `~T` result: the tour's state, and the holder it waits for.
pub fn encode_tour_reply(state: TourState, holder: &[u8], buf: &mut [u8]) -> Option<usize> {
    let mut w = Put { buf, len: 0 };
    w.put(b"~T")?;
    w.put(&[state.letter()])?;
    w.put(holder)?;
    Some(w.len)
}

/// Parses a `~T` result: the state and the holder it waits for (maybe empty).
pub fn parse_tour_reply(payload: &[u8]) -> Option<(TourState, &[u8])> {
    let [b'~', b'T', s, holder @ ..] = payload else {
        return None;
    };
    Some((TourState::from_letter(*s)?, holder))
}

/// Writes the `~L` result: as many `name=S` entries as fit into `buf`.
pub fn encode_tour_list<'n>(tours: impl IntoIterator<Item = (&'n [u8], TourState)>, buf: &mut [u8]) -> usize {
    let mut w = Put { buf, len: 0 };
    if w.put(b"~L").is_none() {
        return 0;
    }
    for (i, (name, state)) in tours.into_iter().enumerate() {
        let before = w.len;
        let sep: &[u8] = if i == 0 { b"" } else { b"," };
        let fits = w
            .put(sep)
            .and_then(|()| w.put(name))
            .and_then(|()| w.put(&[b'=', state.letter()]));
        if fits.is_none() {
            w.len = before;
            break;
        }
    }
    w.len
}

/// The entries of a `~L` result, `None` for what is no `~L` result.
pub fn parse_tour_list(payload: &[u8]) -> Option<impl Iterator<Item = Option<(&[u8], TourState)>>> {
    let [b'~', b'L', rest @ ..] = payload else { return None };
    Some(
        rest.split(|b| *b == b',')
            .filter(|e| !e.is_empty())
            .map(|entry| match entry {
                [name @ .., b'=', s] if valid_name(name) => Some((name, TourState::from_letter(*s)?)),
                _ => None,
            }),
    )
}

fn address(rest: &[u8]) -> Option<(u8, u8)> {
    let [p1, p2, d1, d2] = rest else { return None };
    let byte = |h: u8, l: u8| Some((hex_value(h)? << 4) | hex_value(l)?);
    Some((byte(*p1, *p2)?, byte(*d1, *d2)?))
}

struct Put<'b> {
    buf: &'b mut [u8],
    len: usize,
}

impl Put<'_> {
    fn put(&mut self, bytes: &[u8]) -> Option<()> {
        let end = self.len.checked_add(bytes.len())?;
        self.buf.get_mut(self.len..end)?.copy_from_slice(bytes);
        self.len = end;
        Some(())
    }

    fn hex(&mut self, byte: u8) -> Option<()> {
        self.put(&[hex_digit(byte >> 4), hex_digit(byte & 0x0F)])
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn encoded(c: GcuCommand<'_>) -> ([u8; 64], usize) {
        let mut buf = [0u8; 64];
        let n = c.encode(&mut buf).unwrap();
        (buf, n)
    }

    #[test]
    fn commands_round_trip() {
        for c in [
            GcuCommand::Release(1, 0x0A),
            GcuCommand::Controller(0xFE, 1),
            GcuCommand::TourStart(b"perimeter"),
            GcuCommand::TourStop(b"north-2"),
            GcuCommand::TourList,
        ] {
            let (buf, n) = encoded(c);
            assert_eq!(GcuCommand::parse(&buf[..n]), Some(c));
        }
        assert_eq!(&encoded(GcuCommand::Release(1, 0x0A)).0[..6], b"~R010A");
    }

    #[test]
    fn refuses_what_is_not_a_gcu_command() {
        for bad in [&b"~R01"[..], b"~R01GG", b"~T+", b"~T+a b", b"~X", b"PL", b"~T?x"] {
            assert_eq!(GcuCommand::parse(bad), None, "{bad:?}");
        }
        let long = [b'a'; NAME_MAX + 1];
        let mut p = [0u8; 40];
        p[..3].copy_from_slice(b"~T+");
        p[3..3 + long.len()].copy_from_slice(&long);
        assert_eq!(GcuCommand::parse(&p[..3 + long.len()]), None);
    }

    #[test]
    fn replies_round_trip() {
        let mut buf = [0u8; 64];
        for r in [
            ControllerReply::Nobody,
            ControllerReply::Link {
                priority: 80,
                name: b"operators",
            },
            ControllerReply::Tour(b"perimeter"),
            ControllerReply::Park,
        ] {
            let n = r.encode(1, 2, &mut buf).unwrap();
            assert_eq!(ControllerReply::parse(&buf[..n]), Some((1, 2, r)));
        }
        let n = encode_tour_reply(TourState::Waiting, b"operators", &mut buf).unwrap();
        assert_eq!(
            parse_tour_reply(&buf[..n]),
            Some((TourState::Waiting, &b"operators"[..]))
        );
        let tours = [(&b"a"[..], TourState::Running), (&b"bb"[..], TourState::Stopped)];
        let n = encode_tour_list(tours, &mut buf);
        assert_eq!(&buf[..n], b"~La=R,bb=S");
        let mut parsed = parse_tour_list(&buf[..n]).unwrap();
        assert_eq!(parsed.next(), Some(Some(tours[0])));
        assert_eq!(parsed.next(), Some(Some(tours[1])));
        assert_eq!(parsed.next(), None);
        drop(parsed);
        // What does not fit is left off whole.
        let n = encode_tour_list(tours, &mut buf[..8]);
        assert_eq!(&buf[..n], b"~La=R");
    }
}
