//! Who may hold an accepted connection (ARCHITECTURE "Safety": no client can
//! lock others out; state bounded by what is live). One table per program,
//! shared by all its listeners (gcud's client links, every gimbal's ONVIF
//! device):
//!
//! - a total cap ([`Limits::max_total`]): when it is reached, the
//!   connection idle the longest is evicted for the newcomer (one idle for
//!   at least [`MIN_IDLE_TO_EVICT`]); only when every connection is busy is
//!   the newcomer refused;
//! - a share per listener: of the listeners holding connections (and the
//!   newcomer's), each keeps a reserve (`reserve`) the others may not take, so
//!   a listener may hold at most the total less the others' reserves; a
//!   newcomer on a listener at its share takes its own listener's idlest
//!   slot or is refused, and one on a listener below its reserve, the
//!   total full and nothing idle, evicts the longest-quiet connection of a
//!   listener over its share, busy or not (gcud: 32 connections to the
//!   clients' listener, each sending a stray byte every 0.4 s, refused
//!   every operator; issue 49);
//! - a per-peer cap ([`Limits::max_per_peer`]): a newcomer from a peer at
//!   its cap is refused; with [`Limits::cap_loopback`] false it applies to
//!   peers off this machine only (gcud's default: every local client is the
//!   same loopback peer);
//! - an idle time-out ([`Limits::idle_timeout`]): a connection on which
//!   nothing moved for that long is closed ([`Admitted::ended`] says so);
//! - refusals and evictions are counted exactly and logged at most once a
//!   minute per peer (a flood of attempts is one line).

use std::collections::HashMap;
use std::net::IpAddr;
use std::pin::Pin;
use std::sync::{Arc, Mutex, PoisonError};
use std::task::{Context, Poll};
use std::time::Duration;

use tokio::io::{AsyncRead, AsyncWrite, ReadBuf};
use tokio::sync::Notify;
use tokio::time::Instant;

/// A connection idle for less than this is never evicted (it is in use).
pub const MIN_IDLE_TO_EVICT: Duration = Duration::from_secs(1);
/// A peer's refusals and evictions are logged at most this often.
const LOG_EVERY: Duration = Duration::from_secs(60);
/// Peers remembered for log throttling, at most.
const LOGGED_PEERS: usize = 1024;

/// The limits (gcud's `[limits]`, gimbal-onvif's `[http]`).
#[derive(Debug, Clone, Copy)]
pub struct Limits {
    pub max_total: usize,
    pub max_per_peer: usize,
    /// Whether the per-peer cap applies to loopback peers too (they are all
    /// "this machine": by default only peers off it are capped).
    pub cap_loopback: bool,
    pub idle_timeout: Duration,
}

/// Counters for the metrics.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct AdmissionStats {
    pub open: u64,
    pub accepted: u64,
    pub refused_total_cap: u64,
    pub refused_peer_cap: u64,
    pub refused_not_allowed: u64,
    pub evicted: u64,
    pub idle_closed: u64,
}

#[derive(Debug)]
struct Conn {
    peer: IpAddr,
    /// The listener that accepted it (a program with one listener: 0).
    listener: u64,
    last_active: Instant,
    close: Arc<Notify>,
}

#[derive(Debug, Default)]
struct Table {
    open: HashMap<u64, Conn>,
    next: u64,
    stats: AdmissionStats,
    logged: HashMap<IpAddr, Instant>,
}

/// What happened to a newcomer.
#[derive(Debug)]
pub enum Admission {
    /// Admitted as connection `key`; `close` is notified when it must close
    /// (evicted). `evicted`: the peer of a connection evicted for it.
    Admitted {
        key: u64,
        close: Arc<Notify>,
        evicted: Option<IpAddr>,
    },
    /// Refused; `log`: whether this refusal should be logged (once a minute per peer).
    Refused { why: &'static str, log: bool },
}

/// The table shared by every listener.
#[derive(Debug)]
pub struct Connections {
    limits: Limits,
    table: Mutex<Table>,
}

impl Connections {
    pub fn new(limits: Limits) -> Arc<Self> {
        Arc::new(Self {
            limits,
            table: Mutex::new(Table::default()),
        })
    }

