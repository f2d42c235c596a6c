//! The reverse path of forwarded frames (ARCHITECTURE "Routing semantics":
//! results go back along the reverse path to the link the command came
//! from). When this GCU forwards a frame to another GCU (by route or by a
//! group-255 flood), it remembers where the frame came from, so that the
//! answer arriving on the next-hop link goes back to exactly that origin,
//! even when several clients speak as the same source group.
//!
//! Matching a result frame (Table 3: groups exchanged, port and device
//! unchanged) arriving on link `L`: an entry forwarded on `L`, already
//! transmitted, whose command source group is the frame's destination
//! group, whose port/device equal the frame's (or are 255), and whose
//! destination group is the frame's source group (or 255).
//!
//! When the matching entries do not all share one origin (clients using the
//! same source group for the same device), the answer is dropped and
//! counted ([`DropReason::AmbiguousAnswer`]) rather than risk the wrong
//! link. A bare `?` carries no address: it matches every transmitted entry
//! on `L`, and goes back only when they all share one origin.
//!
//! A result must also be one its command can have (it parses as that
//! command's reply): a `D?` answer is never taken for a pending `P?`.
//!
//! Answered entries are kept until they expire, because the protocol has no
//! sequence numbers and an answer may come twice:
//! - our ACK of the answer was lost on a lossy link and the next GCU sends
//!   the same frame again: a byte-identical frame within that GCU's retry budget (assumed
//!   to be ours: retries + 1 ACK time-outs) is that repeat
//!   ([`AnswerMatch::Repeat`]): ACKed, and not relayed again (ARCHITECTURE
//!   "Links between GCUs": ACK/NAK are hop by hop, so the origin's link
//!   already carries the first copy, with its own retransmission; a second
//!   copy there would be taken for the origin's next command's answer);
//! - our ACK time-out made us retransmit the command and the next GCU ran
//!   it twice: the second answer may differ, so such an entry makes a
//!   waiting entry of another origin ambiguous until it expires; a second
//!   `?` or result (a command has one NIC, 1.4.2, and one result, 1.4.3)
//!   that only answered entries match, none of them a fan-out, is that
//!   second run's ([`AnswerMatch::Spent`]), and goes nowhere.
//!
//! Otherwise entries still waiting for their answer are matched first, so
//! that an answered one does not block the next command of another client
//! (a new `gimbalctl` run, say). When the table is full, a settled entry
//! (answered or closed, and reported) is forgotten first, silently; only
//! forgetting one that was still owed something counts as a drop.
//!
//! Delivery reports (ARCHITECTURE "Delivery contract") of the next GCU
//! come back the same way: a report names the command's destination and
//! checksum, and settles the delivery of the oldest unreported entry it
//! fits. An entry that expires unreported leaves its command not confirmed.
//!
//! Reports also put answers in order, so that the commands of a client that
//! left never shadow the next client's: the next GCU reports a command when
//! its device acknowledged it, before its result (1.4.3: "The result
//! response is sent following the ACK"), and runs one transaction at a time
//! per port, each origin's jobs in order, a stop overtaking only queued
//! work. So on one link, for one source group and one port:
//! - a result answers the oldest entry reported delivered and not yet
//!   answered (its transaction is the one running there);
//! - the delivered report of a later command that is not a stop closes the
//!   earlier reported entries: their transactions ended, no answer of
//!   theirs can come any more;
//! - an entry reported undelivered waits for nothing.
//!
//! Only when no reported entry fits (a report lost on a lossy link) are the
//! unreported waiting entries considered, and then only when they all share
//! one origin.
//!
//! Entries outlive a link going down, either way: the next GCU keeps
//! executing and answers on the link once it is back (same id), and answers
//! for an origin that left are recognised and counted
//! ([`crate::DropReason::OriginGone`]) instead of being routed on.
//!
//! [`DropReason::AmbiguousAnswer`]: crate::DropReason::AmbiguousAnswer

use std::collections::VecDeque;

