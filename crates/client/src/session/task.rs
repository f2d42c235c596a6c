//! The gimbal session's task, the only sender on the gimbal's connection:
//! the next step decided under the lock (owed stops first, then the
//! velocity, the positioning move, the queue, the poll), each step carried
//! out and its outcome recorded (ARCHITECTURE "Front doors").

use super::motion::{Driving, InForce, Pending, Reply, answer};
use super::travel::Travel;
use super::*;
use sagebrush_protocol::ResultKind;

/// What the task does next.
pub(super) enum Step {
    Stop(Command<'static>, Axes),
    /// A drive command, and the axis once it is acknowledged; after a
    /// speed, the direction command that takes it, chained to it
    /// ([`GimbalConnection::send_chained`]).
    Drive(Command<'static>, Applied, Option<(Command<'static>, Applied)>),
    /// A positioning move taken out of the motion state (a newer one
    /// waits there meanwhile), and its callers.
    Place(Place, Vec<Reply>),
    Query(Queued),
    Poll,
    Wait(Option<Instant>),
    End,
}

/// One axis as it is once a drive command is acknowledged.
#[derive(Clone, Copy, Debug)]
pub(super) enum Applied {
    Pan(InForce<Speed>),
    Tilt(InForce<Speed>),
    Zoom(InForce<LensSpeed>),
}

impl Applied {
    pub(super) fn axes(self) -> Axes {
        match self {
            Applied::Pan(_) => Axes {
                pan: true,
                ..Axes::default()
            },
            Applied::Tilt(_) => Axes {
                tilt: true,
                ..Axes::default()
            },
            Applied::Zoom(_) => Axes {
                zoom: true,
                ..Axes::default()
            },
        }
    }
}

impl GimbalSession {
    /// The next step, decided under the lock, and the door's user it is
    /// for (a drive, a positioning move or a queued command; module
    /// documentation of [`super::ForUser`]).
    pub(super) fn next(&self, now: Instant, next_poll: Instant) -> (Step, Option<Arc<str>>) {
        let mut by = None;
        let step = self.next_step(now, next_poll, &mut by);
        (step, by)
    }

    fn next_step(&self, now: Instant, next_poll: Instant, by: &mut Option<Arc<str>>) -> Step {
        let mut s = self.state();
        s.motion.expire(now, &self.config.name);
        s.drop_stale(now);
        s.motion.age_speeds(now);
        if s.closing && s.motion.stop_failures >= STOP_ATTEMPTS_ANSWERED {
            // Stopping the program: the stop was tried and reported.
            return Step::End;
        }
        if s.motion.stops_owed.any() {
            if s.motion.stop_retry_at.is_some_and(|t| t > now) {
                return Step::Wait(s.motion.stop_retry_at);
            }
            let (command, axes) = s.motion.stops_owed.first().expect("owed");
            return Step::Stop(command, axes);
        }
        if s.closing {
            return Step::End;
        }
        if let Some(w) = &s.motion.wish {
            let v = w.what;
            by.clone_from(&w.by);
            if let Some(step) = pan_tilt_step(Axis::Pan, v.pan, s.motion.pan)
                .or_else(|| pan_tilt_step(Axis::Tilt, v.tilt, s.motion.tilt))
                .or_else(|| zoom_step(v.zoom, s.motion.zoom))
            {
                s.motion.driving = Some(Driving {
                    by: by.clone(),
                    replies: Vec::new(),
                });
                return step;
            }
            // Everything asked is in force; then the zeros beside it.
            let w = s.motion.wish.take().expect("checked");
            answer(w.replies, Ok(()));
            let stops = std::mem::take(&mut s.motion.wish_stops);
            if stops.any() {
                s.motion.owe_stop(stops);
                let (command, axes) = s.motion.stops_owed.first().expect("owed");
                return Step::Stop(command, axes);
            }
        }
        if let Some(p) = s.motion.place.take() {
            *by = p.by;
            s.motion.placing = Some(p.what);
            return Step::Place(p.what, p.replies);
        }
        if let Some((queued, _, user)) = s.queue.pop_front() {
            *by = user;
            return Step::Query(queued);
        }
        if !s.readers.is_empty() {
            // A reader waits for a fresh poll: this one is the session's too.
            return Step::Poll;
        }
        let due = if s.motion.moving().any() || s.motion.travel.is_some() {
            next_poll.min(now + REFRESH)
        } else {
            next_poll
        };
        if due <= now {
            return Step::Poll;
        }
        Step::Wait(Some(s.motion.deadline.map_or(due, |d| d.min(due))))
    }