    fn table(&self) -> std::sync::MutexGuard<'_, Table> {
        self.table.lock().unwrap_or_else(PoisonError::into_inner)
    }

    /// A newcomer from `peer` at `now` (a program with one listener).
    pub fn admit(&self, peer: IpAddr, now: Instant) -> Admission {
        self.admit_on(0, peer, now)
    }

    /// A newcomer from `peer` on `listener` at `now`.
    pub fn admit_on(&self, listener: u64, peer: IpAddr, now: Instant) -> Admission {
        let mut t = self.table();
        let of_peer = t.open.values().filter(|c| c.peer == peer).count();
        let capped = self.limits.cap_loopback || !peer.is_loopback();
        if capped && of_peer >= self.limits.max_per_peer {
            t.stats.refused_peer_cap += 1;
            let log = should_log(&mut t, peer, now);
            return Admission::Refused {
                why: "limits.max_connections_per_peer reached",
                log,
            };
        }
        let mut evicted = None;
        let total = self.limits.max_total;
        let (held, share) = shares(&t, total, listener);
        let mine = held.get(&listener).copied().unwrap_or(0);
        // (One listener alone: its share is the whole table.)
        let at_share = held.len() > 1 && mine >= share;
        if at_share || t.open.len() >= total {
            let idle_enough = |c: &Conn| now.duration_since(c.last_active) >= MIN_IDLE_TO_EVICT;
            let idlest = |pick: &dyn Fn(&Conn) -> bool| {
                t.open
                    .iter()
                    .filter(|(_, c)| pick(c))
                    .min_by_key(|(_, c)| c.last_active)
                    .map(|(&k, _)| k)
            };
            // At its share: its own listener's idlest slot only; else the
            // idlest anywhere, or, below its reserve, the longest-quiet slot
            // of a listener over its share.
            let over_share = |c: &Conn| held.get(&c.listener).is_some_and(|&n| n > share);
            let starved = mine < reserve(total, held.len());
            let victim = match at_share {
                true => idlest(&|c| c.listener == listener && idle_enough(c)),
                false => idlest(&idle_enough).or_else(|| starved.then(|| idlest(&over_share)).flatten()),
            };
            if victim.is_none() && at_share {
                t.stats.refused_total_cap += 1;
                let log = should_log(&mut t, peer, now);
                return Admission::Refused {
                    why: "this listener's share of limits.max_connections reached and its connections are busy",
                    log,
                };
            }
            match victim.and_then(|k| t.open.remove(&k)) {
                Some(victim) => {
                    victim.close.notify_one();
                    t.stats.evicted += 1;
                    evicted = Some(victim.peer);
                }
                None => {
                    t.stats.refused_total_cap += 1;
                    let log = should_log(&mut t, peer, now);
                    return Admission::Refused {
                        why: "limits.max_connections reached and every connection is busy",
                        log,
                    };
                }
            }
        }
        let key = t.next;
        t.next += 1;
        let close = Arc::new(Notify::new());
        let conn = Conn {
            peer,
            listener,
            last_active: now,
            close: close.clone(),
        };
        t.open.insert(key, conn);
        t.stats.accepted += 1;
        let evicted = evicted.filter(|&victim| should_log(&mut t, victim, now));
        Admission::Admitted { key, close, evicted }
    }

    /// A peer outside the listener's `allow_peers` was refused; whether to log it.
    pub fn refuse_unlisted(&self, peer: IpAddr, now: Instant) -> bool {
        let mut t = self.table();
        t.stats.refused_not_allowed += 1;
        should_log(&mut t, peer, now)
    }

    /// Connection `key` received bytes at `now`.
    pub fn touch(&self, key: u64, now: Instant) {
        if let Some(c) = self.table().open.get_mut(&key) {
            c.last_active = now;
        }
    }

    /// When connection `key` falls idle, if it is still open.
    pub fn idle_at(&self, key: u64) -> Option<Instant> {
        self.table()
            .open
            .get(&key)
            .map(|c| c.last_active + self.limits.idle_timeout)
    }

