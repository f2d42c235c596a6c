//! `--for DURATION` and `--hold` of continuous motions (slew, zoom in/out,
//! focus far/near): start, keep this connection open (through gcud the
//! dead-man stops a motion when the connection that started it closes),
//! then send the motion's stop command and confirm it was acknowledged.

use std::time::Duration;

use sagebrush_host::hex::payload_text;
use sagebrush_protocol::{Command, Outcome, Undelivered};
use serde_json::Value;
use tokio::io::AsyncReadExt;
use tokio::signal::unix::{SignalKind, signal};

use crate::cli::{Cmd, JogArgs};
use crate::error::CtlError;
use crate::request::Request;
use crate::session::Session;

/// Resolves when stdin reaches its end (or cannot be read).
async fn stdin_closed() {
    let mut stdin = tokio::io::stdin();
    let mut buf = [0u8; 256];
    loop {
        match stdin.read(&mut buf).await {
            Ok(0) | Err(_) => return,
            Ok(_) => {}
        }
    }
}

pub async fn run(
    session: &mut Session,
    cmd: &Cmd,
    request: &Request<'_>,
    jog: JogArgs,
    as_json: bool,
) -> Result<(), CtlError> {
    let (command, payload) = (&request.command, &request.payload[..]);
    let stop = command
        .stopped_by()
        .ok_or_else(|| CtlError::Usage(format!("{} is no continuous motion", command.mnemonic())))?;
    let stop_payload = crate::request::encode(&stop)?;
    let (sent, stop_sent) = (payload_text(payload), payload_text(&stop_payload));
    // Listening before the start: a SIGTERM at any time after it stops the motion.
    let mut term = signal(SignalKind::terminate())?;
    let mut int = signal(SignalKind::interrupt())?;
    let ex = match session.start(request).await {
        Ok(ex) => ex,
        Err(e) => {
            // Not confirmed may still execute: stop it anyway, then say why the start failed.
            if matches!(e, CtlError::Undelivered(Undelivered::NotConfirmed, _)) {
                let _ = session.exchange(&stop, &stop_payload).await;
            }
            return Err(e);
        }
    };
    let started = tokio::time::Instant::now();
    if !as_json {
        match jog.duration {
            Some(d) => sagebrush_host::errln!(
                "gimbalctl: {sent} acknowledged; {stop_sent} in {:.3} s",
                d.as_secs_f64()
            ),
            None => sagebrush_host::errln!(
                "gimbalctl: {sent} acknowledged; holding until Ctrl-C, SIGTERM or end of stdin, then {stop_sent}"
            ),
        }
    }
    // Held by this connection: through gcud, `P?` every REFRESH renews the
    // motion lease of the client listener (ARCHITECTURE "Safety"), so a
    // gimbalctl that hangs lets gcud stop the motion.
    let refresh = sagebrush_client::session::REFRESH;
    let until = jog.duration.map(|d| started + d);
    let stdin_end = stdin_closed();
    tokio::pin!(stdin_end);
    let ended_by = loop {
        let tick = until.map_or(refresh, |u| {
            u.saturating_duration_since(tokio::time::Instant::now()).min(refresh)
        });
        tokio::select! {
            _ = tokio::time::sleep(tick) => {}
            _ = term.recv() => break "signal",
            _ = int.recv() => break "signal",
            _ = &mut stdin_end, if jog.duration.is_none() => break "stdin",
        }
        if until.is_some_and(|u| u <= tokio::time::Instant::now()) {
            break "duration";
        }
        if !session.to.has_wildcard() {
            // Its answer does not matter: the stop below is what is checked.
            let _ = session.exchange(&Command::QueryPosition, b"P?").await;
        }
    };
    let held = started.elapsed();
    let stop_ex = session.exchange(&stop, &stop_payload).await.map_err(|e| {
        CtlError::StopUnconfirmed(
            format!(
                "the stop {stop_sent} after {sent} ({:.3} s, ended by {ended_by}) was not acknowledged: {e}; \
                 the motion may go on (through gcud the dead-man stops it when this connection closes)",
                held.as_secs_f64()
            ),
            Box::new(e),
        )
    })?;
    let stop_outcome = match stop_ex.outcome {
        Outcome::Broadcast => "broadcast",
        _ => "acknowledged",
    };
    if as_json {
        let outcome = if ex.outcome == Outcome::Broadcast {
            "broadcast"
        } else {
            "acknowledged"
        };
        let mut m = crate::exchange_json(session, cmd, request, &ex, outcome);
        m.insert("held_ms".into(), (held.as_millis() as u64).into());
        m.insert(
            "for_ms".into(),
            jog.duration.map(|d: Duration| d.as_millis() as u64).into(),
        );
        m.insert("ended_by".into(), ended_by.into());
        m.insert("stop_sent".into(), stop_sent.clone().into());
        m.insert("stop_outcome".into(), stop_outcome.into());
        m.insert("stop_transmissions".into(), stop_ex.transmissions.into());
        sagebrush_host::outln!("{}", Value::Object(m));
    } else {
        sagebrush_host::outln!(
            "{sent} for {:.3} s (ended by {ended_by}), then {stop_sent} {stop_outcome}",
            held.as_secs_f64()
        );
    }
    Ok(())
}