    pub(super) async fn run(self: Arc<Self>, mut connection: GimbalConnection) {
        let mut next_poll = Instant::now();
        let mut asked_control = None;
        loop {
            // What the connection last learnt of gcud's control (a poll, a refusal).
            self.control_seen(connection.control());
            let now = Instant::now();
            let (step, by) = self.next(now, next_poll);
            if matches!(step, Step::Drive(..) | Step::Place(..) | Step::Query(_)) {
                connection.act_for(by.as_deref()).await;
            }
            match step {
                Step::End => {
                    // Readers still waiting are told the session ended.
                    self.state().readers.clear();
                    return;
                }
                Step::Wait(until) => {
                    let sleep = tokio::time::sleep_until(until.unwrap_or(now + UNREACHABLE_POLL));
                    tokio::select! {
                        () = sleep => {}
                        () = self.wake.notified() => {}
                    }
                }
                Step::Stop(command, axes) => {
                    let sent = connection.send(&command).await;
                    self.reached(&sent);
                    self.stop_sent(&command, axes, sent);
                }
                Step::Drive(command, applied, None) => {
                    let sent = connection.send(&command).await;
                    self.reached(&sent);
                    let outcome = self.drive_sent(&command, applied, sent);
                    self.driven(outcome);
                }
                Step::Drive(speed, applied, Some((direction, then))) => {
                    // A stop owed by now goes before the direction.
                    let go_on = || !self.state().motion.stops_owed.any();
                    let (sent, then_sent) = connection.send_chained(&speed, &direction, &go_on).await;
                    self.reached(&sent);
                    let mut outcome = self.drive_sent(&speed, applied, sent);
                    if let Some(then_sent) = then_sent {
                        self.reached(&then_sent);
                        outcome = self.drive_sent(&direction, then, then_sent);
                    }
                    self.driven(outcome);
                }
                Step::Place(place, replies) => {
                    let sent = connection.send(&place.command()).await;
                    self.reached(&sent);
                    let mut s = self.state();
                    s.motion.placing = None;
                    // The gimbal's own motion: what it does to the speeds is its own.
                    s.motion.forget_speeds();
                    if sent.is_ok() {
                        // A motion from its acceptance until the polls show it ended.
                        s.motion.travel = Some(Travel::new(place.target(), s.status.position, Instant::now()));
                        s.taken = false;
                    } else if matches!(&sent, Err(e) if e.refusal() == Some(Undelivered::NotInControl)) {
                        s.taken = true;
                    }
                    if sent.is_ok() {
                        // The gimbal goes there instead of slewing.
                        s.motion.pan.drive = Drive::Stop;
                        s.motion.tilt.drive = Drive::Stop;
                        s.motion.settle_deadline();
                    }
                    // Its own callers: a move asked while it was on its way
                    // waits in `place`, sent next (it was taken for this
                    // one's and answered with its result: the pan, then tilt
                    // of a Pelco keyboard's absolute pair lost the tilt).
                    answer(replies, sent.map(drop));
                }
                Step::Query(Queued::Bus(command, reply)) => {
                    let sent = connection.send(&command).await;
                    self.reached(&sent);
                    if command.result_kind() == ResultKind::None || sent.is_err() {
                        // Not a query (it may set what a speed does), or it failed.
                        self.state().motion.forget_speeds();
                    }
                    let _ = reply.send(sent);
                }
                Step::Query(Queued::Gcu(request, reply)) => {
                    let a = self.config.address;
                    let answer = if request == GcuRequest::Controller(a.port, a.device) {
                        // This gimbal's: kept for the status too.
                        connection.controller().await.map(GcuAnswer::Controller)
                    } else {
                        connection.gcu(&request).await
                    };
                    self.reached(&answer);
                    let _ = reply.send(answer);
                }
                Step::Poll => {
                    let reading = poll(&mut connection, self.config.lens).await;
                    self.reached(&reading);
                    let failed = reading.is_err();
                    self.polled(reading);
                    // While a motion of its own is in force, with every poll:
                    // a take-over ends it (gcud stopped it), shown at once.
                    let own_motion = self.state().motion.own();
                    if !failed && (own_motion || asked_control.is_none_or(|t: Instant| t.elapsed() >= CONTROL_POLL)) {
                        asked_control = Some(Instant::now());
                        // Unknown while it fails (a gcud that governs nothing answers NIC).
                        let _ = connection.controller().await;
                    }
                    let poll = self.config.poll;
                    next_poll = Instant::now() + if failed { UNREACHABLE_POLL.max(poll) } else { poll };
                }
            }
        }
    }

