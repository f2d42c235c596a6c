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
//!                                                        'L' PR name ['/' via] (a principal or link of priority PR,
//!                                                        and the tool or link it came through; 'Y' when it is
//!                                                        the asking connection's), 'T' name (a tour), 'K' (park)
//! ~T+name        start a tour                            result ~T S [holder]: S = 'R' running,
//! ~T-name        stop a tour                                     'W' waiting for the holder named, 'S' stopped
//! ~T?            list the tours                          result ~L name=S,name=S,...   (as many as fit)
//! ~B PPDD        its rules (bounds): limits and zones    result ~B PPDD = then items, each
//!                                                        'P' lo hi (pan limits), 'T' lo hi (tilt limits),
//!                                                        'Z' panlo panhi tiltlo tilthi (a keep-out zone)
//! ~W             end-of-window reports on this link      result ~W= ([`WINDOW_REPORTS_ON`]); NIC where
//!                                                        the GCU does not send them (1.4.2's NIC window)
//! ~U name        this connection's next commands act     ACK; a delivery report `16` (not permitted) from a
//! ~U             for user `name` (`~U` alone: for the    connection whose principal may not act for users
//!                door itself), ARCHITECTURE "Principals"
//! ~P PR name     (between GCUs) this link's next          ACK; the report 16 as for ~U
//!                commands are principal `name`'s, of
//!                priority PR as the sending GCU governs it
//! ```
//! `PP`, `DD` and `PR` are two upper-case hex digits; names are 1..=32
//! bytes of `A-Z a-z 0-9 _ -`. An unknown tour is answered NIC; `~C` of a
//! gimbal nobody holds answers `-`, and `~R` of it is acknowledged.
//!
//! In a `~B` result every angle is four upper-case hex digits, a signed
//! 16-bit number of hundredths of a degree in two's complement (as the
//! positions of Table 15): `~B0101=PDCD82328` is gimbal 1.1 with pan limits
//! -90.00..=90.00 (`DCD8`, `2328`) and no other rule. Each span has its low
//! end first (`lo <= hi`, both ends included). `P` and `T` come at most once
//! each, zones after them, as many as fit the 256-byte payload (13 with
//! both limits); a gimbal without rules answers `~B PPDD =` alone. The `=`
//! tells a result from the command.

use crate::hex::{hex_digit, hex_value};

/// First payload byte of a GCU command and of its result.
pub const GCU_MARK: u8 = b'~';
/// The result of `~W`: the GCU will report the end of each NIC window.
pub const WINDOW_REPORTS_ON: &[u8] = b"~W=";
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
    /// `~B PPDD`: the gimbal's rules (travel limits and keep-out zones).
    Rules(u8, u8),
    /// `~W`: after the ACK of each of this link's commands that ends with
    /// no answer (1.4.2: no NIC within the window, no result), send the
    /// delivery report `00` once the GCU's own window passed.
    WindowReports,
    /// `~U name`: the connection's next commands act for this user of the
    /// door (`None`, `~U` alone: for the door itself).
    ActFor(Option<&'a [u8]>),
    /// `~P PR name`: between GCUs, the link's next commands are those of
    /// principal `name`, of priority `PR` as the sending GCU governs it.
    Principal(u8, &'a [u8]),
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
            [GCU_MARK, b'B', rest @ ..] => address(rest).map(|(p, d)| GcuCommand::Rules(p, d)),
            [GCU_MARK, b'W'] => Some(GcuCommand::WindowReports),
            [GCU_MARK, b'U'] => Some(GcuCommand::ActFor(None)),
            [GCU_MARK, b'U', name @ ..] if valid_name(name) => Some(GcuCommand::ActFor(Some(name))),
            [GCU_MARK, b'P', h, l, name @ ..] if valid_name(name) => {
                Some(GcuCommand::Principal((hex_value(*h)? << 4) | hex_value(*l)?, name))
            }
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
            GcuCommand::WindowReports => w.put(b"W")?,
            GcuCommand::ActFor(name) => {
                w.put(b"U")?;
                if let Some(name) = name {
                    w.put(name)?;
                }
            }
            GcuCommand::Principal(priority, name) => {
                w.put(b"P")?;
                w.hex(priority)?;
                w.put(name)?;
            }
            GcuCommand::Rules(p, d) => {
                w.put(b"B")?;
                w.hex(p)?;
                w.hex(d)?;
            }
        }
        Some(w.len)
    }

    /// Whether a result frame follows the ACK (every command but `~R` and `~U`).
    pub fn has_result(&self) -> bool {
        !matches!(
            self,
            GcuCommand::Release(..) | GcuCommand::ActFor(_) | GcuCommand::Principal(..)
        )
    }
}

