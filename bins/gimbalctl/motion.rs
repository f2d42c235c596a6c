//! `--wait`: where a positioning command aims, and polling until the
//! motion ends there (exit 0), somewhere else ("stopped short", exit 20),
//! or not within `--wait-timeout` (exit 21).

use std::time::Duration;

use sagebrush_protocol::{Command, LensPosition, Position, Reply};
use serde_json::{Value, json};

use crate::error::CtlError;
use crate::output::{position_json, position_text};
use crate::session::Session;

/// Poll interval.
const POLL: Duration = Duration::from_millis(100);
/// Equal readings in a row that mean "stopped" away from the target (a
/// motion that has not started yet, or accelerates slowly, is not stopped
/// after one equal pair).
const STILL_READINGS: u32 = 3;

/// Where a motion aims.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Target {
    Mount(Position),
    Lens(LensPosition),
}

/// How a wait ended well.
#[derive(Debug)]
pub struct Arrived {
    target: Target,
    at: Target,
    waited: Duration,
}

fn target_json(t: &Target) -> Value {
    match t {
        Target::Mount(p) => position_json(p),
        Target::Lens(l) => json!({ "zoom": l.zoom.get(), "focus": l.focus.get() }),
    }
}

fn target_text(t: &Target) -> String {
    match t {
        Target::Mount(p) => position_text(p).trim().to_string(),
        Target::Lens(l) => format!("zoom {}  focus {}", l.zoom.get(), l.focus.get()),
    }
}

impl Arrived {
    pub fn json(&self) -> Value {
        json!({
            "reached": true,
            "target": target_json(&self.target),
            "final": target_json(&self.at),
            "waited_ms": self.waited.as_millis() as u64,
        })
    }

    pub fn text(&self) -> String {
        format!("arrived at {}", target_text(&self.at))
    }
}

fn expect_position(command: &Command<'_>, payload: &[u8]) -> Result<Position, CtlError> {
    Ok(sagebrush_client::client::expect_position(command, payload)?)
}

/// The target of a positioning command; a preset's is asked (P?nn) first.
pub async fn target(session: &mut Session, command: &Command<'_>) -> Result<Target, CtlError> {
    match command {
        Command::GoTo(p) => Ok(Target::Mount(*p)),
        Command::Home => Ok(Target::Mount(Position::default())),
        Command::LensGoTo(l) => Ok(Target::Lens(*l)),
        Command::GoToPreset(n) => {
            let query = Command::QueryPreset(*n);
            let p = session.query(&query).await?;
            Ok(Target::Mount(expect_position(&query, &p)?))
        }
        other => Err(CtlError::Usage(format!(
            "--wait does not apply to {}",
            other.mnemonic()
        ))),
    }
}

async fn read(session: &mut Session, target: &Target) -> Result<Target, CtlError> {
    match target {
        Target::Mount(_) => {
            let p = session.query(&Command::QueryPosition).await?;
            Ok(Target::Mount(expect_position(&Command::QueryPosition, &p)?))
        }
        Target::Lens(_) => {
            let p = session.query(&Command::QueryLens).await?;
            match Reply::parse(&Command::QueryLens, &p) {
                Ok(Reply::Lens(l)) => Ok(Target::Lens(l)),
                _ => Err(CtlError::BadReply(format!(
                    "V? result {:?} is not a Table 17 lens position",
                    String::from_utf8_lossy(&p)
                ))),
            }
        }
    }
}

/// Polls until the reading equals `target`, or stays put elsewhere for
/// [`STILL_READINGS`] polls (stopped short), or `timeout` runs out.
pub async fn wait(session: &mut Session, target: Target, timeout: Duration) -> Result<Arrived, CtlError> {
    let started = tokio::time::Instant::now();
    let deadline = started + timeout;
    let mut last: Option<Target> = None;
    let mut still = 0u32;
    loop {
        let now = read(session, &target).await?;
        if now == target {
            return Ok(Arrived {
                target,
                at: now,
                waited: started.elapsed(),
            });
        }
        still = if last == Some(now) { still + 1 } else { 0 };
        let detail = |reached: bool| {
            json!({
                "reached": reached,
                "target": target_json(&target),
                "final": target_json(&now),
                "waited_ms": started.elapsed().as_millis() as u64,
            })
        };
        if still + 1 >= STILL_READINGS {
            return Err(CtlError::StoppedShort(
                format!(
                    "stopped short at {} (target {}): software limits, travel, or another command?",
                    target_text(&now),
                    target_text(&target)
                ),
                detail(false),
            ));
        }
        if tokio::time::Instant::now() >= deadline {
            return Err(CtlError::WaitTimeout(
                format!(
                    "still moving after --wait-timeout {} ms, at {} (target {})",
                    timeout.as_millis(),
                    target_text(&now),
                    target_text(&target)
                ),
                detail(false),
            ));
        }
        last = Some(now);
        tokio::time::sleep(POLL).await;
    }
}