    /// Records gcud's control of the gimbal as the connection last learnt
    /// it: a new answer naming another holder (a link, a tour, park) means
    /// it may have set other speeds. Once per answer, so that a holder
    /// named before this link took control back cannot make every speed
    /// be set again; nobody holding it is left to [`SPEED_KEPT`].
    fn control_seen(&self, control: Option<Control>) {
        let mut s = self.state();
        let another = control
            .as_ref()
            .is_some_and(|c| !c.ours && c.holder != Controller::Nobody);
        if another && control != s.status.control {
            s.motion.forget_speeds();
        }
        s.status.control = control;
        if s.taken_over() {
            let holder = s.another_holder().map(ToString::to_string).unwrap_or_default();
            info!(gimbal = %self.config.name, %holder, "another controller took the gimbal: gcud stopped the motion asked here");
        }
    }

    /// Records what became of an owed stop: confirmed, refused by the
    /// gimbal, given up after [`STOP_ATTEMPTS_ANSWERED`] answered attempts,
    /// or kept owed and sent again.
    fn stop_sent(&self, command: &Command<'static>, axes: Axes, sent: Result<Option<Vec<u8>>, CommandError>) {
        let mut s = self.state();
        if sent.is_err() {
            s.motion.forget_speeds();
        }
        match sent {
            Ok(_) => {
                s.motion.stop_confirmed(axes);
                if !s.motion.stops_owed.any() {
                    s.motion.stop_failures = 0;
                    let replies = std::mem::take(&mut s.motion.stop_replies);
                    answer(replies, Ok(()));
                    if !s.motion.moving().any() && s.motion.travel.is_none() {
                        // Confirmed on the bus: it stands, whatever the last poll saw.
                        s.status.changing = false;
                    }
                }
                s.motion.settle_deadline();
            }
            Err(CommandError::Nic(e)) => {
                // The gimbal cannot apply it (a zoom stop without a lens): nothing to retry.
                warn!(gimbal = %self.config.name, error = %e, "{} refused by the gimbal", command.in_words());
                s.motion.stops_owed = s.motion.stops_owed.without(axes);
                if !s.motion.stops_owed.any() {
                    let replies = std::mem::take(&mut s.motion.stop_replies);
                    answer(replies, Err(CommandError::Nic(e)));
                }
            }
            Err(e) if !matches!(e, CommandError::Io(_)) && s.motion.stop_failures + 1 >= STOP_ATTEMPTS_ANSWERED => {
                // gcud answered, the gimbal did not confirm (absent,
                // noise): tried again once; owing it for ever would
                // hold every other command of this gimbal.
                warn!(gimbal = %self.config.name, error = %e, "{} not confirmed after {STOP_ATTEMPTS_ANSWERED} attempts: given up", command.in_words());
                s.motion.stops_owed = s.motion.stops_owed.without(axes);
                s.motion.stop_failures = 0;
                s.motion.stop_retry_at = None;
                if !s.motion.stops_owed.any() {
                    let replies = std::mem::take(&mut s.motion.stop_replies);
                    answer(replies, Err(e));
                }
            }
            Err(e) => {
                s.motion.stop_failures += 1;
                let retry = if matches!(e, CommandError::Io(_)) {
                    STOP_RETRY
                } else {
                    (STOP_RETRY * s.motion.stop_failures).min(UNREACHABLE_POLL)
                };
                s.motion.stop_retry_at = Some(Instant::now() + retry);
                if s.motion.stop_failures.is_power_of_two() {
                    warn!(gimbal = %self.config.name, error = %e, attempt = s.motion.stop_failures, "{} not confirmed: kept owed, sent again", command.in_words());
                }
                if s.motion.stop_failures >= STOP_ATTEMPTS_ANSWERED {
                    let replies = std::mem::take(&mut s.motion.stop_replies);
                    answer(replies, Err(e));
                }
            }
        }
    }

