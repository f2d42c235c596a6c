//! `[capture]` at run time (docs/capture.md): start-up and SIGUSR1 ask for
//! the capture to be toggled, and a task of its own carries the requests
//! out one after the other off the router task: reading the configuration
//! file, creating, rotating and opening the capture file, and waiting for
//! a stopped capture's writer all happen on a blocking thread, so that no
//! file or pipe I/O (a FIFO nobody reads, a stalled reader, a slow disk)
//! can hold up routing, the dead-man stops or `/healthz`. The router task
//! only taps bytes into the running capture's bounded queue.

use std::path::PathBuf;
use std::sync::Arc;
use std::time::Duration;

use sagebrush_host::capture::{Capture, CaptureStats, CaptureSwitch};
use tokio::sync::{mpsc, oneshot};
use tracing::{error, info, warn};

use crate::config::CaptureSettings;

/// How long a stopping capture's writer gets to write what is queued.
const STOP_WAIT: Duration = Duration::from_secs(2);
/// Requests waiting; a SIGUSR1 beyond them is refused with a warning.
const QUEUED: usize = 4;

enum Request {
    /// Stop the running capture, or start one from the configuration file
    /// as it reads now (`fallback`: the running settings).
    Toggle {
        file: PathBuf,
        fallback: Option<CaptureSettings>,
        why: &'static str,
        /// Told once the capture started (or could not).
        done: Option<oneshot::Sender<()>>,
    },
    /// Stop the running capture, if any, and say when its file is complete.
    Stop {
        why: &'static str,
        done: oneshot::Sender<()>,
    },
}

/// The handle the router task keeps: it sends requests, never waits for them.
#[derive(Debug, Clone)]
pub struct CaptureControl {
    requests: mpsc::Sender<Request>,
}

impl std::fmt::Debug for Request {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Request::Toggle { why, .. } => write!(f, "Toggle ({why})"),
            Request::Stop { why, .. } => write!(f, "Stop ({why})"),
        }
    }
}

impl CaptureControl {
    /// Spawns the task that carries out the requests for `switch`.
    pub fn spawn(switch: Arc<CaptureSwitch>) -> Self {
        let (requests, mut rx) = mpsc::channel::<Request>(QUEUED);
        tokio::spawn(async move {
            while let Some(request) = rx.recv().await {
                let switch = switch.clone();
                let done = tokio::task::spawn_blocking(move || match request {
                    Request::Toggle {
                        file,
                        fallback,
                        why,
                        done,
                    } => {
                        toggle(&switch, file, fallback, why);
                        done
                    }
                    Request::Stop { why, done } => {
                        if let Some(capture) = switch.stop() {
                            log_stop(&capture, why);
                        }
                        Some(done)
                    }
                })
                .await;
                if let Ok(Some(done)) = done {
                    let _ = done.send(());
                }
            }
        });
        Self { requests }
    }

    /// Starts a capture, or stops the running one (SIGUSR1). Returns at once.
    pub fn toggle(&self, config: &crate::config::Config, why: &'static str) {
        let request = Request::Toggle {
            file: config.file.clone(),
            fallback: config.capture.clone(),
            why,
            done: None,
        };
        if self.requests.try_send(request).is_err() {
            warn!("{why}: the capture is still busy with earlier requests; this one is ignored");
        }
    }

    /// `[capture] enabled`: starts the capture before the first line opens,
    /// so that it holds every byte; waits until the file is created (a FIFO
    /// is not opened yet: its writer waits for a reader, holding up nothing).
    pub async fn start(&self, config: &crate::config::Config) {
        let (done, started) = oneshot::channel();
        let request = Request::Toggle {
            file: config.file.clone(),
            fallback: config.capture.clone(),
            why: "start-up",
            done: Some(done),
        };
        if self.requests.send(request).await.is_ok() {
            let _ = started.await;
        }
    }

    /// Stops the running capture and waits (at most `STOP_WAIT` and a
    /// little) until its file is complete: gcud's last step on exit, after
    /// routing ended.
    pub async fn stop(&self, why: &'static str) {
        let (done, finished) = oneshot::channel();
        if self.requests.send(Request::Stop { why, done }).await.is_ok() {
            let _ = tokio::time::timeout(STOP_WAIT + Duration::from_secs(1), finished).await;
        }
    }
}

/// Stops the running capture (one that had stopped by itself, on a write
/// error or its budget, is replaced by a fresh one) or starts one with
/// `[capture]` as the file reads now. A capture that cannot start is one
/// error line; routing goes on. Runs on a blocking thread.
fn toggle(switch: &CaptureSwitch, file: PathBuf, fallback: Option<CaptureSettings>, why: &str) {
    if let Some(capture) = switch.stop() {
        let running = capture.is_active();
        log_stop(&capture, why);
        if running {
            return;
        }
    }
    let settings = match crate::reload::Reread::Capture.read(&file) {
        Some(now) => now.capture,
        None => fallback,
    };
    let Some(settings) = settings else {
        return warn!("{why}: no [capture] section in the configuration; nothing to capture to");
    };
    match Capture::open(&settings.file, settings.capture_config()) {
        Ok(capture) => {
            if capture.waits_for_reader() {
                info!(file = %settings.file.display(), "capture started (SIGUSR1 stops it); the FIFO has no reader yet: records wait for one");
            } else {
                info!(file = %settings.file.display(), "capture started (SIGUSR1 stops it)");
            }
            switch.start(capture);
        }
        Err(e) => {
            error!(file = %settings.file.display(), error = %e, "cannot start the capture; routing goes on without it")
        }
    }
}

/// Stops `capture`, waiting at most [`STOP_WAIT`] for its writer (a
/// stalled FIFO reader cannot hold this thread longer), and logs its counts.
fn log_stop(capture: &Capture, why: &str) {
    let stats: CaptureStats = capture.stop(STOP_WAIT);
    info!(
        file = %capture.path().display(),
        records = stats.records,
        bytes = stats.bytes_written,
        dropped = stats.dropped,
        "capture stopped ({why})"
    );
}
