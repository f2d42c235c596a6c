use super::*;
use sagebrush_protocol::{Command, Undelivered};

const L: LinkId = LinkId(1);
thread_local!(static CLOCK: std::cell::Cell<u64> = const { std::cell::Cell::new(10_000) });

/// A time after the repeat window of every earlier answer.
fn later() -> u64 {
    CLOCK.with(|c| {
        c.set(c.get() + 1_000);
        c.get()
    })
}

/// The facts of `frame`'s command, whose result kind the test states.
fn fwd(frame: &Frame<'_>, kind: ResultKind) -> CommandFacts {
    let facts = CommandFacts {
        stop: false,
        ..CommandFacts::read(frame.payload())
    };
    assert_eq!(facts.reply.result_kind(), kind, "{frame:?}");
    facts
}

fn origin(link: u32) -> Origin {
    Origin::Link {
        link: LinkId(link),
        source: 2,
    }
}

#[test]
fn result_goes_back_to_the_origin_of_the_forwarded_command() {
    let settings = LinkSettings::default();
    let mut rp = ReversePath::new(8, 200);
    let cmd = Frame::new(Address::new(5, 1, 12), 2, b"P?").unwrap();
    let (a, _) = rp.insert(
        L,
        origin(10),
        &cmd,
        fwd(&cmd, ResultKind::Required(ResultTimeout::Normal)),
        None,
    );
    let (b, _) = rp.insert(
        L,
        origin(11),
        &cmd,
        fwd(&cmd, ResultKind::Required(ResultTimeout::Normal)),
        None,
    );
    let result = Frame::new(Address::new(2, 1, 12), 5, b"00000000").unwrap();
    // Not transmitted yet: not an answer.
    assert_eq!(rp.match_result(later(), L, &result, true), AnswerMatch::None);
    rp.sent(a, 0, &settings);
    assert_eq!(
        rp.match_result(later(), LinkId(2), &result, true),
        AnswerMatch::None,
        "wrong link"
    );
    assert_eq!(rp.match_result(later(), L, &result, true), AnswerMatch::One(origin(10)));
    // A second answer past the repeat window: a command has one result
    // (1.4.3), so it is the next GCU's second run of it, nobody's.
    assert_eq!(rp.match_result(later(), L, &result, true), AnswerMatch::Spent);
    rp.sent(b, 1, &settings);
    // Origin 11 is still waiting: the next answer is its answer (a new
    // client run must not be blocked by an answered entry).
    assert_eq!(rp.match_result(later(), L, &result, true), AnswerMatch::One(origin(11)));
    // Both answered now: a further one is a second run's, whoever's.
    assert_eq!(rp.match_result(later(), L, &result, true), AnswerMatch::Spent);
    rp.expire(settings.answer_timeout, &mut Vec::new());
    assert_eq!(rp.match_result(later(), L, &result, true), AnswerMatch::Spent);
    rp.expire(settings.answer_timeout + 1, &mut Vec::new());
    assert_eq!(rp.match_result(later(), L, &result, true), AnswerMatch::None);
}

#[test]
fn an_answered_entry_sent_twice_may_be_answered_again() {
    let settings = LinkSettings::default();
    let mut rp = ReversePath::new(8, 200);
    let cmd = Frame::new(Address::new(5, 1, 12), 2, b"P?").unwrap();
    let (a, _) = rp.insert(
        L,
        origin(10),
        &cmd,
        fwd(&cmd, ResultKind::Required(ResultTimeout::Normal)),
        None,
    );
    rp.sent(a, 0, &settings);
    rp.resent(a);
    let result = Frame::new(Address::new(2, 1, 12), 5, b"00000000").unwrap();
    assert_eq!(rp.match_result(later(), L, &result, true), AnswerMatch::One(origin(10)));
    let (b, _) = rp.insert(
        L,
        origin(11),
        &cmd,
        fwd(&cmd, ResultKind::Required(ResultTimeout::Normal)),
        None,
    );
    rp.sent(b, 1, &settings);
    assert_eq!(
        rp.match_result(later(), L, &result, true),
        AnswerMatch::Ambiguous,
        "origin 10's command ran twice at the next GCU: this may be its second answer"
    );
}

