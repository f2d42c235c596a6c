//! The live updates, `GET /api/events` (server-sent events): every
//! gimbal's state is rendered once per [`PUSH`] tick into one shared
//! snapshot (a `watch` channel: the text and its version), and only when
//! the text changed; each stream sends a snapshot only when its version
//! moved, and a keep-alive comment in between. 512 streams of a viewer
//! each re-rendered every gimbal every 100 ms whether or not anything
//! changed (1.2-1.7 CPU-seconds a second, 126 MB, up to 75 MB/s of
//! pushes; issue 49).
//!
//! Streams are bounded per user: at most `max_streams_per_user` at once,
//! and a user's new stream past it ends that user's oldest (with an
//! `ended` event saying why), never another user's.

use std::convert::Infallible;
use std::sync::{Arc, Mutex};
use std::time::Duration;

use axum::Router;
use axum::extract::State;
use axum::http::HeaderMap;
use axum::response::sse::{Event, KeepAlive, Sse};
use axum::response::{IntoResponse, Response};
use axum::routing::get;
use tokio::sync::{oneshot, watch};

use super::{Failure, Shared, Web, no_store};

/// The gimbals' state is rendered (and pushed if it changed) this often.
pub const PUSH: Duration = Duration::from_millis(100);
/// A stream's keep-alive comment comes at least this often when nothing
/// changes, and at least four times per idle time-out.
const KEEP_ALIVE_MAX: Duration = Duration::from_secs(15);

/// The snapshot every stream reads: the state's JSON text.
pub(super) type Snapshot = watch::Sender<Arc<str>>;

/// A new, empty snapshot.
pub(super) fn snapshot() -> Snapshot {
    watch::Sender::new(Arc::from(""))
}

/// Renders the state every [`PUSH`] into `w`'s snapshot, bumping its
/// version only when the text changed. Runs for ever.
pub(super) async fn render(w: Arc<Web>) {
    let mut tick = tokio::time::interval(PUSH);
    tick.set_missed_tick_behavior(tokio::time::MissedTickBehavior::Delay);
    loop {
        tick.tick().await;
        let text = w.state().to_string();
        w.snapshot.send_if_modified(|shown| {
            let changed = **shown != *text;
            if changed {
                *shown = Arc::from(text);
            }
            changed
        });
    }
}

/// One open stream, in opening order.
#[derive(Debug)]
struct Open {
    id: u64,
    user: String,
    /// Dropped to end the stream.
    _end: oneshot::Sender<()>,
}

/// The open streams, bounded per user.
#[derive(Debug)]
pub(super) struct Streams {
    per_user: usize,
    open: Mutex<(u64, Vec<Open>)>,
}

/// A stream's place among the open ones: removed when the stream ends.
#[derive(Debug)]
struct Ticket {
    streams: Arc<Streams>,
    id: u64,
}

impl Drop for Ticket {
    fn drop(&mut self) {
        let mut open = self.streams.open.lock().unwrap_or_else(|p| p.into_inner());
        open.1.retain(|o| o.id != self.id);
    }
}

impl Streams {
    pub(super) fn new(per_user: usize) -> Arc<Self> {
        Arc::new(Self {
            per_user: per_user.max(1),
            open: Mutex::new((0, Vec::new())),
        })
    }

    /// Opens a stream of `user`, ending that user's oldest ones past the
    /// cap; the receiver resolves when this one is ended so.
    fn open(self: &Arc<Self>, user: &str) -> (Ticket, oneshot::Receiver<()>) {
        let (end, ended) = oneshot::channel();
        let mut open = self.open.lock().unwrap_or_else(|p| p.into_inner());
        while open.1.iter().filter(|o| o.user == user).count() >= self.per_user {
            if let Some(oldest) = open.1.iter().position(|o| o.user == user) {
                open.1.remove(oldest);
            }
        }
        open.0 += 1;
        let id = open.0;
        open.1.push(Open {
            id,
            user: user.to_owned(),
            _end: end,
        });
        let ticket = Ticket {
            streams: Arc::clone(self),
            id,
        };
        (ticket, ended)
    }

    /// Streams open now (all users): the pages live.
    pub(super) fn len(&self) -> usize {
        self.open.lock().unwrap_or_else(|p| p.into_inner()).1.len()
    }
}

/// What a stream holds between two events.
struct Stream {
    shown: watch::Receiver<Arc<str>>,
    ended: oneshot::Receiver<()>,
    _ticket: Ticket,
    first: bool,
    done: bool,
}

/// The next event of a stream: the snapshot at once, then each new
/// version, until the stream is ended by a newer one of its user.
async fn next(mut s: Stream) -> Option<(Result<Event, Infallible>, Stream)> {
    if s.done {
        return None;
    }
    if !s.first {
        tokio::select! {
            _ = &mut s.ended => {
                s.done = true;
                let why = "ended: a newer page of the same user opened past max_streams_per_user";
                return Some((Ok(Event::default().event("ended").data(why)), s));
            }
            changed = s.shown.changed() => changed.ok()?,
        }
    }
    s.first = false;
    let text = Arc::clone(&s.shown.borrow_and_update());
    Some((Ok(Event::default().data(&*text)), s))
}

async fn events(State(w): Shared, headers: HeaderMap) -> Result<Response, Failure> {
    let who = w.who(&headers)?;
    let (ticket, ended) = w.streams.open(&who.user);
    let stream = Stream {
        shown: w.snapshot.subscribe(),
        ended,
        _ticket: ticket,
        first: true,
        done: false,
    };
    let keep_alive = (w.idle_timeout / 4).min(KEEP_ALIVE_MAX);
    let events = futures_util::stream::unfold(stream, next);
    let sse = Sse::new(events).keep_alive(KeepAlive::new().interval(keep_alive));
    Ok((no_store(), sse).into_response())
}

/// The route of the live updates.
pub(super) fn routes() -> Router<Arc<Web>> {
    Router::new().route("/api/events", get(events))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_users_new_stream_past_the_cap_ends_that_users_oldest_only() {
        let streams = Streams::new(2);
        let (admin, mut admin_ended) = streams.open("admin");
        let mut viewer: Vec<_> = (0..5).map(|_| streams.open("viewer")).collect();
        assert_eq!(streams.len(), 3, "the admin's and the viewer's newest two");
        assert!(
            admin_ended
                .try_recv()
                .is_err_and(|e| e == oneshot::error::TryRecvError::Empty)
        );
        let ended = |r: &mut oneshot::Receiver<()>| r.try_recv() == Err(oneshot::error::TryRecvError::Closed);
        assert!(
            viewer[..3].iter_mut().all(|(_, r)| ended(r)),
            "the viewer's oldest three"
        );
        assert!(viewer[3..].iter_mut().all(|(_, r)| !ended(r)));
        drop(viewer);
        drop(admin);
        assert_eq!(streams.len(), 0, "a stream that ends leaves");
    }
}