use sagebrush_protocol::{Address, DeliveryReport, Frame, FrameBuf, Reply, ResultKind, ResultTimeout, WILDCARD};

use crate::command::CommandFacts;
use crate::config::LinkSettings;
use crate::types::{CommandId, LinkId, Origin};

#[derive(Clone, Debug)]
struct Pending {
    key: u64,
    out_link: LinkId,
    origin: Origin,
    /// Source group of the forwarded frame.
    source: u8,
    dest: Address,
    /// The forwarded command's facts, read when it was accepted (an answer
    /// must fit it).
    facts: CommandFacts,
    /// The forwarded frame's checksum (the next GCU's report names it).
    checksum: u8,
    /// Set at the first transmission on `out_link`.
    expires: Option<u64>,
    /// An answer went back already.
    answered: bool,
    /// Transmitted more than once: the next GCU may answer twice.
    resent: bool,
    /// The last answer that went back, and when.
    last_answer: Option<(u64, FrameBuf)>,
    /// The command whose delivery the next GCU's report settles (a link's
    /// command; not a flood copy or the GCU's own stop).
    command: Option<CommandId>,
    /// The next GCU's delivery report: `Some(true)` delivered.
    reported: Option<bool>,
    /// The next GCU reported a later command on the same port: this
    /// entry's transaction ended there and no answer of it can come.
    closed: bool,
    /// Its origin was told it was not delivered (our own delivery time-out:
    /// `0B not confirmed`), or left: its `?` goes nowhere.
    disowned: bool,
}

impl Pending {
    /// Whether this entry still waits for answers: a fan-out (a wildcard
    /// group, port or device) waits for several until it expires.
    fn waiting(&self) -> bool {
        !self.closed && self.reported != Some(false) && (!self.answered || self.dest.has_wildcard())
    }

    /// Its delivery is reported (or nobody awaits it).
    fn told(&self) -> bool {
        self.reported.is_some() || self.command.is_none()
    }

    /// Nothing more can come for it that anybody awaits: forgetting it
    /// loses nothing (kept only to recognise a repeated answer).
    fn settled(&self) -> bool {
        self.told() && !self.waiting()
    }

    /// Work left: a client awaits its report, or a required result is
    /// still to come. (A `?` that may follow a command without result, or
    /// more answers of a fan-out, are not worth waiting for.)
    fn owed(&self) -> bool {
        !self.told()
            || matches!(self.facts.reply.result_kind(), ResultKind::Required(_)) && !self.answered && self.waiting()
    }

    fn answered_by(&self, frame: &Frame<'_>) -> bool {
        let level = |want: u8, got: u8| want == WILDCARD || want == got;
        self.facts.reply.result_kind() != ResultKind::None
            && frame.dest.group == self.source
            && level(self.dest.port, frame.dest.port)
            && level(self.dest.device, frame.dest.device)
            && level(self.dest.group, frame.source)
            && Reply::parse_expected(&self.facts.reply, frame.payload()).is_ok()
    }
}

/// Where an answer (result or `?`) from a link goes back to.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum AnswerMatch {
    None,
    One(Origin),
    Ambiguous,
    /// The next GCU sent an answer again (our ACK of it was lost): it
    /// went back already, and goes nowhere now.
    Repeat,
    /// A second answer of a command answered already: a command has one
    /// NIC (1.4.2) and one result (1.4.3), so it is the next GCU's second
    /// run of a command it took twice (our copy sent again, the ACK of the
    /// first lost). Its origin has its answer and would take this one for
    /// its next command to the device: it goes nowhere (counted).
    Spent,
    /// A `?` or result of a command whose origin was told it was not
    /// delivered, or left ([`ReversePath::disown`]): a `?` names no command
    /// and a result only its Table 3 header (1.4.3), so the origin would
    /// take it for the one it awaits now. It goes nowhere (counted).
    Disowned,
}

#[derive(Debug)]
pub(crate) struct ReversePath {
    entries: VecDeque<Pending>,
    next_key: u64,
    max: usize,
    /// How long after an answer the next GCU may send it again.
    repeat_window: u64,
}

