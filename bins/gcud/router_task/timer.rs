//! The run loop's one timer: the router core's next deadline
//! (`Router::next_deadline`) or a held ACK's (`Lines::next_held_ack`),
//! whichever comes first, kept armed across the loop's turns instead of
//! made anew on each.
//!
//! Arming a tokio timer earlier than the runtime last planned to wake costs
//! a wake-up of its own (an eventfd write and one more turn of the loop).
//! A routed command arms its ACK time-out, and the answer that follows
//! moves the deadline later again; re-arming at every turn paid that
//! wake-up for every transaction. This timer is only moved earlier; when
//! the deadline moved later it fires early once, a tick that finds nothing
//! due (the router takes any input as a tick), and is armed again at the
//! deadline then in force.

use std::future::Future;
use std::pin::Pin;
use std::task::{Context, Poll};

use tokio::time::{Instant, Sleep};

/// The timer and the instant it is armed at, if armed.
#[derive(Debug)]
pub(super) struct RouterTimer {
    sleep: Pin<Box<Sleep>>,
    armed: Option<Instant>,
}

impl RouterTimer {
    pub fn new() -> Self {
        Self {
            sleep: Box::pin(tokio::time::sleep_until(Instant::now())),
            armed: None,
        }
    }

    /// Arms the timer for `deadline` unless it already fires no later.
    pub fn arm(&mut self, deadline: Option<Instant>) {
        let Some(at) = deadline else { return };
        if self.armed.is_none_or(|armed| at < armed) {
            self.sleep.as_mut().reset(at);
            self.armed = Some(at);
        }
    }

    /// Resolves when the armed time comes (disarming it); never while unarmed.
    pub fn poll_fired(&mut self, cx: &mut Context<'_>) -> Poll<()> {
        if self.armed.is_none() {
            return Poll::Pending;
        }
        let fired = self.sleep.as_mut().poll(cx);
        if fired.is_ready() {
            self.armed = None;
        }
        fired
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::time::Duration;

    async fn fired(timer: &mut RouterTimer) {
        std::future::poll_fn(|cx| timer.poll_fired(cx)).await
    }

    #[tokio::test(start_paused = true)]
    async fn fires_at_the_earliest_deadline_armed_and_only_once() {
        let start = Instant::now();
        let mut timer = RouterTimer::new();
        timer.arm(Some(start + Duration::from_millis(30)));
        timer.arm(Some(start + Duration::from_millis(10)));
        timer.arm(Some(start + Duration::from_millis(20)));
        timer.arm(None);
        fired(&mut timer).await;
        assert_eq!(
            Instant::now() - start,
            Duration::from_millis(10),
            "the earliest deadline"
        );
        let unarmed = tokio::time::timeout(Duration::from_secs(60), fired(&mut timer)).await;
        assert!(unarmed.is_err(), "fired once, then unarmed until armed again");
        timer.arm(Some(Instant::now() + Duration::from_millis(5)));
        let armed_at = Instant::now();
        fired(&mut timer).await;
        assert_eq!(Instant::now() - armed_at, Duration::from_millis(5), "armed again");
    }
}
