//! The reverse path of forwarded frames (DESIGN "Routing semantics":
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
//! Answered entries are kept until they expire: a lost link ACK makes the
//! sender retransmit and the next GCU execute the command twice (the
//! protocol has no sequence numbers), so a second answer may follow. Kept,
//! the answered entry makes that duplicate ambiguous against another
//! origin's pending command instead of being taken for its answer. When
//! the table is full, the oldest answered entry is forgotten first.
//!
//! Entries outlive a link going down, either way: the next GCU keeps
//! executing and answers on the link once it is back (same id), and answers
//! for an origin that left are recognised and counted
//! ([`crate::DropReason::OriginGone`]) instead of being routed on.
//!
//! [`DropReason::AmbiguousAnswer`]: crate::DropReason::AmbiguousAnswer

use std::collections::VecDeque;

use sagebrush_protocol::{Address, Frame, ResultKind, ResultTimeout, WILDCARD};

use crate::config::LinkSettings;
use crate::types::{LinkId, Origin};

#[derive(Clone, Copy, Debug)]
struct Pending {
    key: u64,
    out_link: LinkId,
    origin: Origin,
    /// Source group of the forwarded frame.
    source: u8,
    dest: Address,
    kind: ResultKind,
    /// Set at the first transmission on `out_link`.
    expires: Option<u64>,
    /// An answer went back already.
    answered: bool,
}

impl Pending {
    fn answered_by(&self, frame: &Frame<'_>) -> bool {
        let level = |want: u8, got: u8| want == WILDCARD || want == got;
        self.kind != ResultKind::None
            && frame.dest.group == self.source
            && level(self.dest.port, frame.dest.port)
            && level(self.dest.device, frame.dest.device)
            && level(self.dest.group, frame.source)
    }
}

/// Where an answer (result or `?`) from a link goes back to.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum AnswerMatch {
    None,
    One(Origin),
    Ambiguous,
}

#[derive(Debug)]
pub(crate) struct ReversePath {
    entries: VecDeque<Pending>,
    next_key: u64,
    max: usize,
}

impl ReversePath {
    pub fn new(max: usize) -> Self {
        Self {
            entries: VecDeque::new(),
            next_key: 0,
            max: max.max(1),
        }
    }

    /// Remembers a forwarded frame; returns its key and whether the oldest
    /// entry had to be forgotten to make room.
    pub fn insert(&mut self, out_link: LinkId, origin: Origin, frame: &Frame<'_>, kind: ResultKind) -> (u64, bool) {
        let evicted = self.entries.len() >= self.max;
        if evicted {
            let at = self.entries.iter().position(|e| e.answered).unwrap_or(0);
            self.entries.remove(at);
        }
        let key = self.next_key;
        self.next_key += 1;
        self.entries.push_back(Pending {
            key,
            out_link,
            origin,
            source: frame.source,
            dest: frame.dest,
            kind,
            expires: None,
            answered: false,
        });
        (key, evicted)
    }

    /// The frame of `key` was transmitted for the first time at `now`.
    pub fn sent(&mut self, key: u64, now: u64, settings: &LinkSettings) {
        if let Some(e) = self.entries.iter_mut().find(|e| e.key == key) {
            let wait = match e.kind {
                ResultKind::None => settings.nic_answer_timeout,
                ResultKind::Required(ResultTimeout::Long) => settings.long_answer_timeout,
                ResultKind::Required(ResultTimeout::Normal) | ResultKind::Optional => settings.answer_timeout,
            };
            e.expires = Some(now.saturating_add(wait));
        }
    }

    /// The frame of `key` was dropped or given up. Once transmitted, the
    /// next GCU may have executed it even though no ACK came back (ACKs get
    /// lost too), so a transmitted entry stays until it expires.
    pub fn cancel(&mut self, key: u64) {
        self.entries.retain(|e| e.key != key || e.expires.is_some());
    }

    /// Where a frame arriving on `link` goes back to, if it answers a forwarded one.
    pub fn match_result(&mut self, link: LinkId, frame: &Frame<'_>) -> AnswerMatch {
        self.take(|e| e.out_link == link && e.expires.is_some() && e.answered_by(frame))
    }

    /// Where a `?` arriving on `link` goes back to.
    pub fn match_nic(&mut self, link: LinkId) -> AnswerMatch {
        self.take(|e| e.out_link == link && e.expires.is_some())
    }

    /// The origin of the matching entries, when they all share one; the
    /// oldest unanswered one is marked answered.
    fn take(&mut self, matches: impl Fn(&Pending) -> bool) -> AnswerMatch {
        let mut candidates = self.entries.iter_mut().filter(|e| matches(e));
        let Some(first) = candidates.next() else {
            return AnswerMatch::None;
        };
        let origin = first.origin;
        let mut fresh = (!first.answered).then_some(first);
        for e in candidates {
            if e.origin != origin {
                return AnswerMatch::Ambiguous;
            }
            if fresh.is_none() && !e.answered {
                fresh = Some(e);
            }
        }
        if let Some(e) = fresh {
            e.answered = true;
        }
        AnswerMatch::One(origin)
    }

    /// Forgets what expired by `now`.
    pub fn expire(&mut self, now: u64) {
        self.entries.retain(|e| e.expires.is_none_or(|t| t > now));
    }

    pub fn next_deadline(&self) -> Option<u64> {
        self.entries.iter().filter_map(|e| e.expires).min()
    }