#[test]
fn a_repeated_answer_is_recognised_and_goes_nowhere() {
    let settings = LinkSettings::default();
    let mut rp = ReversePath::new(8, 200);
    let cmd = Frame::new(Address::new(5, 1, 12), 2, b"P?").unwrap();
    let (a, _) = rp.insert(
        L,
        origin(10),
        &cmd,
        fwd(&cmd, ResultKind::Required(ResultTimeout::Normal)),
        None,
    );
    rp.sent(a, 0, &settings);
    let answer = Frame::new(Address::new(2, 1, 12), 5, b"00640064").unwrap();
    assert_eq!(rp.match_result(1000, L, &answer, true), AnswerMatch::One(origin(10)));
    let (b, _) = rp.insert(
        L,
        origin(11),
        &cmd,
        fwd(&cmd, ResultKind::Required(ResultTimeout::Normal)),
        None,
    );
    rp.sent(b, 1010, &settings);
    // The next GCU did not get our ACK and sends the same frame again: it
    // went back already (hop by hop), and is no answer of origin 11's.
    assert_eq!(rp.match_result(1200, L, &answer, true), AnswerMatch::Repeat, "a repeat");
    let moved = Frame::new(Address::new(2, 1, 12), 5, b"00C80064").unwrap();
    assert_eq!(
        rp.match_result(1250, L, &moved, true),
        AnswerMatch::One(origin(11)),
        "a new answer"
    );
    // Past the window, the same bytes are a new answer, and nobody waits:
    // both commands were answered, so it is a second run's.
    assert_eq!(rp.match_result(1401, L, &answer, true), AnswerMatch::Spent);
    // On a lossless link nothing is repeated: identical bytes are a new answer.
    let (c, _) = rp.insert(
        L,
        origin(12),
        &cmd,
        fwd(&cmd, ResultKind::Required(ResultTimeout::Normal)),
        None,
    );
    rp.sent(c, 1410, &settings);
    assert_eq!(rp.match_result(1420, L, &moved, false), AnswerMatch::One(origin(12)));
}

#[test]
fn an_answer_must_fit_the_forwarded_command() {
    let settings = LinkSettings::default();
    let mut rp = ReversePath::new(8, 200);
    let position = Frame::new(Address::new(5, 1, 12), 2, b"P?").unwrap();
    let identify = Frame::new(Address::new(5, 1, 12), 2, b"D?").unwrap();
    let (a, _) = rp.insert(
        L,
        origin(10),
        &position,
        fwd(&position, ResultKind::Required(ResultTimeout::Normal)),
        None,
    );
    let (b, _) = rp.insert(
        L,
        origin(11),
        &identify,
        fwd(&identify, ResultKind::Required(ResultTimeout::Normal)),
        None,
    );
    rp.sent(a, 0, &settings);
    rp.sent(b, 0, &settings);
    let id_block = Frame::new(Address::new(2, 1, 12), 5, b"0C19Sagebrush SIM").unwrap();
    assert_eq!(
        rp.match_result(later(), L, &id_block, true),
        AnswerMatch::One(origin(11)),
        "not a Table 15 position"
    );
    let pos = Frame::new(Address::new(2, 1, 12), 5, b"00000000").unwrap();
    assert_eq!(rp.match_result(later(), L, &pos, true), AnswerMatch::One(origin(10)));
}

#[test]
fn answer_that_two_origins_may_own_is_ambiguous() {
    let settings = LinkSettings::default();
    let mut rp = ReversePath::new(8, 200);
    let exact = Frame::new(Address::new(5, 1, 12), 2, b"*mu1").unwrap();
    let wildcard = Frame::new(Address::new(5, 1, 255), 2, b"*mu2").unwrap();
    let kind = ResultKind::Optional;
    let (a, _) = rp.insert(L, origin(10), &wildcard, fwd(&wildcard, kind), None);
    let (b, _) = rp.insert(L, origin(11), &exact, fwd(&exact, kind), None);
    rp.sent(a, 0, &settings);
    rp.sent(b, 0, &settings);
    let result = Frame::new(Address::new(2, 1, 12), 5, b"1").unwrap();
    assert_eq!(rp.match_result(later(), L, &result, true), AnswerMatch::Ambiguous);
    let other = Frame::new(Address::new(2, 1, 13), 5, b"2").unwrap();
    assert_eq!(rp.match_result(later(), L, &other, true), AnswerMatch::One(origin(10)));
    assert_eq!(
        rp.match_result(later(), L, &other, true),
        AnswerMatch::One(origin(10)),
        "wildcard entries stay"
    );
}