/// Who controls a gimbal, as `~C` answers it.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum ControllerReply<'a> {
    /// Nobody holds control.
    Nobody,
    /// A principal (or, on a link without principals, the configured
    /// link) of this priority and name.
    Link {
        /// Its priority, 0..=100.
        priority: u8,
        /// The principal's name, or the link's.
        name: &'a [u8],
        /// The tool or link the principal's commands came through (empty:
        /// a link without principals).
        via: &'a [u8],
        /// The link that asked holds it (`Y` in place of `L`): a client
        /// tells its own link's control from another's without knowing
        /// the name gcud gives its link.
        yours: bool,
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
            ControllerReply::Link {
                priority,
                name,
                via,
                yours,
            } => {
                w.put(if yours { b"Y" } else { b"L" })?;
                w.hex(priority)?;
                w.put(name)?;
                if !via.is_empty() {
                    w.put(b"/")?;
                    w.put(via)?;
                }
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
            [which @ (b'L' | b'Y'), h, l, named @ ..] => {
                let (name, via) = match named.iter().position(|&b| b == b'/') {
                    Some(at) => (&named[..at], &named[at + 1..]),
                    None => (named, &[][..]),
                };
                if !valid_name(name) || !(via.is_empty() || valid_name(via)) {
                    return None;
                }
                ControllerReply::Link {
                    priority: (hex_value(*h)? << 4) | hex_value(*l)?,
                    name,
                    via,
                    yours: *which == b'Y',
                }
            }
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

impl core::fmt::Display for TourState {
    /// [`TourState::name`].
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.write_str(self.name())
    }
}

impl TourState {
    /// The state in a word, as `gimbalctl` and the logs say it.
    pub const fn name(self) -> &'static str {
        match self {
            TourState::Running => "running",
            TourState::Waiting => "waiting",
            TourState::Stopped => "stopped",
        }
    }

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

/// One rule of a gimbal as `~B` answers it, angles in hundredths of a
/// degree, each span `[lo, hi]` with `lo <= hi`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum RuleItem {
    /// `P lo hi`: pan travel no command may leave.
    PanLimits([i16; 2]),
    /// `T lo hi`: tilt travel no command may leave.
    TiltLimits([i16; 2]),
    /// `Z panlo panhi tiltlo tilthi`: a rectangle no motion may enter.
    KeepOut {
        /// Its pan span.
        pan: [i16; 2],
        /// Its tilt span.
        tilt: [i16; 2],
    },
    /// `R nn`: a preset gcud's park or a tour recalls (two hex digits): a
    /// door stores no preset of its own there.
    Reserved(u8),
}

impl RuleItem {
    /// Its letter and angles.
    fn parts(&self) -> (u8, [i16; 4], usize) {
        match *self {
            RuleItem::PanLimits([lo, hi]) => (b'P', [lo, hi, 0, 0], 2),
            RuleItem::TiltLimits([lo, hi]) => (b'T', [lo, hi, 0, 0], 2),
            RuleItem::KeepOut { pan, tilt } => (b'Z', [pan[0], pan[1], tilt[0], tilt[1]], 4),
            RuleItem::Reserved(n) => (b'R', [i16::from(n), 0, 0, 0], 0),
        }
    }
}

