//! `gimbalctl release` and `gimbalctl tour list|start|stop`: GCU commands
//! on port 0 (the protocol crate's module `gcu`, ARCHITECTURE
//! "Governance"), through gcud's client listener (`--tcp`) only; and the
//! holder named when gcud refuses a command because another link controls
//! the gimbal.

use sagebrush_client::governance::Controller;
use sagebrush_host::hex::payload_text;
use sagebrush_protocol::gcu::{parse_tour_list, parse_tour_reply};
use sagebrush_protocol::{Address, Command, GcuCommand, MAX_PAYLOAD, TourState, Undelivered, WILDCARD};
use serde_json::{Value, json};

use crate::cli::{Global, TourCmd};
use crate::error::CtlError;
use crate::session::Session;

/// A GCU's address: its group, port 0, device 0.
fn gcu(group: u8) -> Address {
    Address::new(group, 0, 0)
}

fn over_tcp(g: &Global, what: &str) -> Result<(), CtlError> {
    match (&g.tcp, &g.serial) {
        (Some(_), _) => Ok(()),
        _ => Err(CtlError::Usage(format!(
            "`{what}` is a GCU command to gcud: give --tcp HOST:PORT of its client listener \
             (a bus has no GCU to ask)"
        ))),
    }
}

fn state_name(state: TourState) -> &'static str {
    match state {
        TourState::Running => "running",
        TourState::Waiting => "waiting",
        TourState::Stopped => "stopped",
    }
}

/// The GCU `--tcp` reaches: the source group of its answer to `D?` at
/// group 255 (Table 3; the local GCU answers before any GCU below it).
async fn reached_group(g: &Global) -> Result<u8, CtlError> {
    let mut session = Session::open(g, Address::new(WILDCARD, 0, 0)).await?;
    let ex = session.exchange(&Command::Identify, b"D?").await?;
    match ex.result {
        Some(frame) => Ok(frame.frame().source),
        None => Err(CtlError::NoResult(
            "gcud did not say its group (no answer to D? on port 0): give --to G.0.0".into(),
        )),
    }
}

/// One GCU command to the GCU of `group`: the result payload, if it has one.
async fn exchange(g: &Global, group: u8, command: GcuCommand<'_>) -> Result<Option<Vec<u8>>, CtlError> {
    let mut buf = [0u8; MAX_PAYLOAD];
    let len = command
        .encode(&mut buf)
        .ok_or_else(|| CtlError::Usage("the GCU command does not fit a frame".into()))?;
    let payload = &buf[..len];
    let mut session = Session::open(g, gcu(group)).await?;
    // The transaction waits as for a command of that answer: a result
    // (D? stands for any query of port 0) or the ACK alone.
    let waits_as = match command.has_result() {
        true => Command::Identify,
        false => Command::Unknown(payload),
    };
    let ex = session.exchange(&waits_as, payload).await.map_err(|e| {
        let sent = payload_text(payload);
        match e {
            CtlError::Nic(_) => CtlError::Nic(format!(
                "GCU {group} does not know {sent}: no such tour or gimbal, or a gcud without governance \
                 (`gimbalctl tour list` lists the tours)"
            )),
            CtlError::Undelivered(failure, _) if !failure.is_refusal() => CtlError::Undelivered(
                failure,
                format!("not delivered: {sent} to GCU {group}: {}", failure.describe()),
            ),
            other => other,
        }
    })?;
    Ok(ex.result.map(|f| f.frame().payload().to_vec()))
}

/// The group of the GCU the command goes to: `--to`'s, or the one reached.
async fn group_of(g: &Global) -> Result<u8, CtlError> {
    match g.to {
        Some(to) if to.group != WILDCARD => Ok(to.group),
        _ => reached_group(g).await,
    }
}

/// Who controls `gimbal`, in words (`link operators (priority 80)`,
/// `tour perimeter`, `park`), `None` for nobody.
pub async fn holder(g: &Global, gimbal: Address) -> Result<Option<String>, CtlError> {
    let payload = exchange(g, gimbal.group, GcuCommand::Controller(gimbal.port, gimbal.device)).await?;
    let payload = payload.unwrap_or_default();
    let bad = || CtlError::BadReply(format!("answer to ~C: {:?}", String::from_utf8_lossy(&payload)));
    // The client crate's reading of `~C` and its words for the holder.
    let holder = Controller::from_result(&payload, gimbal.port, gimbal.device).map_err(|_| bad())?;
    Ok(match holder {
        Controller::Nobody => None,
        Controller::Link { yours: true, .. } => {
            let text = holder.to_string();
            let open = text.strip_suffix(')').unwrap_or(&text);
            Some(format!("{open}, this connection's)"))
        }
        other => Some(other.to_string()),
    })
}

