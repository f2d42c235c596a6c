//! `gimbalctl`: command Sagebrush pan-tilt gimbals (protocol rev 1.9) by
//! hand, on a bus (`--serial`) or through a GCU daemon (`--tcp`). Built on
//! the protocol crate's `Transaction` (via `sagebrush_client`). Exit codes
//! are listed in [`cli::EXIT_CODES`].

mod cli;
mod codec;
mod error;
mod gcud_status;
mod govern;
mod jog;
mod motion;
mod output;
mod progress;
mod request;
mod scan;
mod session;
mod tls_init;
mod watch;

use std::process::ExitCode;
use std::time::Duration;

use clap::CommandFactory;
use sagebrush_client::master::Exchange;
use sagebrush_host::hex::payload_text;
use sagebrush_protocol::{Address, Outcome, Reply};
use serde_json::{Map, Value, json};

use crate::cli::{Cli, Cmd};
use crate::error::CtlError;
use crate::request::Request;
use crate::session::Session;

fn main() -> ExitCode {
    if let Some(code) = sagebrush_host::man::generate_if_asked(Cli::command, cli::manual) {
        return code;
    }
    let cli = match cli::parse(std::env::args_os().collect()) {
        Ok(cli) => cli,
        Err(e) => {
            use clap::error::ErrorKind;
            let usage_error = !matches!(e.kind(), ErrorKind::DisplayHelp | ErrorKind::DisplayVersion)
                && e.kind() != ErrorKind::DisplayHelpOnMissingArgumentOrSubcommand;
            // Scripts asking for JSON get a JSON failure for bad arguments too.
            if usage_error && std::env::args().any(|a| a == "--json") {
                let text = e.render().to_string();
                let first = text.lines().next().unwrap_or_default().trim_start_matches("error: ");
                sagebrush_host::outln!(
                    "{}",
                    json!({ "ok": false, "command": null, "dest": null, "outcome": "usage",
                            "error": first, "exit_code": 2 })
                );
            }
            e.exit();
        }
    };
    let as_json = cli.global.json;
    if let Err(e) = sagebrush_host::logging::init(&cli.global.log, false) {
        sagebrush_host::errln!("gimbalctl: {e}");
        return ExitCode::from(2);
    }
    let result = match &cli.command {
        Cmd::Encode { payload } => {
            destination(&cli).and_then(|to| codec::encode(to, cli.global.from, payload, as_json))
        }
        Cmd::Decode { hex } => codec::decode(hex, as_json),
        Cmd::GcudStatus { http } => gcud_status::run(http, as_json),
        Cmd::Tls(cli::TlsCmd::Init { dir, host, principal }) => tls_init::run(dir, host, principal),
        _ => match tokio::runtime::Builder::new_current_thread().enable_all().build() {
            Ok(rt) => {
                let r = rt.block_on(run_to_the_end_of_the_capture(&cli));
                // A blocking stdin read (--hold) must not keep the process alive.
                rt.shutdown_background();
                r
            }
            Err(e) => Err(CtlError::Io(format!("cannot start the runtime: {e}"))),
        },
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            if as_json {
                let mut value = json!({
                    "ok": false,
                    "command": cli.command.name(),
                    "dest": cli.global.to.map(|a| a.to_string()),
                    "outcome": e.kind(),
                    "error": e.to_string(),
                    "exit_code": e.exit_code(),
                });
                if let (Value::Object(m), Value::Object(extra)) = (&mut value, e.detail()) {
                    m.extend(extra);
                }
                sagebrush_host::outln!("{value}");
            }
            sagebrush_host::errln!("gimbalctl: {e}");
            ExitCode::from(e.exit_code())
        }
    }
}

/// `--to`, which every command to a device needs (no silent default).
fn destination(cli: &Cli) -> Result<Address, CtlError> {
    cli.global.to.ok_or_else(|| {
        CtlError::Usage(format!(
            "`{}` needs --to GROUP.PORT.DEVICE: which device? e.g. --to 5.1.1 (GCU 5, port 1, device 1; \
             5.0.0 is GCU 5 itself; 255 is a wildcard); `gimbalctl scan` lists what answers",
            cli.command.name()
        ))
    })
}

