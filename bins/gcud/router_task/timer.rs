//! The run loop's one timer: the router core's next deadline
//! (`Router::next_deadline`) or a held ACK's (`Lines::next_held_ack`),
//! whichever comes first, following it earlier and later.
//!
//! What a timer costs in tokio (1.54, `runtime/time`): registering one
//! earlier than the driver planned to wake when it last parked
//! (`Inner::next_wake`) unparks the driver, even from the runtime's own
//! thread: an eventfd write and one more turn. A `Sleep::reset` later only
//! marks the entry (`StateCell::extend_expiration`): it stays in the
//! wheel's slot of the earlier instant, and the driver still wakes then
//! (an `epoll_wait` that returns nothing) to file it again. So a moved
//! deadline gets a timer made anew in place (`Pin::set`, no allocation:
//! the old entry leaves the wheel, the new one registers when the loop
//! polls it): later, it is past the driver's plan and costs nothing; the
//! driver computes its next wake from the wheel at every park.
//!
//! On paced serial lines every answer moves the core's deadline later (a
//! port's result came; its next command's ACK time-out is the next one
//! due). Armed only earlier, the timer fired at the stale instant, a tick
//! with nothing due, and re-arming it after that tick paid the unpark;
//! extended, the driver woke at the stale instant. Made anew, neither.

use std::future::Future;
use std::pin::Pin;
use std::task::{Context, Poll};
use std::time::Duration;

use tokio::time::{Instant, Sleep};

/// How far out the timer is moved while the core has no deadline.
const PARKED: Duration = Duration::from_secs(24 * 3600);

/// The timer and the instant it is armed at, if armed.
#[derive(Debug)]
pub(super) struct RouterTimer {
    sleep: Pin<Box<Sleep>>,
    armed: Option<Instant>,
}

impl RouterTimer {
    pub fn new() -> Self {
        Self {
            sleep: Box::pin(tokio::time::sleep_until(Instant::now() + PARKED)),
            armed: None,
        }
    }

    /// Arms the timer for `deadline`, earlier or later than it was; with no
    /// deadline, disarms it.
    pub fn arm(&mut self, deadline: Option<Instant>) {
        if deadline == self.armed {
            return;
        }
        match deadline {
            Some(at) => self.sleep.set(tokio::time::sleep_until(at)),
            // Armed and waiting: moved out of the way (a mark, no wake-up);
            // once fired it stays so, never polled while disarmed.
            None => self.sleep.as_mut().reset(Instant::now() + PARKED),
        }
        self.armed = deadline;
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

    /// Waits for the timer to fire: when, since `start`, and how many times
    /// the task was polled on the way (a wake with nothing due is one more).
    async fn fired(timer: &mut RouterTimer, start: Instant) -> (Duration, u32) {
        let mut polls = 0;
        std::future::poll_fn(|cx| {
            polls += 1;
            timer.poll_fired(cx)
        })
        .await;
        (Instant::now() - start, polls)
    }

    fn ms(n: u64) -> Duration {
        Duration::from_millis(n)
    }

    #[tokio::test(start_paused = true)]
    async fn fires_at_the_deadline_in_force_earlier_or_later_and_only_once() {
        let start = Instant::now();
        let mut timer = RouterTimer::new();
        timer.arm(Some(start + ms(10)));
        timer.arm(Some(start + ms(30)));
        assert_eq!(
            fired(&mut timer, start).await,
            (ms(30), 2),
            "moved later: fires then, no wake at the earlier instant"
        );
        let start = Instant::now();
        timer.arm(Some(start + ms(30)));
        timer.arm(Some(start + ms(10)));
        timer.arm(Some(start + ms(20)));
        assert_eq!(fired(&mut timer, start).await, (ms(20), 2), "the last deadline armed");
        let unarmed = tokio::time::timeout(Duration::from_secs(60), fired(&mut timer, start)).await;
        assert!(unarmed.is_err(), "fired once, then unarmed until armed again");
        let start = Instant::now();
        timer.arm(Some(start + ms(5)));
        timer.arm(None);
        let disarmed = tokio::time::timeout(Duration::from_secs(60), fired(&mut timer, start)).await;
        assert!(disarmed.is_err(), "disarmed: never fires");
        let start = Instant::now();
        timer.arm(Some(start + ms(5)));
        assert_eq!(fired(&mut timer, start).await, (ms(5), 2), "armed again");
    }
}