#[test]
fn nic_of_two_origins_is_ambiguous_and_entries_expire() {
    let settings = LinkSettings::default();
    let mut rp = ReversePath::new(8, 200);
    let cmd = Frame::new(Address::new(5, 1, 12), 2, b"PL").unwrap();
    let (a, _) = rp.insert(L, origin(10), &cmd, fwd(&cmd, ResultKind::None), None);
    rp.sent(a, 0, &settings);
    let (b, _) = rp.insert(L, origin(11), &cmd, fwd(&cmd, ResultKind::None), None);
    rp.sent(b, 0, &settings);
    assert_eq!(rp.match_nic(L), AnswerMatch::Ambiguous);
    rp.cancel(b);
    assert_eq!(
        rp.match_nic(L),
        AnswerMatch::Ambiguous,
        "b was transmitted: its answer may come"
    );
    let (d, _) = rp.insert(L, origin(12), &cmd, fwd(&cmd, ResultKind::None), None);
    rp.cancel(d);
    rp.expire(settings.nic_answer_timeout, &mut Vec::new());
    assert_eq!(rp.len(), 0, "b expired, d was never transmitted");
    let (a, _) = rp.insert(L, origin(10), &cmd, fwd(&cmd, ResultKind::None), None);
    rp.sent(a, 0, &settings);
    assert_eq!(rp.match_nic(L), AnswerMatch::One(origin(10)));
    let (c, _) = rp.insert(L, origin(10), &cmd, fwd(&cmd, ResultKind::None), None);
    rp.sent(c, 5, &settings);
    assert_eq!(rp.next_deadline(), Some(settings.nic_answer_timeout));
    rp.expire(settings.nic_answer_timeout, &mut Vec::new());
    assert_eq!(rp.len(), 1);
    rp.expire(settings.nic_answer_timeout + 5, &mut Vec::new());
    assert_eq!(rp.len(), 0);
    assert_eq!(rp.match_nic(L), AnswerMatch::None);
}

#[test]
fn bounded_by_evicting_the_oldest_answered_first() {
    let settings = LinkSettings::default();
    let mut rp = ReversePath::new(2, 200);
    let cmd = Frame::new(Address::new(5, 1, 12), 2, b"PL").unwrap();
    let other = Frame::new(Address::new(5, 1, 13), 2, b"P?").unwrap();
    let (a, evicted) = rp.insert(L, origin(1), &cmd, fwd(&cmd, ResultKind::None), None);
    assert_eq!(evicted, None);
    let (b, evicted) = rp.insert(
        L,
        origin(2),
        &other,
        fwd(&other, ResultKind::Required(ResultTimeout::Normal)),
        None,
    );
    assert_eq!(evicted, None);
    rp.sent(a, 0, &settings);
    rp.sent(b, 0, &settings);
    let answer = Frame::new(Address::new(2, 1, 13), 5, b"00000000").unwrap();
    assert_eq!(rp.match_result(later(), L, &answer, true), AnswerMatch::One(origin(2)));
    assert_eq!(
        rp.insert(L, origin(1), &cmd, fwd(&cmd, ResultKind::None), None).1,
        None,
        "the answered entry is settled: forgetting it is no drop"
    );
    assert_eq!(rp.len(), 2);
    // The unanswered first entry survived: a `?` still finds origin 1.
    assert_eq!(rp.match_nic(L), AnswerMatch::One(origin(1)));
}

fn report(dest: Address, command: &Frame<'_>, failure: Option<Undelivered>) -> DeliveryReport {
    DeliveryReport {
        failure,
        dest,
        command_checksum: command.checksum(),
        at_group: 5,
    }
}

/// Issue 20.1: the commands of a client that left (origin 10, still
/// waiting) never shadow the next client's (origin 11): the next GCU's
/// reports say which transaction runs, and a later report closes the
/// earlier ones.
#[test]
fn answers_follow_the_next_gcus_reports_not_a_waiting_origin() {
    let settings = LinkSettings::default();
    let mut rp = ReversePath::new(16, 200);
    let at = Address::new(5, 1, 12);
    let presets: Vec<FrameBuf> = (1..=3u8)
        .map(|n| FrameBuf::build(at, 2, |b| Command::QueryPreset(n).encode(b).map(<[u8]>::len)).unwrap())
        .collect();
    let query = Frame::new(at, 2, b"P?").unwrap();
    let normal = |f: &Frame<'_>| fwd(f, ResultKind::Required(ResultTimeout::Normal));
    for p in &presets {
        let (k, _) = rp.insert(L, origin(10), &p.frame(), normal(&p.frame()), Some(CommandId(k_of(p))));
        rp.sent(k, 0, &settings);
    }
    let (k, _) = rp.insert(L, origin(11), &query, normal(&query), Some(CommandId(99)));
    rp.sent(k, 0, &settings);
    let answer = Frame::new(Address::new(2, 1, 12), 5, b"00640064").unwrap();
    // Unreported, two origins wait: an answer now cannot be placed.
    assert_eq!(rp.match_result(later(), L, &answer, false), AnswerMatch::Ambiguous);
    // The first preset query ran: reported, then answered.
    let first = presets[0].frame();
    assert_eq!(
        settles(&mut rp, &report(at, &first, None)),
        Some(Some(CommandId(k_of(&presets[0]))))
    );
    assert_eq!(
        rp.match_result(later(), L, &answer, false),
        AnswerMatch::One(origin(10))
    );
    // The second was reported but its answer was lost; the third was
    // refused (its queue was full): the report of the next client's
    // query closes the second, and the answer is the next client's.
    let second = presets[1].frame();
    let third = presets[2].frame();
    assert!(settles(&mut rp, &report(at, &second, None)).is_some());
    assert!(settles(&mut rp, &report(at, &third, Some(Undelivered::QueueFull))).is_some());
    assert_eq!(settles(&mut rp, &report(at, &query, None)), Some(Some(CommandId(99))));
    assert_eq!(
        rp.match_result(later(), L, &answer, false),
        AnswerMatch::One(origin(11))
    );
    assert_eq!(rp.unsettled(), 0, "nothing is owed any more");
}