/// [`run`]; with `--capture`, SIGINT and SIGTERM end the command instead of
/// the process, so that the session, and the capture file with it, is
/// completed (flushed and closed) before gimbalctl exits, 130 or 143 as a
/// shell reports a process killed by them. What ends on a signal by itself
/// keeps doing so: a jog with `--for`/`--hold` (it sends its stop first),
/// `scan` (it prints what it found so far) and `watch` on Ctrl-C (a normal end).
async fn run_to_the_end_of_the_capture(cli: &Cli) -> Result<(), CtlError> {
    use tokio::signal::unix::{Signal, SignalKind, signal};
    // A jog with --for/--hold sends its stop first; a scan prints what it found.
    let handles_signals =
        cli.command.jog().is_some_and(|j| j.duration.is_some() || j.hold) || matches!(cli.command, Cmd::Scan(_));
    if cli.global.capture.is_none() || handles_signals {
        return run(cli).await;
    }
    let mut term = signal(SignalKind::terminate())?;
    // `watch` ends on Ctrl-C itself, with its samples so far: a normal end.
    let mut int = match cli.command {
        Cmd::Watch { .. } => None,
        _ => Some(signal(SignalKind::interrupt())?),
    };
    async fn interrupted(int: &mut Option<Signal>) {
        match int {
            Some(s) => {
                s.recv().await;
            }
            None => std::future::pending().await,
        }
    }
    let (name, code) = tokio::select! {
        result = run(cli) => return result,
        _ = term.recv() => ("SIGTERM", 143),
        _ = interrupted(&mut int) => ("SIGINT", 130),
    };
    // `run` and its session are gone here: the capture file is complete.
    Err(CtlError::Interrupted(
        format!("interrupted by {name}"),
        code,
        Value::Null,
    ))
}

/// [`run_command`]; a command refused because another link controls the
/// gimbal names the holder (asked of gcud with `~C`).
async fn run(cli: &Cli) -> Result<(), CtlError> {
    match run_command(cli).await {
        // `release` names the holder itself.
        Err(e) if !matches!(cli.command, Cmd::Release) => {
            Err(govern::name_the_holder(&cli.global, cli.global.to, e).await)
        }
        ok => ok,
    }
}

async fn run_command(cli: &Cli) -> Result<(), CtlError> {
    let g = &cli.global;
    match &cli.command {
        Cmd::Scan(args) => return scan::scan(g, args).await,
        Cmd::Release => return govern::release(g, destination(cli)?).await,
        Cmd::Tour(tour) => return govern::tour(g, tour).await,
        _ => {}
    }
    let to = destination(cli)?;
    let data = request::data(&cli.command)?;
    let request = request::request(&cli.command, &data)?;
    let wait = cli.command.wait();
    if wait.is_some() && (to.device == 255 || to.port == 255 || to.group == 255) {
        return Err(CtlError::Usage(format!(
            "--wait polls one device's position, and {to} is a wildcard address: give one device, e.g. --to 5.1.1"
        )));
    }
    let mut session = Session::open(g, to).await?;
    if let Cmd::Watch { rate, count } = cli.command {
        return watch::watch(&mut session, rate, count, g.json).await;
    }
    let Some(request) = request else {
        return Err(CtlError::Usage("this subcommand sends nothing".into()));
    };
    if let Some(j) = cli.command.jog().filter(|j| j.duration.is_some() || j.hold) {
        return jog::run(&mut session, &cli.command, &request, j, g.json).await;
    }
    // A preset's position, known before the recall, is what --wait aims at.
    let target = match wait {
        Some(_) => Some(motion::target(&mut session, &request.command).await?),
        None => None,
    };
    let ex = session.start(&request).await?;
    let raw = matches!(cli.command, Cmd::Raw { .. });
    let (text, mut value) = report(&session, &cli.command, &request, &ex, raw)?;
    if cli.command.jog().is_some() && session.gcud && ex.outcome != Outcome::Broadcast {
        sagebrush_host::errln!(
            "gimbalctl: note: through gcud this motion stops as soon as gimbalctl exits (gcud's dead-man); \
             use --for DURATION or --hold to keep it going"
        );
    }
    if let (Some(w), Some(target)) = (wait, target) {
        let arrived = motion::wait(&mut session, target, Duration::from_millis(w.wait_timeout)).await?;
        if let Value::Object(m) = &mut value {
            if let Value::Object(extra) = arrived.json() {
                m.extend(extra);
            }
        }
        if !g.json {
            sagebrush_host::outln!("{text}");
            sagebrush_host::outln!("{}", arrived.text());
            return Ok(());
        }
    }
    if g.json {
        sagebrush_host::outln!("{value}");
    } else {
        sagebrush_host::outln!("{text}");
        if ex.transmissions > 1 || ex.naks_sent > 0 {
            sagebrush_host::errln!(
                "gimbalctl: note: {} transmission(s), {} NAK(s) received, {} damaged result(s) NAKed",
                ex.transmissions,
                ex.naks_received,
                ex.naks_sent
            );
        }
    }
    Ok(())
}

