//! A gimbal's drives (Pan-tiltDrive, CAM_Zoom) on their way to its session:
//! bounded whatever the clients send, and stops first. One drive and one
//! stop at most are posted to the session at a time; what comes meanwhile
//! waits in one slot each, newest wins (a 20 Hz joystick stream posts at
//! the bus's pace, never a queue of stale drives). A stop is posted at
//! once, even while a drive is under way, and ends the drives still
//! waiting for its axes (a stop overtakes queued drives). Each drive runs
//! for the motion lease unless the client repeats it: VISCA drives have
//! no time-out of their own. Replies: Completion once the drive or stop
//! is in force (or superseded), `90 61 41 FF` when gcud refuses it, with
//! gcud's reason in the log.

use std::sync::{Arc, Mutex, PoisonError};
use std::time::Duration;

use sagebrush_client::CommandError;
use sagebrush_client::session::{Drive, GimbalSession, Velocity};
use tokio::sync::{Notify, oneshot};
use tracing::info;

use crate::reply::Replier;
use crate::stats::{Stats, may_warn};
use crate::visca;

/// Clients told of one drive's outcome at most; older ones superseded
/// beyond it are answered Completion at once.
const WAITING: usize = 8;

/// A velocity with the clients that wait for its outcome.
#[derive(Debug)]
struct Posting {
    velocity: Velocity,
    replies: Vec<Replier>,
}

/// A posting under way: the session's answer to come, and who waits for it.
type Under = Option<(oneshot::Receiver<Result<(), CommandError>>, Vec<Replier>)>;

#[derive(Debug, Default)]
struct Slot {
    drive: Option<Posting>,
    stop: Option<Posting>,
}

/// One gimbal's drives; see the module's documentation.
#[derive(Debug, Default)]
pub struct Desk {
    slot: Mutex<Slot>,
    wake: Notify,
}

fn is_stop(v: &Velocity) -> bool {
    [
        v.pan.is_some_and(|d| d != Drive::Stop),
        v.tilt.is_some_and(|d| d != Drive::Stop),
        v.zoom.is_some_and(|d| d != Drive::Stop),
    ]
    .iter()
    .all(|moves| !moves)
}

/// `replies` with `more` added, the oldest beyond [`WAITING`] in `done`.
fn join(mut replies: Vec<Replier>, more: Vec<Replier>, done: &mut Vec<Replier>) -> Vec<Replier> {
    replies.extend(more);
    if replies.len() > WAITING {
        done.extend(replies.drain(..replies.len() - WAITING));
    }
    replies
}

impl Desk {
    /// Takes `velocity` (a drive, or a stop: no axis moving) for `replier`.
    pub fn post(&self, velocity: Velocity, replier: Replier) {
        let mut done = Vec::new();
        {
            let mut s = self.slot.lock().unwrap_or_else(PoisonError::into_inner);
            if is_stop(&velocity) {
                let mut replies = vec![replier];
                // The stop ends the waiting drive's axes it names.
                if let Some(mut d) = s.drive.take() {
                    let v = &mut d.velocity;
                    v.pan = v.pan.filter(|_| velocity.pan.is_none());
                    v.tilt = v.tilt.filter(|_| velocity.tilt.is_none());
                    v.zoom = v.zoom.filter(|_| velocity.zoom.is_none());
                    if is_stop(&d.velocity) {
                        replies = join(d.replies, replies, &mut done);
                    } else {
                        s.drive = Some(d);
                    }
                }
                s.stop = Some(match s.stop.take() {
                    None => Posting { velocity, replies },
                    Some(old) => Posting {
                        velocity: Velocity {
                            pan: old.velocity.pan.or(velocity.pan),
                            tilt: old.velocity.tilt.or(velocity.tilt),
                            zoom: old.velocity.zoom.or(velocity.zoom),
                        },
                        replies: join(old.replies, replies, &mut done),
                    },
                });
            } else {
                // Newest wins, per axis: a zoom drive leaves a waiting pan drive be.
                s.drive = Some(match s.drive.take() {
                    None => Posting {
                        velocity,
                        replies: vec![replier],
                    },
                    Some(old) => Posting {
                        velocity: Velocity {
                            pan: velocity.pan.or(old.velocity.pan),
                            tilt: velocity.tilt.or(old.velocity.tilt),
                            zoom: velocity.zoom.or(old.velocity.zoom),
                        },
                        replies: join(old.replies, vec![replier], &mut done),
                    },
                });
            }
        }
        for r in done {
            r.send(&visca::completion());
        }
        self.wake.notify_one();
    }