impl ReversePath {
    /// A table of at most `max` entries; `repeat_window` is how long after
    /// an answer the next GCU may still send it again (its whole retry
    /// budget on the link: retries + 1 ACK time-outs).
    pub fn new(max: usize, repeat_window: u64) -> Self {
        Self {
            entries: VecDeque::new(),
            next_key: 0,
            max: max.max(1),
            repeat_window,
        }
    }

    /// Remembers a forwarded frame; returns its key and whether the oldest
    /// entry had to be forgotten to make room.
    /// `command`: the command whose delivery this forward decides, if any.
    /// Returns the key, and the unreported command of an entry forgotten
    /// to make room (`Some(None)`: an entry without one).
    pub fn insert(
        &mut self,
        out_link: LinkId,
        origin: Origin,
        frame: &Frame<'_>,
        facts: CommandFacts,
        command: Option<CommandId>,
    ) -> (u64, Option<Option<CommandId>>) {
        let mut evicted = None;
        if self.entries.len() >= self.max {
            let at = (self.entries.iter().position(Pending::settled))
                .or_else(|| self.entries.iter().position(|e| e.answered))
                .unwrap_or(0);
            evicted = self
                .entries
                .remove(at)
                .filter(|e| !e.settled())
                .map(|e| e.command.filter(|_| e.reported.is_none()));
        }
        let key = self.next_key;
        self.next_key += 1;
        self.entries.push_back(Pending {
            key,
            out_link,
            origin,
            source: frame.source,
            dest: frame.dest,
            facts,
            checksum: frame.checksum(),
            expires: None,
            answered: false,
            resent: false,
            last_answer: None,
            command,
            reported: None,
            closed: false,
            disowned: false,
        });
        (key, evicted)
    }

    /// The command whose delivery entry `key` decides, and whether its
    /// frame was transmitted (the next GCU may have it).
    pub fn command_of(&self, key: u64) -> Option<(CommandId, bool)> {
        self.entries
            .iter()
            .find(|e| e.key == key && e.reported.is_none())
            .and_then(|e| e.command.map(|c| (c, e.expires.is_some())))
    }

    /// A delivery report arrived on `link` in a frame for group `to`: the
    /// key of the entry it settles (the next GCU has that frame:
    /// `Link::reported`) and its command (`None`: an entry with no command
    /// to settle, e.g. a flood copy); `None` when nothing fits.
    pub fn match_report(&mut self, link: LinkId, to: u8, report: &DeliveryReport) -> Option<(u64, Option<CommandId>)> {
        let fits = |e: &Pending| {
            e.out_link == link
                && e.expires.is_some()
                && e.source == to
                && e.dest == report.dest
                && e.checksum == report.command_checksum
        };
        let Some(at) = self.entries.iter().position(|e| fits(e) && e.reported.is_none()) else {
            // A second report of a command we sent twice: the next GCU took
            // our retransmission (its ACK lost) for a new command and ran it
            // again, after the first run. The first run's window is over,
            // and a `?` from now on is the second run's, which nobody awaits
            // (`take`: a `?` only waiting entries take).
            if report.failure.is_none() {
                for e in self
                    .entries
                    .iter_mut()
                    .filter(|e| fits(e) && e.resent && e.reported == Some(true))
                {
                    e.answered = true;
                }
            }
            return None;
        };
        let delivered = report.failure.is_none();
        let entry = &mut self.entries[at];
        entry.reported = Some(delivered);
        // A stop overtakes queued work at the next GCU: its report says
        // nothing about the transactions before it.
        let (command, stop, dest, key) = (entry.command, entry.facts.stop, entry.dest, entry.key);
        if delivered && !stop && dest.port != WILDCARD {
            for e in self.entries.iter_mut().take(at) {
                if e.out_link == link && e.source == to && e.dest.port == dest.port && e.reported == Some(true) {
                    debug_assert!(e.key < key);
                    e.closed = true;
                }
            }
        }
        Some((key, command))
    }