fn k_of(frame: &FrameBuf) -> u64 {
    u64::from(frame.frame().checksum())
}

/// Issue 20.1: on a lossless link two byte-identical answers in the
/// same tick (a resting gimbal's position, asked twice) are two answers.
#[test]
fn identical_answers_in_one_tick_on_a_lossless_link_are_two_answers() {
    let settings = LinkSettings::default();
    let mut rp = ReversePath::new(8, 200);
    let cmd = Frame::new(Address::new(5, 1, 12), 2, b"P?").unwrap();
    let normal = |f: &Frame<'_>| fwd(f, ResultKind::Required(ResultTimeout::Normal));
    let (a, _) = rp.insert(L, origin(10), &cmd, normal(&cmd), Some(CommandId(1)));
    let (b, _) = rp.insert(L, origin(11), &cmd, normal(&cmd), Some(CommandId(2)));
    rp.sent(a, 0, &settings);
    rp.sent(b, 0, &settings);
    let answer = Frame::new(Address::new(2, 1, 12), 5, b"00000000").unwrap();
    let delivered = report(cmd.dest, &cmd, None);
    assert_eq!(settles(&mut rp, &delivered), Some(Some(CommandId(1))));
    assert_eq!(rp.match_result(500, L, &answer, false), AnswerMatch::One(origin(10)));
    assert_eq!(settles(&mut rp, &delivered), Some(Some(CommandId(2))));
    assert_eq!(rp.match_result(500, L, &answer, false), AnswerMatch::One(origin(11)));
}

/// ARCHITECTURE "Delivery contract": a `?` of a command whose origin was
/// told it was not delivered goes nowhere; the NIC follows the ACK
/// (1.4.2), so it is the `?` of the oldest entry the next GCU reported
/// delivered, and another command of that origin still gets its own.
#[test]
fn a_nic_of_a_disowned_command_goes_nowhere_and_the_next_ones_goes_back() {
    let settings = LinkSettings::default();
    let mut rp = ReversePath::new(8, 200);
    let none = |f: &Frame<'_>| fwd(f, ResultKind::None);
    let first = Frame::new(Address::new(5, 1, 12), 2, b"SP5").unwrap();
    let second = Frame::new(Address::new(5, 2, 12), 2, b"SP6").unwrap();
    let (a, _) = rp.insert(L, origin(10), &first, none(&first), Some(CommandId(1)));
    rp.sent(a, 0, &settings);
    let (b, _) = rp.insert(L, origin(10), &second, none(&second), Some(CommandId(2)));
    rp.sent(b, 0, &settings);
    // Our delivery time-out told the origin `0B`: the first is disowned.
    rp.disown(CommandId(1));
    // The next GCU reports the second delivered (the first's report never
    // came): a `?` now is the second's, and goes back.
    assert_eq!(
        settles(&mut rp, &report(second.dest, &second, None)),
        Some(Some(CommandId(2)))
    );
    assert_eq!(rp.match_nic(L), AnswerMatch::One(origin(10)));
    // A third command of that origin waits when the first one's report
    // comes after all: the `?` after it is the first one's, and goes nowhere.
    let (c, _) = rp.insert(L, origin(10), &first, none(&first), Some(CommandId(3)));
    rp.sent(c, 0, &settings);
    assert_eq!(
        settles(&mut rp, &report(first.dest, &first, None)),
        Some(Some(CommandId(1)))
    );
    assert_eq!(rp.match_nic(L), AnswerMatch::Disowned);
    // A third command of that origin still gets its own.
    assert_eq!(rp.match_nic(L), AnswerMatch::One(origin(10)));
}

/// The command a report from group 2's side on `L` settles (`match_report`).
fn settles(rp: &mut ReversePath, report: &DeliveryReport) -> Option<Option<CommandId>> {
    rp.match_report(L, 2, report).map(|(_, command)| command)
}