    /// Connection `key` closed; `idle`: because of the idle time-out.
    pub fn left(&self, key: u64, idle: bool) {
        let mut t = self.table();
        t.open.remove(&key);
        if idle {
            t.stats.idle_closed += 1;
        }
    }

    pub fn stats(&self) -> AdmissionStats {
        let t = self.table();
        AdmissionStats {
            open: t.open.len() as u64,
            ..t.stats
        }
    }
}

/// The slots each listener keeps from the others, of `total`, with
/// `listeners` holding connections: a quarter of an even split, at least one.
fn reserve(total: usize, listeners: usize) -> usize {
    (total / (4 * listeners.max(1))).max(1)
}

/// The most one of `listeners` listeners may hold of `total`: the total less
/// the others' reserves (at least its own reserve).
fn share_of(total: usize, listeners: usize) -> usize {
    let r = reserve(total, listeners);
    total.saturating_sub(r * listeners.saturating_sub(1)).max(r)
}

/// Connections held per listener (the newcomer's `listener` counted among
/// them), and the share each may hold.
fn shares(t: &Table, total: usize, listener: u64) -> (HashMap<u64, usize>, usize) {
    let mut held: HashMap<u64, usize> = HashMap::new();
    held.insert(listener, 0);
    for c in t.open.values() {
        *held.entry(c.listener).or_default() += 1;
    }
    let share = share_of(total, held.len());
    (held, share)
}

/// Why an admitted connection must close.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Ending {
    /// Evicted for a newcomer at the total cap (it was the longest idle).
    Evicted,
    /// Nothing moved on it for the idle time-out.
    Idle,
}

impl Ending {
    /// The reason in words, naming the limit.
    pub fn reason(self) -> &'static str {
        match self {
            Self::Evicted => {
                "evicted for a newcomer at the connection cap (idle the longest, or the quietest of a listener over its share)"
            }
            Self::Idle => "idle (nothing moved for the idle time-out)",
        }
    }
}

/// An admitted connection's place in the table. It leaves the table when
/// dropped, however the connection ends (its task aborted included).
#[derive(Debug)]
pub struct Admitted {
    table: Arc<Connections>,
    key: u64,
    close: Arc<Notify>,
    /// Closed for its idle time-out.
    idle: bool,
}

impl Admitted {
    /// Admits a newcomer from `peer` into `table` now: the guard, and the
    /// peer of a connection evicted for it (when that eviction should be
    /// logged); or why it is refused and whether to log that.
    pub fn admit(table: &Arc<Connections>, peer: IpAddr) -> Result<(Self, Option<IpAddr>), (&'static str, bool)> {
        Self::admit_on(table, 0, peer)
    }

    /// As [`Admitted::admit`], on `listener` of a program with several
    /// (each keeps its share of the table, module documentation).
    pub fn admit_on(
        table: &Arc<Connections>,
        listener: u64,
        peer: IpAddr,
    ) -> Result<(Self, Option<IpAddr>), (&'static str, bool)> {
        match table.admit_on(listener, peer, Instant::now()) {
            Admission::Admitted { key, close, evicted } => Ok((
                Self {
                    table: Arc::clone(table),
                    key,
                    close,
                    idle: false,
                },
                evicted,
            )),
            Admission::Refused { why, log } => Err((why, log)),
        }
    }

    /// The table and this connection's key in it (to [`Connections::touch`]).
    pub fn entry(&self) -> (Arc<Connections>, u64) {
        (Arc::clone(&self.table), self.key)
    }

    /// Something moved on the connection now.
    pub fn touch(&self) {
        self.table.touch(self.key, Instant::now());
    }

    /// Resolves when the connection must close: evicted, or idle for the
    /// time-out (counted as such when the guard is dropped).
    pub async fn ended(&mut self) -> Ending {
        loop {
            let Some(at) = self.table.idle_at(self.key) else {
                return Ending::Evicted;
            };
            tokio::select! {
                () = self.close.notified() => return Ending::Evicted,
                () = tokio::time::sleep_until(at) => {
                    if self.table.idle_at(self.key).is_some_and(|at| at <= Instant::now()) {
                        self.idle = true;
                        return Ending::Idle;
                    }
                }
            }
        }
    }