/// The JSON fields every exchange has: what was asked, what was sent, how it went.
pub fn exchange_json(
    session: &Session,
    cmd: &Cmd,
    request: &Request<'_>,
    ex: &Exchange,
    outcome: &str,
) -> Map<String, Value> {
    let mut m = Map::new();
    m.insert("ok".into(), true.into());
    m.insert("command".into(), cmd.name().into());
    m.insert("sent".into(), payload_text(&request.payload).into());
    m.insert("mnemonic".into(), request.command.mnemonic().into());
    if let Value::Object(args) = output::command_json(&request.command) {
        for (k, v) in args {
            if k != "name" && k != "mnemonic" {
                m.insert(k, v);
            }
        }
    }
    m.insert("dest".into(), session.to.to_string().into());
    m.insert("source".into(), session.from().into());
    m.insert("outcome".into(), outcome.into());
    m.insert("transmissions".into(), ex.transmissions.into());
    m.insert("naks_received".into(), ex.naks_received.into());
    m.insert("naks_sent".into(), ex.naks_sent.into());
    m.insert("noise_bytes".into(), ex.noise_bytes.into());
    m.insert("elapsed_ms".into(), (ex.elapsed.as_millis() as u64).into());
    m
}

/// The text and JSON of a successful exchange.
fn report(
    session: &Session,
    cmd: &Cmd,
    request: &Request<'_>,
    ex: &Exchange,
    raw: bool,
) -> Result<(String, Value), CtlError> {
    let command = &request.command;
    let sent = payload_text(&request.payload);
    let (text, result, outcome) = match &ex.result {
        Some(frame) => {
            let p = frame.frame().payload();
            match Reply::parse(command, p) {
                Ok(reply) => {
                    let (t, v) = output::describe(command, &reply);
                    (t, v, "result")
                }
                Err(_) if raw => (payload_text(p), json!({ "raw": payload_text(p) }), "result"),
                Err(e) => {
                    return Err(CtlError::BadReply(format!(
                        "result of {sent} ({}) from {}: {e} (payload \"{}\")",
                        command.mnemonic(),
                        session.to,
                        payload_text(p)
                    )));
                }
            }
        }
        None if ex.outcome == Outcome::Broadcast => (
            format!(
                "{sent} sent to every device of {} (broadcast: no answer awaited)",
                session.to
            ),
            Value::Null,
            "broadcast",
        ),
        None => (output::acknowledged_text(command, &sent), Value::Null, "acknowledged"),
    };
    let mut m = exchange_json(session, cmd, request, ex, outcome);
    m.insert("result".into(), result);
    m.insert(
        "result_payload".into(),
        ex.result.as_ref().map(|f| payload_text(f.frame().payload())).into(),
    );
    Ok((text, Value::Object(m)))
}