    /// Records what became of a drive command: the axis in force, a
    /// refusal by gcud's rules, or a failure that owes the stops.
    fn drive_sent(
        &self,
        command: &Command<'static>,
        applied: Applied,
        sent: Result<Option<Vec<u8>>, CommandError>,
    ) -> Result<(), CommandError> {
        let mut s = self.state();
        let outcome = sent.as_ref().map(drop).map_err(Clone::clone);
        if sent.is_err() {
            // Any error or refusal: the speed set may not be what the gimbal has.
            s.motion.forget_speeds();
        }
        // The user it was sent for: another user's wish posted meanwhile
        // is not refused with it (two Pelco keyboards: the desk was told
        // the DVR's refusal, which named the desk as the holder).
        let sender = s.motion.driving.as_ref().map(|d| d.by.clone());
        let theirs = |w: &Pending<Velocity>| sender.as_ref().is_none_or(|by| *by == w.by);
        match sent {
            Ok(_) => {
                s.last_refusal = None;
                s.taken = false;
                // A speed command's ACK starts the time its speed is believed.
                let set_now = matches!(command, Command::SetSpeed(..) | Command::ZoomSpeed(_));
                let now = Instant::now();
                match applied {
                    Applied::Pan(a) => s.motion.pan = a.speed_set(set_now, now, &s.motion.pan),
                    Applied::Tilt(a) => s.motion.tilt = a.speed_set(set_now, now, &s.motion.tilt),
                    Applied::Zoom(a) => s.motion.zoom = a.speed_set(set_now, now, &s.motion.zoom),
                }
            }
            Err(e) if e.refusal().is_some() => {
                // gcud refused it by its rules: nothing reached
                // the bus, the axis did not start.
                if s.motion.wish.as_ref().is_some_and(theirs) {
                    let w = s.motion.wish.take().expect("checked");
                    answer(w.replies, Err(e.clone()));
                }
                let zeros = match &s.motion.wish {
                    // Another user's, posted meanwhile: their zeros wait with it.
                    Some(_) => Axes::default(),
                    None => std::mem::take(&mut s.motion.wish_stops),
                };
                if e.refusal() == Some(Undelivered::NotInControl) {
                    // Another link holds the gimbal: its motion is
                    // not this door's to stop, and gcud stopped
                    // ours when that link took control. What was
                    // set here (speeds too) is set again next time.
                    s.motion.drop_in_force();
                    s.taken = true;
                } else {
                    // Never leave an axis moving that the caller was told failed.
                    let ours = s.motion.in_force().or(zeros);
                    if ours.any() {
                        s.motion.owe_stop(ours);
                    }
                }
                s.motion.settle_deadline();
                if s.last_refusal != e.refusal() {
                    s.last_refusal = e.refusal();
                    info!(gimbal = %self.config.name, "{e} (logged once until something is accepted or refused otherwise)");
                }
            }
            Err(e) => {
                // Never leave an axis moving that the caller was told failed.
                let axes = s.motion.moving().or(std::mem::take(&mut s.motion.wish_stops));
                if let Some(w) = s.motion.wish.take() {
                    answer(w.replies, Err(e.clone()));
                }
                s.motion.owe_stop(axes.or(applied.axes()));
                warn!(gimbal = %self.config.name, error = %e, "{} failed: stopping the motion", command.in_words());
            }
        }
        outcome
    }