    /// `stream`, touching this connection's entry whenever bytes move
    /// either way (so that only a connection where nothing moves is idle).
    pub fn track<S>(&self, stream: S) -> Tracked<S> {
        Tracked {
            inner: stream,
            table: Arc::clone(&self.table),
            key: self.key,
        }
    }
}

impl Drop for Admitted {
    fn drop(&mut self) {
        self.table.left(self.key, self.idle);
    }
}

pin_project_lite::pin_project! {
    /// A stream that touches its admission entry on every read and write
    /// that moved bytes ([`Admitted::track`]).
    #[derive(Debug)]
    pub struct Tracked<S> {
        #[pin]
        inner: S,
        table: Arc<Connections>,
        key: u64,
    }
}

impl<S: AsyncRead> AsyncRead for Tracked<S> {
    fn poll_read(self: Pin<&mut Self>, cx: &mut Context<'_>, buf: &mut ReadBuf<'_>) -> Poll<std::io::Result<()>> {
        let this = self.project();
        let before = buf.filled().len();
        let read = this.inner.poll_read(cx, buf);
        if matches!(read, Poll::Ready(Ok(()))) && buf.filled().len() > before {
            this.table.touch(*this.key, Instant::now());
        }
        read
    }
}

impl<S: AsyncWrite> AsyncWrite for Tracked<S> {
    fn poll_write(self: Pin<&mut Self>, cx: &mut Context<'_>, data: &[u8]) -> Poll<std::io::Result<usize>> {
        let this = self.project();
        let written = this.inner.poll_write(cx, data);
        if matches!(written, Poll::Ready(Ok(n)) if n > 0) {
            this.table.touch(*this.key, Instant::now());
        }
        written
    }