    /// The origin of `command` was told it was not delivered: a `?` of its
    /// entry is matched still (it is that command's, not a later one's)
    /// but goes nowhere ([`AnswerMatch::Disowned`]).
    pub fn disown(&mut self, command: CommandId) {
        for e in self.entries.iter_mut().filter(|e| e.command == Some(command)) {
            e.disowned = true;
        }
    }

    /// The origin link `link` went down: the same for all its entries (a
    /// configured link comes back under the same id).
    pub fn disown_origin(&mut self, link: LinkId) {
        for e in self.entries.iter_mut().filter(|e| e.origin.link() == Some(link)) {
            e.disowned = true;
        }
    }

    /// The frame of `key` was transmitted for the first time at `now`.
    pub fn sent(&mut self, key: u64, now: u64, settings: &LinkSettings) {
        if let Some(e) = self.entries.iter_mut().find(|e| e.key == key) {
            let wait = match e.facts.reply.result_kind() {
                ResultKind::None => settings.nic_answer_timeout,
                ResultKind::Required(ResultTimeout::Long) => settings.long_answer_timeout,
                ResultKind::Required(ResultTimeout::Normal) | ResultKind::Optional => settings.answer_timeout,
            };
            e.expires = Some(now.saturating_add(wait));
        }
    }

    /// The frame of `key` was transmitted again (NAK or ACK time-out).
    pub fn resent(&mut self, key: u64) {
        if let Some(e) = self.entries.iter_mut().find(|e| e.key == key) {
            e.resent = true;
        }
    }

    /// The frame of `key` was dropped or given up. Once transmitted, the
    /// next GCU may have executed it even though no ACK came back (ACKs get
    /// lost too), so a transmitted entry stays until it expires.
    pub fn cancel(&mut self, key: u64) {
        self.entries.retain(|e| e.key != key || e.expires.is_some());
    }

    /// Where a frame arriving on `link` goes back to, if it answers a forwarded one.
    /// `repeats`: whether the link may repeat an answer (it can lose our ACK).
    pub fn match_result(&mut self, now: u64, link: LinkId, frame: &Frame<'_>, repeats: bool) -> AnswerMatch {
        let answer = FrameBuf::from_frame(frame);
        // On a lossless link nothing is ever repeated: identical bytes are a
        // new answer, even within the same tick (two answers of a resting
        // gimbal's position are byte for byte the same).
        let window = self.repeat_window;
        let repeated = |e: &Pending| {
            repeats
                && e.last_answer
                    .as_ref()
                    .is_some_and(|(at, last)| *last == answer && now <= at.saturating_add(window))
        };
        let matches = |e: &Pending| e.out_link == link && e.expires.is_some() && e.answered_by(frame);
        // A repeat of an answer that went back already: the hop-by-hop
        // repeat of one frame, not a new answer of any entry.
        if self.entries.iter().any(|e| matches(e) && repeated(e)) {
            return AnswerMatch::Repeat;
        }
        // The transaction running at the next GCU: the oldest entry it
        // reported delivered and has not answered. Only a fan-out of another
        // origin waiting for the same answers makes it ambiguous.
        let running = |e: &Pending| matches(e) && e.waiting() && e.reported == Some(true) && !e.dest.has_wildcard();
        if let Some(at) = self.entries.iter().position(running) {
            let origin = self.entries[at].origin;
            let fan_out_of_other = self
                .entries
                .iter()
                .any(|e| matches(e) && e.waiting() && e.dest.has_wildcard() && e.origin != origin);
            let duplicate_of_other = self
                .entries
                .iter()
                .any(|e| !e.waiting() && !e.closed && e.resent && e.origin != origin && matches(e));
            if fan_out_of_other || duplicate_of_other {
                return AnswerMatch::Ambiguous;
            }
            let entry = &mut self.entries[at];
            entry.answered = true;
            entry.last_answer = Some((now, answer));
            if entry.disowned {
                return AnswerMatch::Disowned;
            }
            return AnswerMatch::One(origin);
        }
        self.take(matches, Some((now, answer)))
    }