    /// A drive step ended with `outcome`: the callers of a wish another
    /// user superseded while it was on its way learn it.
    fn driven(&self, outcome: Result<(), CommandError>) {
        if let Some(d) = self.state().motion.driving.take() {
            answer(d.replies, outcome);
        }
    }

    /// Records a poll's reading, or its error, in the status.
    fn polled(&self, reading: Result<(Position, Option<LensPosition>), CommandError>) {
        let mut s = self.state();
        s.answer_readers(&reading);
        let st = &mut s.status;
        match reading {
            Ok((p, lens)) => {
                st.changing = st.position.is_some_and(|old| old != p) || (st.lens.is_some() && st.lens != lens);
                st.position = Some(p);
                st.lens = lens;
                st.error = None;
                s.motion.travel_polled(p, Instant::now());
            }
            Err(e) => {
                st.changing = false;
                st.error = Some(e.to_string());
                // The gimbal did not answer: it may have restarted since.
                s.motion.forget_speeds();
            }
        }
    }

    pub(super) fn reached<T>(&self, result: &Result<T, CommandError>) {
        match result {
            Err(e @ CommandError::Io(_)) => {
                self.reach.down(&self.config.link.gcud, e);
                // The connection is gone: gcud's dead-man stopped what it
                // started, unless gcud itself is gone; either way owe the stops.
                let mut s = self.state();
                let moving = s.motion.moving();
                if moving.any() {
                    s.motion.stops_owed = s.motion.stops_owed.or(moving);
                }
                // The next connection may find gcud or the gimbal restarted.
                s.motion.forget_speeds();
            }
            _ => self.reach.up(&self.config.link.gcud),
        }
    }
}

pub(super) fn closed() -> CommandError {
    CommandError::Io("the gimbal session has ended".to_owned())
}

/// The next command that moves one axis from `now` toward `want`, with
/// the axis after it. A speed (`SPn`, `STn`, `Zn`) is taken by the next
/// direction command (Table 11: "At constant speed"), so a speed that
/// differs from the one asked is set first and the direction follows: the
/// gimbal never starts at a speed nobody asked for ([`drive_step`] chains
/// the two, so a stream of changing rates always progresses).
pub(super) fn next_drive<S: Copy + PartialEq>(
    want: Option<Drive<S>>,
    now: InForce<S>,
    speed_command: impl Fn(S) -> Command<'static>,
    direction_command: impl Fn(Drive<S>) -> Command<'static>,
) -> Option<(Command<'static>, InForce<S>)> {
    let want = want?;
    let speed = want.speed()?;
    if now.speed != Some(speed) {
        let after = InForce {
            speed: Some(speed),
            ..now
        };
        return Some((speed_command(speed), after));
    }
    let at_speed = match want {
        Drive::Forward(_) => Drive::Forward(speed),
        _ => Drive::Back(speed),
    };
    // Start, turn, or apply the speed just set.
    (now.drive != at_speed).then(|| {
        let after = InForce { drive: at_speed, ..now };
        (direction_command(at_speed), after)
    })
}