    pub fn len(&self) -> usize {
        self.entries.len()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const L: LinkId = LinkId(1);

    fn origin(link: u32) -> Origin {
        Origin::Link {
            link: LinkId(link),
            source: 2,
        }
    }

    #[test]
    fn result_goes_back_to_the_origin_of_the_forwarded_command() {
        let settings = LinkSettings::default();
        let mut rp = ReversePath::new(8);
        let cmd = Frame::new(Address::new(5, 1, 12), 2, b"P?").unwrap();
        let (a, _) = rp.insert(L, origin(10), &cmd, ResultKind::Required(ResultTimeout::Normal));
        let (b, _) = rp.insert(L, origin(11), &cmd, ResultKind::Required(ResultTimeout::Normal));
        let result = Frame::new(Address::new(2, 1, 12), 5, b"00000000").unwrap();
        // Not transmitted yet: not an answer.
        assert_eq!(rp.match_result(L, &result), AnswerMatch::None);
        rp.sent(a, 0, &settings);
        assert_eq!(rp.match_result(LinkId(2), &result), AnswerMatch::None, "wrong link");
        assert_eq!(rp.match_result(L, &result), AnswerMatch::One(origin(10)));
        // A duplicate of that answer is still recognised as origin 10's.
        assert_eq!(rp.match_result(L, &result), AnswerMatch::One(origin(10)));
        rp.sent(b, 1, &settings);
        // Now it could be origin 10's duplicate or origin 11's answer.
        assert_eq!(rp.match_result(L, &result), AnswerMatch::Ambiguous);
        rp.expire(settings.answer_timeout);
        assert_eq!(rp.match_result(L, &result), AnswerMatch::One(origin(11)));
        rp.expire(settings.answer_timeout + 1);
        assert_eq!(rp.match_result(L, &result), AnswerMatch::None);
    }

    #[test]
    fn answer_that_two_origins_may_own_is_ambiguous() {
        let settings = LinkSettings::default();
        let mut rp = ReversePath::new(8);
        let exact = Frame::new(Address::new(5, 1, 12), 2, b"*mu1").unwrap();
        let wildcard = Frame::new(Address::new(5, 1, 255), 2, b"*mu2").unwrap();
        let kind = ResultKind::Optional;
        let (a, _) = rp.insert(L, origin(10), &wildcard, kind);
        let (b, _) = rp.insert(L, origin(11), &exact, kind);
        rp.sent(a, 0, &settings);
        rp.sent(b, 0, &settings);
        let result = Frame::new(Address::new(2, 1, 12), 5, b"1").unwrap();
        assert_eq!(rp.match_result(L, &result), AnswerMatch::Ambiguous);
        let other = Frame::new(Address::new(2, 1, 13), 5, b"2").unwrap();
        assert_eq!(rp.match_result(L, &other), AnswerMatch::One(origin(10)));
        assert_eq!(
            rp.match_result(L, &other),
            AnswerMatch::One(origin(10)),
            "wildcard entries stay"
        );
    }

    #[test]
    fn nic_of_two_origins_is_ambiguous_and_entries_expire() {
        let settings = LinkSettings::default();
        let mut rp = ReversePath::new(8);
        let cmd = Frame::new(Address::new(5, 1, 12), 2, b"PL").unwrap();
        let (a, _) = rp.insert(L, origin(10), &cmd, ResultKind::None);
        rp.sent(a, 0, &settings);
        let (b, _) = rp.insert(L, origin(11), &cmd, ResultKind::None);
        rp.sent(b, 0, &settings);
        assert_eq!(rp.match_nic(L), AnswerMatch::Ambiguous);
        rp.cancel(b);
        assert_eq!(
            rp.match_nic(L),
            AnswerMatch::Ambiguous,
            "b was transmitted: its answer may come"
        );
        let (d, _) = rp.insert(L, origin(12), &cmd, ResultKind::None);
        rp.cancel(d);
        rp.expire(settings.nic_answer_timeout);
        assert_eq!(rp.len(), 0, "b expired, d was never transmitted");
        let (a, _) = rp.insert(L, origin(10), &cmd, ResultKind::None);
        rp.sent(a, 0, &settings);
        assert_eq!(rp.match_nic(L), AnswerMatch::One(origin(10)));
        let (c, _) = rp.insert(L, origin(10), &cmd, ResultKind::None);
        rp.sent(c, 5, &settings);
        assert_eq!(rp.next_deadline(), Some(settings.nic_answer_timeout));
        rp.expire(settings.nic_answer_timeout);
        assert_eq!(rp.len(), 1);
        rp.expire(settings.nic_answer_timeout + 5);
        assert_eq!(rp.len(), 0);
        assert_eq!(rp.match_nic(L), AnswerMatch::None);
    }

    #[test]
    fn bounded_by_evicting_the_oldest_answered_first() {
        let settings = LinkSettings::default();
        let mut rp = ReversePath::new(2);
        let cmd = Frame::new(Address::new(5, 1, 12), 2, b"PL").unwrap();
        let other = Frame::new(Address::new(5, 1, 13), 2, b"P?").unwrap();
        let (a, evicted) = rp.insert(L, origin(1), &cmd, ResultKind::None);
        assert!(!evicted);
        let (b, evicted) = rp.insert(L, origin(2), &other, ResultKind::Required(ResultTimeout::Normal));
        assert!(!evicted);
        rp.sent(a, 0, &settings);
        rp.sent(b, 0, &settings);
        let answer = Frame::new(Address::new(2, 1, 13), 5, b"00000000").unwrap();
        assert_eq!(rp.match_result(L, &answer), AnswerMatch::One(origin(2)));
        assert!(rp.insert(L, origin(1), &cmd, ResultKind::None).1);
        assert_eq!(rp.len(), 2);
        // The unanswered first entry survived: a `?` still finds origin 1.
        assert_eq!(rp.match_nic(L), AnswerMatch::One(origin(1)));
    }
}
