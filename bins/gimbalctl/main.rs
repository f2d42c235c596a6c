//! `gimbalctl`: command Sagebrush pan-tilt gimbals (protocol rev 1.9) by
//! hand, on a bus (`--serial`) or through a GCU daemon (`--tcp`). Built on
//! the protocol crate's `Transaction` (via `sagebrush_host::master`). Exit codes
//! are listed in [`cli::EXIT_CODES`].

mod cli;
mod codec;
mod error;
mod output;
mod request;
mod session;
mod watch;

use std::process::ExitCode;
use std::time::Duration;

use clap::Parser;
use sagebrush_host::hex::payload_text;
use sagebrush_host::master::Exchange;
use sagebrush_protocol::{Command, Outcome, Position, Reply};
use serde_json::{Value, json};

use crate::cli::{Cli, Cmd};
use crate::error::CtlError;
use crate::session::Session;

fn main() -> ExitCode {
    let cli = Cli::parse();
    let as_json = cli.global.json;
    if let Err(e) = sagebrush_host::logging::init(&cli.global.log, false) {
        eprintln!("gimbalctl: {e}");
        return ExitCode::from(2);
    }
    let result = match &cli.command {
        Cmd::Encode { payload } => codec::encode(cli.global.to, cli.global.from, payload, as_json),
        Cmd::Decode { hex } => codec::decode(hex, as_json),
        _ => match tokio::runtime::Builder::new_current_thread().enable_all().build() {
            Ok(rt) => rt.block_on(run(&cli)),
            Err(e) => Err(CtlError::Io(format!("cannot start the runtime: {e}"))),
        },
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            if as_json {
                println!(
                    "{}",
                    json!({
                        "ok": false,
                        "dest": cli.global.to.to_string(),
                        "outcome": e.kind(),
                        "error": e.to_string(),
                        "exit_code": e.exit_code(),
                    })
                );
            }
            eprintln!("gimbalctl: {e}");
            ExitCode::from(e.exit_code())
        }
    }
}

async fn run(cli: &Cli) -> Result<(), CtlError> {
    let g = &cli.global;
    let payload = request::payload(&cli.command)?;
    let mut session = Session::open(g).await?;
    if let Cmd::Watch { rate, count } = cli.command {
        return watch::watch(&mut session, rate, count, g.json).await;
    }
    let Some(payload) = payload else {
        return Err(CtlError::Usage("this subcommand sends nothing".into()));
    };
    let ex = session.exchange(&payload).await?;
    let raw = matches!(cli.command, Cmd::Raw { .. });
    let (text, mut value) = report(&session, &payload, &ex, raw)?;
    if let Cmd::Goto {
        pan,
        tilt,
        wait: true,
        wait_timeout,
    } = cli.command
    {
        let target = match Command::parse(&payload) {
            Command::GoTo(p) => p,
            _ => Position::default(),
        };
        let (last, reached) = wait_for_stop(&mut session, target, Duration::from_millis(wait_timeout)).await?;
        value["final"] = output::position_json(&last);
        value["reached"] = reached.into();
        if !g.json {
            println!(
                "{} at {}{}",
                if reached { "arrived" } else { "stopped short" },
                output::position_text(&last).trim(),
                if reached {
                    String::new()
                } else {
                    format!(" (target pan {pan:.2}° tilt {tilt:.2}°; software limits or travel?)")
                }
            );
            return Ok(());
        }
    }
    if g.json {
        println!("{value}");
    } else {
        println!("{text}");
        if ex.transmissions > 1 || ex.naks_sent > 0 {
            eprintln!(
                "gimbalctl: note: {} transmission(s), {} NAK(s) received, {} damaged result(s) NAKed",
                ex.transmissions, ex.naks_received, ex.naks_sent
            );
        }
    }
    Ok(())
}

/// The text and JSON of a successful exchange.
fn report(session: &Session, payload: &[u8], ex: &Exchange, raw: bool) -> Result<(String, Value), CtlError> {
    let command = Command::parse(payload);
    let (text, result, outcome) = match &ex.result {
        Some(frame) => {
            let p = frame.frame().payload();
            match Reply::parse(&command, p) {
                Ok(reply) => {
                    let (t, v) = output::describe(&reply);
                    (t, v, "result")
                }
                Err(_) if raw => (payload_text(p), Value::Null, "result"),
                Err(e) => {
                    return Err(CtlError::BadReply(format!(
                        "result of {} from {}: {e} (payload \"{}\")",
                        command.mnemonic(),
                        session.to,
                        payload_text(p)
                    )));
                }
            }
        }
        None if ex.outcome == Outcome::Broadcast => (
            format!(
                "{} sent to every device (broadcast: no answer awaited)",
                command.mnemonic()
            ),
            Value::Null,
            "broadcast",
        ),
        None => (output::acknowledged_text(&command), Value::Null, "acknowledged"),
    };
    let value = json!({
        "ok": true,
        "dest": session.to.to_string(),
        "source": session.from,
        "command": command.mnemonic(),
        "payload": payload_text(payload),
        "outcome": outcome,
        "result": result,
        "result_payload": ex.result.as_ref().map(|f| payload_text(f.frame().payload())),
        "transmissions": ex.transmissions,
        "naks_received": ex.naks_received,
        "naks_sent": ex.naks_sent,
        "noise_bytes": ex.noise_bytes,
        "elapsed_ms": ex.elapsed.as_millis() as u64,
    });
    Ok((text, value))
}

/// Polls the position until two readings 100 ms apart agree; whether that is the target.
async fn wait_for_stop(
    session: &mut Session,
    target: Position,
    timeout: Duration,
) -> Result<(Position, bool), CtlError> {
    let deadline = tokio::time::Instant::now() + timeout;
    let mut last: Option<Position> = None;
    loop {
        let p = session.query(&Command::QueryPosition).await?;
        let p = match Reply::parse(&Command::QueryPosition, &p) {
            Ok(Reply::Position(p)) => p,
            _ => return Err(CtlError::BadReply(format!("position reply {p:?} is not Table 15"))),
        };
        if last == Some(p) {
            return Ok((p, p == target));
        }
        if tokio::time::Instant::now() >= deadline {
            return Err(CtlError::NoResult(format!(
                "the mount was still moving after {} ms (at {})",
                timeout.as_millis(),
                output::position_text(&p).trim()
            )));
        }
        last = Some(p);
        tokio::time::sleep(Duration::from_millis(100)).await;
    }
}