/// A refusal because another link controls the gimbal says whom it is
/// held by (asked with `~C`); any other error is returned as it is.
pub async fn name_the_holder(g: &Global, to: Option<Address>, e: CtlError) -> CtlError {
    let (CtlError::Undelivered(Undelivered::NotInControl, message), Some(to)) = (&e, to) else {
        return e;
    };
    if g.tcp.is_none() || to.has_wildcard() {
        return e;
    }
    match holder(g, to).await {
        Ok(Some(who)) => CtlError::Undelivered(
            Undelivered::NotInControl,
            format!(
                "{message}; {to} is held by {who} until its control lapses ([control] hold_ms after its last command)"
            ),
        ),
        _ => e,
    }
}

/// `gimbalctl release --to G.P.D`.
pub async fn release(g: &Global, to: Address) -> Result<(), CtlError> {
    over_tcp(g, "release")?;
    if to.has_wildcard() || to.port == 0 || to.device == 0 {
        return Err(CtlError::Usage(format!(
            "release needs one gimbal's address, e.g. --to 5.1.1; {to} is not one"
        )));
    }
    match exchange(g, to.group, GcuCommand::Release(to.port, to.device)).await {
        Ok(_) => {}
        Err(CtlError::Undelivered(Undelivered::NotInControl, _)) => {
            let who = holder(g, to)
                .await
                .ok()
                .flatten()
                .unwrap_or_else(|| "another link".to_owned());
            return Err(CtlError::Undelivered(
                Undelivered::NotInControl,
                format!(
                    "not released: {to} is held by {who}; only the holder's link or one of its priority \
                     or higher may release it (it lapses [control] hold_ms after its last command)"
                ),
            ));
        }
        Err(e) => return Err(e),
    }
    if g.json {
        sagebrush_host::outln!(
            "{}",
            json!({ "ok": true, "command": "release", "dest": to.to_string(), "outcome": "released" })
        );
    } else {
        sagebrush_host::outln!("released {to}: nobody controls it now");
    }
    Ok(())
}

/// `gimbalctl tour list | start NAME | stop NAME`.
pub async fn tour(g: &Global, cmd: &TourCmd) -> Result<(), CtlError> {
    over_tcp(g, "tour")?;
    let group = group_of(g).await?;
    let (command, name) = match cmd {
        TourCmd::List => (GcuCommand::TourList, None),
        TourCmd::Start { name } => (GcuCommand::TourStart(name.as_bytes()), Some(name)),
        TourCmd::Stop { name } => (GcuCommand::TourStop(name.as_bytes()), Some(name)),
    };
    let payload = exchange(g, group, command).await?.unwrap_or_default();
    let bad = || CtlError::BadReply(format!("GCU {group} answered {:?}", String::from_utf8_lossy(&payload)));
    let Some(name) = name else {
        let tours = parse_tour_list(&payload).ok_or_else(bad)?;
        let mut list = Vec::new();
        for entry in tours {
            let (name, state) = entry.ok_or_else(bad)?;
            list.push((String::from_utf8_lossy(name).into_owned(), state_name(state)));
        }
        if g.json {
            let tours: Vec<Value> = list.iter().map(|(n, s)| json!({ "name": n, "state": s })).collect();
            sagebrush_host::outln!(
                "{}",
                json!({ "ok": true, "command": "tour list", "gcu": group, "tours": tours })
            );
        } else if list.is_empty() {
            sagebrush_host::outln!("GCU {group} has no tours ([[tour]] in gcud's configuration)");
        } else {
            for (n, s) in &list {
                sagebrush_host::outln!("{n}  {s}");
            }
        }
        return Ok(());
    };
    let (state, waiting_for) = parse_tour_reply(&payload).ok_or_else(bad)?;
    let waiting_for = String::from_utf8_lossy(waiting_for).into_owned();
    if g.json {
        sagebrush_host::outln!(
            "{}",
            json!({ "ok": true, "command": cmd_name(cmd), "gcu": group, "tour": name,
                    "state": state_name(state),
                    "waiting_for": (!waiting_for.is_empty()).then_some(&waiting_for) })
        );
    } else {
        match state {
            TourState::Waiting if !waiting_for.is_empty() => sagebrush_host::outln!(
                "tour {name}: waiting for {waiting_for} (it starts when their control of the gimbal lapses)"
            ),
            TourState::Waiting => sagebrush_host::outln!("tour {name}: waiting for control of the gimbal"),
            s => sagebrush_host::outln!("tour {name}: {}", state_name(s)),
        }
    }
    Ok(())
}

fn cmd_name(cmd: &TourCmd) -> &'static str {
    match cmd {
        TourCmd::List => "tour list",
        TourCmd::Start { .. } => "tour start",
        TourCmd::Stop { .. } => "tour stop",
    }
}