    fn poll_write_vectored(
        self: Pin<&mut Self>,
        cx: &mut Context<'_>,
        bufs: &[std::io::IoSlice<'_>],
    ) -> Poll<std::io::Result<usize>> {
        let this = self.project();
        let written = this.inner.poll_write_vectored(cx, bufs);
        if matches!(written, Poll::Ready(Ok(n)) if n > 0) {
            this.table.touch(*this.key, Instant::now());
        }
        written
    }

    fn is_write_vectored(&self) -> bool {
        self.inner.is_write_vectored()
    }

    fn poll_flush(self: Pin<&mut Self>, cx: &mut Context<'_>) -> Poll<std::io::Result<()>> {
        self.project().inner.poll_flush(cx)
    }

    fn poll_shutdown(self: Pin<&mut Self>, cx: &mut Context<'_>) -> Poll<std::io::Result<()>> {
        self.project().inner.poll_shutdown(cx)
    }
}

/// Whether to log about `peer` now (at most once per [`LOG_EVERY`]).
fn should_log(t: &mut Table, peer: IpAddr, now: Instant) -> bool {
    if t.logged.len() >= LOGGED_PEERS {
        t.logged.retain(|_, at| now.duration_since(*at) < LOG_EVERY);
    }
    match t.logged.get(&peer) {
        Some(at) if now.duration_since(*at) < LOG_EVERY => false,
        _ => {
            if t.logged.len() < LOGGED_PEERS {
                t.logged.insert(peer, now);
            }
            true
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn table(max_total: usize, max_per_peer: usize) -> Arc<Connections> {
        Connections::new(Limits {
            max_total,
            max_per_peer,
            cap_loopback: true,
            idle_timeout: Duration::from_secs(300),
        })
    }

    fn ip(last: u8) -> IpAddr {
        IpAddr::from([127, 0, 0, last])
    }

    #[tokio::test]
    async fn the_longest_idle_is_evicted_for_a_newcomer_busy_ones_never() {
        let c = table(2, 8);
        let t0 = Instant::now();
        let Admission::Admitted { key: a, close, .. } = c.admit(ip(1), t0) else {
            panic!()
        };
        let Admission::Admitted { key: b, .. } = c.admit(ip(2), t0) else {
            panic!()
        };
        // Both busy (just active): the newcomer is refused.
        assert!(matches!(c.admit(ip(3), t0), Admission::Refused { log: true, .. }));
        // b stays active, a falls idle: a goes.
        let later = t0 + Duration::from_secs(5);
        c.touch(b, later);
        let Admission::Admitted { evicted, .. } = c.admit(ip(3), later) else {
            panic!("the idle one makes room")
        };
        assert_eq!(evicted, Some(ip(1)));
        assert!(c.idle_at(a).is_none());
        // The evicted task is told (notify_one stores a permit).
        close.notified().await;
        let s = c.stats();
        assert_eq!((s.open, s.evicted, s.refused_total_cap), (2, 1, 1));
    }

    #[tokio::test]
    async fn one_listeners_busy_connections_never_take_another_listeners_reserve() {
        let c = table(8, 8);
        let t0 = Instant::now();
        // Alone, a listener may fill the table (every connection busy).
        for i in 0..8 {
            assert!(matches!(c.admit_on(1, ip(i), t0), Admission::Admitted { .. }), "{i}");
        }
        // A newcomer on another listener: one of the first's busy ones goes.
        let Admission::Admitted { evicted, .. } = c.admit_on(2, ip(100), t0) else {
            panic!("the other listener's reserve")
        };
        assert!(evicted.is_some_and(|p| p != ip(100)));
        // The first is at its share now (8 less the other's reserve of 1):
        // refused while its connections are busy, not taken from the other.
        assert!(matches!(c.admit_on(1, ip(50), t0), Admission::Refused { .. }));
        // Its idle one makes room for its own newcomer only.
        let later = t0 + Duration::from_secs(5);
        let Admission::Admitted { evicted, .. } = c.admit_on(1, ip(51), later) else {
            panic!("its own idlest")
        };
        assert!(evicted.is_some_and(|p| p != ip(100)), "{evicted:?}");
        let s = c.stats();
        assert_eq!((s.open, s.evicted, s.refused_total_cap), (8, 2, 1));
    }

    #[tokio::test]
    async fn a_peer_at_its_cap_is_refused_and_logged_once_a_minute() {
        let c = table(10, 2);
        let t0 = Instant::now();
        for _ in 0..2 {
            assert!(matches!(c.admit(ip(1), t0), Admission::Admitted { .. }));
        }
        let logs: Vec<bool> = (0..5)
            .map(|_| match c.admit(ip(1), t0) {
                Admission::Refused { log, .. } => log,
                Admission::Admitted { .. } => panic!("over the per-peer cap"),
            })
            .collect();
        assert_eq!(logs, vec![true, false, false, false, false]);
        assert!(
            matches!(c.admit(ip(2), t0), Admission::Admitted { .. }),
            "others are not affected"
        );
        assert!(matches!(
            c.admit(ip(1), t0 + LOG_EVERY),
            Admission::Refused { log: true, .. }
        ));
        assert_eq!(c.stats().refused_peer_cap, 6);
    }

    #[tokio::test(start_paused = true)]
    async fn a_guard_ends_idle_unless_bytes_move_and_leaves_the_table_when_dropped() {
        let c = Connections::new(Limits {
            max_total: 4,
            max_per_peer: 4,
            cap_loopback: true,
            idle_timeout: Duration::from_secs(10),
        });
        let (mut a, _) = Admitted::admit(&c, ip(1)).unwrap();
        let (client, server) = tokio::io::duplex(64);
        let mut tracked = a.track(server);
        tokio::time::sleep(Duration::from_secs(8)).await;
        let mut client = client;
        tokio::io::AsyncWriteExt::write_all(&mut client, b"x").await.unwrap();
        let mut byte = [0u8; 1];
        tokio::io::AsyncReadExt::read_exact(&mut tracked, &mut byte)
            .await
            .unwrap();
        let started = Instant::now();
        assert_eq!(a.ended().await, Ending::Idle);
        assert_eq!(started.elapsed(), Duration::from_secs(10), "counted from the last byte");
        drop(a);
        let s = c.stats();
        assert_eq!((s.open, s.idle_closed), (0, 1));
    }
}
