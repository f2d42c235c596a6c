//! `gimbalctl watch`: polls position (P?, Table 15) and lens (V?, Table 17)
//! at a rate and keeps one live line on a terminal; one line (or JSON
//! object) per sample otherwise.

use std::io::IsTerminal;
use std::time::Duration;

use sagebrush_protocol::{Command, Reply};
use serde_json::json;

use crate::error::CtlError;
use crate::output::{position_json, position_text};
use crate::session::Session;

/// Polls until `count` samples or Ctrl-C.
pub async fn watch(session: &mut Session, rate: f64, count: Option<u64>, as_json: bool) -> Result<(), CtlError> {
    if !(rate.is_finite() && rate > 0.0 && rate <= 100.0) {
        return Err(CtlError::Usage(format!(
            "--rate {rate} must be within (0, 100] samples per second"
        )));
    }
    let live = !as_json && std::io::stdout().is_terminal();
    let mut ticker = tokio::time::interval(Duration::from_secs_f64(1.0 / rate));
    ticker.set_missed_tick_behavior(tokio::time::MissedTickBehavior::Delay);
    let mut n = 0u64;
    let ctrl_c = tokio::signal::ctrl_c();
    tokio::pin!(ctrl_c);
    while count.is_none_or(|c| n < c) {
        tokio::select! {
            _ = ticker.tick() => {}
            _ = &mut ctrl_c => break,
        }
        n += 1;
        let position = session.query(&Command::QueryPosition).await?;
        let position = match Reply::parse(&Command::QueryPosition, &position) {
            Ok(Reply::Position(p)) => p,
            _ => {
                return Err(CtlError::BadReply(format!(
                    "position reply \"{}\" is not Table 15",
                    sagebrush_host::hex::payload_text(&position)
                )));
            }
        };
        // The lens may be unpowered (NIC): shown as absent, not an error.
        let lens = match session.query(&Command::QueryLens).await {
            Ok(p) => match Reply::parse(&Command::QueryLens, &p) {
                Ok(Reply::Lens(l)) => Some(l),
                _ => {
                    return Err(CtlError::BadReply(format!(
                        "lens reply \"{}\" is not Table 17",
                        sagebrush_host::hex::payload_text(&p)
                    )));
                }
            },
            Err(CtlError::Nic(_)) => None,
            Err(e) => return Err(e),
        };
        if as_json {
            let lens = lens.map(|l| json!({ "zoom": l.zoom.get(), "focus": l.focus.get() }));
            sagebrush_host::outln!(
                "{}",
                json!({ "sample": n, "position": position_json(&position), "lens": lens })
            );
        } else {
            let lens = lens.map_or("lens -".to_string(), |l| {
                format!("zoom {:4}  focus {:4}", l.zoom.get(), l.focus.get())
            });
            let line = format!("{}  {lens}", position_text(&position));
            if live {
                sagebrush_host::out!("\r\x1b[2K{line}");
            } else {
                sagebrush_host::outln!("{line}");
            }
        }
    }
    if live {
        sagebrush_host::outln!();
    }
    Ok(())
}