/// Writes the `~B` result about gimbal `port`.`device`: as many items as
/// fit into `buf` (the first that does not fit ends it); 0 when not even
/// the header fits.
pub fn encode_rules(port: u8, device: u8, items: impl IntoIterator<Item = RuleItem>, buf: &mut [u8]) -> usize {
    let mut w = Put { buf, len: 0 };
    let header = w
        .put(b"~B")
        .and_then(|()| w.hex(port))
        .and_then(|()| w.hex(device))
        .and_then(|()| w.put(b"="));
    if header.is_none() {
        return 0;
    }
    for item in items {
        let before = w.len;
        let (letter, values, n) = item.parts();
        let mut fits = w.put(&[letter]);
        if let RuleItem::Reserved(preset) = item {
            fits = fits.and_then(|()| w.hex(preset));
        }
        for v in &values[..n] {
            let [h, l] = v.to_be_bytes();
            fits = fits.and_then(|()| w.hex(h)).and_then(|()| w.hex(l));
        }
        if fits.is_none() {
            w.len = before;
            break;
        }
    }
    w.len
}

/// The items of a `~B` result, every one checked when it was parsed.
#[derive(Clone, Debug)]
pub struct RuleItems<'a>(&'a [u8]);

impl Iterator for RuleItems<'_> {
    type Item = RuleItem;

    fn next(&mut self) -> Option<RuleItem> {
        let (item, rest) = rule_item(self.0)?;
        self.0 = rest;
        Some(item)
    }
}

/// Parses a `~B` result: the gimbal's port and device and its rules
/// (limits, zones, and the presets gcud reserves);
/// `None` for anything else, or a result with a malformed item, a span
/// whose low end is above its high end, or limits given twice.
pub fn parse_rules(payload: &[u8]) -> Option<(u8, u8, RuleItems<'_>)> {
    let [b'~', b'B', rest @ ..] = payload else { return None };
    let (p, d) = address(rest.get(..4)?)?;
    let [b'=', items @ ..] = rest.get(4..)? else {
        return None;
    };
    let (mut left, mut seen) = (items, [false; 2]);
    // Each item takes at least 3 bytes: the loop ends.
    while !left.is_empty() {
        let (item, rest) = rule_item(left)?;
        let once = match item {
            RuleItem::PanLimits(_) => Some(0),
            RuleItem::TiltLimits(_) => Some(1),
            RuleItem::KeepOut { .. } | RuleItem::Reserved(_) => None,
        };
        if let Some(i) = once {
            if seen[i] {
                return None;
            }
            seen[i] = true;
        }
        left = rest;
    }
    Some((p, d, RuleItems(items)))
}

/// One item at the start of `bytes` and what follows it.
fn rule_item(bytes: &[u8]) -> Option<(RuleItem, &[u8])> {
    let (letter, rest) = bytes.split_first()?;
    if *letter == b'R' {
        let [h, l, rest @ ..] = rest else { return None };
        let preset = (hex_value(*h)? << 4) | hex_value(*l)?;
        return Some((RuleItem::Reserved(preset), rest));
    }
    let n = match letter {
        b'P' | b'T' => 2,
        b'Z' => 4,
        _ => return None,
    };
    let mut v = [0i16; 4];
    for (i, slot) in v.iter_mut().take(n).enumerate() {
        let digits = rest.get(i * 4..i * 4 + 4)?;
        let mut word = 0u16;
        for &b in digits {
            word = (word << 4) | u16::from(hex_value(b)?);
        }
        *slot = i16::from_be_bytes(word.to_be_bytes());
    }
    let span = |lo: i16, hi: i16| (lo <= hi).then_some([lo, hi]);
    let item = match letter {
        b'P' => RuleItem::PanLimits(span(v[0], v[1])?),
        b'T' => RuleItem::TiltLimits(span(v[0], v[1])?),
        _ => RuleItem::KeepOut {
            pan: span(v[0], v[1])?,
            tilt: span(v[2], v[3])?,
        },
    };
    Some((item, rest.get(n * 4..)?))
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
mod tests;