    /// Posts the slots' drives and stops to `session` as they come, each
    /// drive for `lease`, until the task is aborted.
    pub async fn run(self: Arc<Self>, session: Arc<GimbalSession>, lease: Duration, stats: Arc<Stats>) {
        let (mut drive, mut stop): (Under, Under) = (None, None);
        async fn outcome(u: &mut Under) -> Result<(), CommandError> {
            match u {
                Some((rx, _)) => rx
                    .await
                    .unwrap_or_else(|_| Err(CommandError::Io("the gimbal's session ended".into()))),
                None => std::future::pending().await,
            }
        }
        loop {
            tokio::select! {
                () = self.wake.notified() => {}
                r = outcome(&mut stop), if stop.is_some() => finish(stop.take(), r, &session, &stats),
                r = outcome(&mut drive), if drive.is_some() => finish(drive.take(), r, &session, &stats),
            }
            let (next_stop, next_drive) = {
                let mut s = self.slot.lock().unwrap_or_else(PoisonError::into_inner);
                (
                    if stop.is_none() { s.stop.take() } else { None },
                    if drive.is_none() { s.drive.take() } else { None },
                )
            };
            for (posting, under) in [(next_stop, &mut stop), (next_drive, &mut drive)] {
                let Some(p) = posting else { continue };
                let user = p.replies.last().and_then(|r| r.user.clone());
                let rx = session
                    .acting_for(user.as_deref())
                    .post_velocity(p.velocity, Some(lease), "visca");
                *under = Some((rx, p.replies));
            }
        }
    }
}

fn finish(under: Under, r: Result<(), CommandError>, session: &GimbalSession, stats: &Stats) {
    let Some((_, replies)) = under else { return };
    match r {
        Ok(()) => replies.iter().for_each(|c| c.send(&visca::completion())),
        Err(e) => {
            let total = Stats::count(&stats.not_executed);
            let peer = replies.last().map_or_else(|| "-".to_owned(), |r| r.peer.to_string());
            if may_warn("drive not executed", &session.config.name) {
                // gcud's decision (another controller, a limit): routine, in words.
                info!(gimbal = %session.config.name, from = %peer, total, reason = %e, "drive not executed: answered 90 61 41 FF");
            }
            replies.iter().for_each(|c| c.send(&visca::not_executable()));
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::reply::Out;
    use sagebrush_protocol::{LensSpeed, Speed};
    use tokio::sync::mpsc;

    fn client(tx: &mpsc::Sender<Vec<u8>>) -> Replier {
        Replier {
            to: Out::Tcp(tx.clone()),
            peer: "127.0.0.1:1".parse().unwrap(),
            user: None,
        }
    }

    fn pan(d: Drive<Speed>) -> Velocity {
        Velocity {
            pan: Some(d),
            tilt: Some(Drive::Stop),
            zoom: None,
        }
    }

    fn fast() -> Speed {
        Speed::new(9).unwrap()
    }

    #[test]
    fn a_stop_overtakes_the_drives_waiting_and_answers_their_clients() {
        let desk = Desk::default();
        let (tx, _rx) = mpsc::channel(64);
        desk.post(pan(Drive::Back(fast())), client(&tx));
        desk.post(pan(Drive::Forward(fast())), client(&tx));
        desk.post(pan(Drive::Stop), client(&tx));
        let s = desk.slot.lock().unwrap();
        assert!(s.drive.is_none(), "a drive still waits behind the stop: {:?}", s.drive);
        let stop = s.stop.as_ref().expect("the stop waits to be posted");
        assert_eq!(stop.velocity.pan, Some(Drive::Stop));
        assert_eq!(stop.replies.len(), 3, "the drives' clients hear the stop's outcome");
    }

    #[test]
    fn newest_drive_wins_and_the_clients_waiting_are_bounded() {
        let desk = Desk::default();
        let (tx, mut rx) = mpsc::channel(256);
        for i in 0..100u8 {
            desk.post(pan(Drive::Back(Speed::new(i % 16).unwrap())), client(&tx));
        }
        let s = desk.slot.lock().unwrap();
        let d = s.drive.as_ref().expect("one drive waits");
        assert_eq!(d.velocity.pan, Some(Drive::Back(Speed::new(99 % 16).unwrap())));
        assert_eq!(d.replies.len(), WAITING);
        let mut completions = 0;
        while let Ok(m) = rx.try_recv() {
            assert_eq!(m, visca::completion());
            completions += 1;
        }
        assert_eq!(
            completions,
            100 - WAITING,
            "the superseded beyond the bound are answered Completion"
        );
    }

    #[test]
    fn a_zoom_stop_leaves_a_pan_drive_waiting() {
        let desk = Desk::default();
        let (tx, _rx) = mpsc::channel(64);
        desk.post(pan(Drive::Back(fast())), client(&tx));
        let zoom = Velocity {
            zoom: Some(Drive::Forward(LensSpeed::new(3).unwrap())),
            ..Velocity::default()
        };
        desk.post(zoom, client(&tx));
        desk.post(
            Velocity {
                zoom: Some(Drive::Stop),
                ..Velocity::default()
            },
            client(&tx),
        );
        let s = desk.slot.lock().unwrap();
        // The zoom drive joined the pan drive; the zoom stop ended the zoom alone.
        let d = s.drive.as_ref().expect("the pan drive still waits");
        assert_eq!((d.velocity.pan, d.velocity.zoom), (Some(Drive::Back(fast())), None));
        assert_eq!(s.stop.as_ref().unwrap().velocity.zoom, Some(Drive::Stop));
    }
}