    /// Where a `?` arriving on `link` goes back to. The NIC follows its
    /// command's ACK (1.4.2), and the next GCU reports a command delivered
    /// at that ACK: so it is first the oldest waiting entry reported
    /// delivered (as a result, above), else the oldest waiting one.
    pub fn match_nic(&mut self, link: LinkId) -> AnswerMatch {
        self.take(|e| e.out_link == link && e.expires.is_some(), None)
    }

    /// The origin of the matching entries, when they all share one: those
    /// still waiting for an answer first (the oldest is marked answered; a
    /// fan-out keeps waiting), else answered ones: a fan-out's further
    /// answer goes back where the first went, any other is a second run's
    /// ([`AnswerMatch::Spent`]). An answered entry whose frame was sent
    /// more than once may yet be answered again, so it makes a waiting
    /// entry of another origin ambiguous. `answer`: the result frame, `None`
    /// for a bare `?`, which the oldest entry reported delivered takes
    /// first, and which only waiting entries take. Either goes nowhere when
    /// its entry is disowned.
    fn take(&mut self, matches: impl Fn(&Pending) -> bool, answer: Option<(u64, FrameBuf)>) -> AnswerMatch {
        let bare = answer.is_none();
        let mut waiting = self
            .entries
            .iter()
            .filter(|e| e.waiting() && matches(e))
            .map(|e| e.origin);
        if let Some(origin) = waiting.next() {
            let duplicate_of_other = self
                .entries
                .iter()
                .any(|e| !e.waiting() && e.resent && e.origin != origin && matches(e));
            if waiting.any(|o| o != origin) || duplicate_of_other {
                return AnswerMatch::Ambiguous;
            }
            let delivered = |e: &Pending| bare && e.reported == Some(true);
            let at = (self.entries.iter())
                .position(|e| e.waiting() && matches(e) && delivered(e))
                .or_else(|| self.entries.iter().position(|e| e.waiting() && matches(e)));
            if let Some(first) = at.map(|at| &mut self.entries[at]) {
                first.answered = true;
                first.last_answer = answer;
                if first.disowned {
                    return AnswerMatch::Disowned;
                }
            }
            return AnswerMatch::One(origin);
        }
        let mut answered = self.entries.iter().filter(|e| matches(e)).map(|e| e.origin);
        match answered.next() {
            None => AnswerMatch::None,
            Some(_) if self.entries.iter().filter(|e| matches(e)).all(|e| e.disowned) => AnswerMatch::Disowned,
            // Every command it could answer was answered, and none is a
            // fan-out (whose answers are many): a second answer, from the
            // next GCU running a retransmission as a new command (our ACK
            // of the first copy was lost on a lossy link).
            Some(_) if bare || !self.entries.iter().any(|e| matches(e) && e.dest.has_wildcard()) => AnswerMatch::Spent,
            Some(origin) if answered.all(|o| o == origin) => AnswerMatch::One(origin),
            Some(_) => AnswerMatch::Ambiguous,
        }
    }

    /// Forgets what expired by `now`; adds to `unconfirmed` the commands
    /// whose delivery no report settled (the caller's vector, reused: no
    /// allocation in steady state).
    pub fn expire(&mut self, now: u64, unconfirmed: &mut Vec<CommandId>) {
        self.entries.retain(|e| {
            let keep = e.expires.is_none_or(|t| t > now);
            if !keep && e.reported.is_none() {
                unconfirmed.extend(e.command);
            }
            keep
        });
    }

    pub fn next_deadline(&self) -> Option<u64> {
        self.entries.iter().filter_map(|e| e.expires).min()
    }

    #[cfg(test)]
    pub fn len(&self) -> usize {
        self.entries.len()
    }

    /// Entries still owed something: a delivery report a client waits for,
    /// or a required result. Answered and reported entries are kept only to
    /// recognise repeats, which is no work left (shutdown need not wait).
    pub fn unsettled(&self) -> usize {
        self.entries.iter().filter(|e| e.owed()).count()
    }
}

#[cfg(test)]
mod tests;