/// The step [`next_drive`] gives, `applied` saying which axis: a speed
/// with the direction command that takes it chained, in one step, so that
/// no newer rate asked in between can set another speed before it.
fn drive_step<S: Copy + PartialEq>(
    want: Option<Drive<S>>,
    now: InForce<S>,
    speed_command: impl Fn(S) -> Command<'static>,
    direction_command: impl Fn(Drive<S>) -> Command<'static>,
    applied: impl Fn(InForce<S>) -> Applied,
) -> Option<Step> {
    let (command, after) = next_drive(want, now, &speed_command, &direction_command)?;
    let then = (after.speed != now.speed)
        .then(|| next_drive(want, after, &speed_command, &direction_command))
        .flatten()
        .map(|(direction, then)| (direction, applied(then)));
    Some(Step::Drive(command, applied(after), then))
}

/// [`next_drive`] for pan or tilt (Table 11: `SPn`/`STn`, `PR`/`PL`/`TU`/`TD`).
pub(super) fn pan_tilt_step(axis: Axis, want: Option<Drive<Speed>>, now: InForce<Speed>) -> Option<Step> {
    drive_step(
        want,
        now,
        |s| Command::SetSpeed(axis, s),
        |d| match (axis, d) {
            (Axis::Pan, Drive::Forward(_)) => Command::PanRight,
            (Axis::Pan, _) => Command::PanLeft,
            (Axis::Tilt, Drive::Forward(_)) => Command::TiltUp,
            (Axis::Tilt, _) => Command::TiltDown,
        },
        |after| match axis {
            Axis::Pan => Applied::Pan(after),
            Axis::Tilt => Applied::Tilt(after),
        },
    )
}

/// [`next_drive`] for the zoom (Table 16: `Zn`, `ZI`/`ZO`).
pub(super) fn zoom_step(want: Option<Drive<LensSpeed>>, now: InForce<LensSpeed>) -> Option<Step> {
    drive_step(
        want,
        now,
        Command::ZoomSpeed,
        |d| match d {
            Drive::Forward(_) => Command::ZoomIn,
            _ => Command::ZoomOut,
        },
        Applied::Zoom,
    )
}

pub(super) async fn poll(
    connection: &mut GimbalConnection,
    lens: bool,
) -> Result<(Position, Option<LensPosition>), CommandError> {
    let position = connection.position().await?;
    let lens = if lens { Some(connection.lens().await?) } else { None };
    Ok((position, lens))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn speed(n: u8) -> Speed {
        Speed::new(n).unwrap()
    }

    /// What `step` sends, in order, and the axis once all of it is
    /// acknowledged, as the session applies it.
    fn applied(step: Step) -> (Vec<String>, InForce<Speed>) {
        match step {
            Step::Drive(command, Applied::Pan(after), None) => (vec![command.mnemonic().to_owned()], after),
            Step::Drive(speed, Applied::Pan(_), Some((direction, Applied::Pan(after)))) => (
                vec![speed.mnemonic().to_owned(), direction.mnemonic().to_owned()],
                after,
            ),
            _ => unreachable!("only pan is asked"),
        }
    }

    #[test]
    fn a_rate_changing_at_every_step_still_moves_the_gimbal() {
        let mut now = InForce::default();
        let mut sent = Vec::new();
        for n in 0..12u8 {
            let want = Some(Drive::Forward(speed(1 + n % 15)));
            let (mnemonics, after) = applied(pan_tilt_step(Axis::Pan, want, now).unwrap());
            sent.extend(mnemonics);
            now = after;
        }
        let directions = sent.iter().filter(|m| m.as_str() == "PR").count();
        assert_eq!(directions, 12, "speed and direction alternate, chained: {sent:?}");
        assert!(sent.chunks(2).all(|pair| pair == ["SPn", "PR"]), "{sent:?}");
        assert_eq!(sent[0], "SPn", "the first speed is set before the first direction");
    }
}
