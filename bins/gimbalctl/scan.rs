//! `gimbalctl scan`: what is reachable. Through gcud: GCUs (D? to G.0.0,
//! Table 4/6), their ports, and on each port the devices that answer D?
//! (then AW, Table 5, and I?, Table 6B). On a bus: the devices at one
//! GROUP.PORT. Only queries, one at a time, `--interval` apart; every
//! failure other than silence is reported per address and the sweep goes
//! on; a second answer to one address (duplicate IDs) is a collision.

use std::time::Duration;

use sagebrush_host::hex::payload_text;
use sagebrush_protocol::{Address, Command, DeliveryReport, FrameBuf, Reply, Undelivered};
use serde_json::{Value, json};

use crate::cli::{Global, ScanArgs};
use crate::error::CtlError;
use crate::output;
use crate::session::Session;

/// How long to listen for a second answer after each identity result.
const LINGER: Duration = Duration::from_millis(40);

/// A device's identity block as JSON, from a D? result payload.
fn identity(payload: &[u8]) -> Option<Value> {
    match Reply::parse(&Command::Identify, payload) {
        Ok(reply @ Reply::Identity(_)) => Some(output::describe(&Command::Identify, &reply).1),
        _ => None,
    }
}

struct Scan<'a> {
    session: Session,
    args: &'a ScanArgs,
    problems: Vec<Value>,
    collisions: Vec<Value>,
    probes: u64,
}

/// What one identity probe found.
enum Probe {
    Found(Value),
    /// Nothing answered (device silent, no ACK): absent.
    Silent,
    /// Stop sweeping this port: the GCU has no such port, or it is closed.
    Port(Undelivered),
    /// The group is not reachable (no route and the like).
    Unreachable,
    Failed,
}

impl Scan<'_> {
    fn problem(&mut self, at: Address, e: &CtlError) {
        self.problems.push(json!({
            "address": at.to_string(),
            "outcome": e.kind(),
            "exit_code": e.exit_code(),
            "error": e.to_string(),
        }));
    }

    async fn pause(&self) {
        if self.args.interval > 0 {
            tokio::time::sleep(Duration::from_millis(self.args.interval)).await;
        }
    }

    /// D? to `at`; then a short listen for a second answer.
    async fn identify(&mut self, at: Address) -> Result<Probe, CtlError> {
        self.session.to = at;
        self.probes += 1;
        let payload = crate::request::encode(&Command::Identify)?;
        let result = self.session.exchange(&payload).await;
        let probe = match result {
            Ok(ex) => match &ex.result {
                Some(frame) => {
                    let p = frame.frame().payload();
                    if DeliveryReport::is_report(p) {
                        // A late report about an earlier probe: not this address's answer.
                        let e = CtlError::BadReply(format!(
                            "a delivery report \"{}\" about an earlier probe came instead of {at}'s identity",
                            payload_text(p)
                        ));
                        self.problem(at, &e);
                        self.pause().await;
                        return Ok(Probe::Failed);
                    }
                    match identity(p) {
                        Some(id) => {
                            self.check_collision(at, &id, &ex).await?;
                            Probe::Found(id)
                        }
                        None => {
                            let e = CtlError::BadReply(format!(
                                "D? result from {at} is no Table 6 identity: \"{}\"",
                                payload_text(p)
                            ));
                            self.problem(at, &e);
                            Probe::Failed
                        }
                    }
                }
                None => {
                    let e = CtlError::NoResult(format!("{at} acknowledged D? but sent no identity"));
                    self.problem(at, &e);
                    Probe::Failed
                }
            },
            Err(CtlError::Io(m)) => return Err(CtlError::Io(m)),
            Err(CtlError::NoAck(_)) | Err(CtlError::Undelivered(Undelivered::DeviceSilent, _)) => Probe::Silent,
            Err(CtlError::Undelivered(u @ (Undelivered::NoSuchPort | Undelivered::PortClosed), _)) => Probe::Port(u),
            Err(CtlError::Undelivered(
                Undelivered::NoRoute | Undelivered::Loop | Undelivered::SourceNotAllowed | Undelivered::LinkDown,
                _,
            )) if at.port == 0 => Probe::Unreachable,
            Err(e) => {
                self.problem(at, &e);
                Probe::Failed
            }
        };
        self.pause().await;
        Ok(probe)
    }

    /// Two devices with one ID on a bus both answer: extra ACKs, a second
    /// result, or damaged results (NAKed, noise) give them away.
    async fn check_collision(
        &mut self,
        at: Address,
        first: &Value,
        ex: &sagebrush_client::master::Exchange,
    ) -> Result<(), CtlError> {
        let extra = self.session.linger(LINGER).await?;
        let others: Vec<&FrameBuf> = extra
            .frames
            .iter()
            .filter(|f| f.frame().dest.port == at.port && f.frame().dest.device == at.device)
            .collect();
        let damaged = ex.naks_sent > 0 || ex.noise_bytes > 0 || ex.stray_frames > 0;
        if others.is_empty() && extra.acks == 0 && !damaged {
            return Ok(());
        }
        let mut answers = vec![first.clone()];
        answers.extend(others.iter().map(|f| {
            identity(f.frame().payload()).unwrap_or_else(|| json!({ "raw": payload_text(f.frame().payload()) }))
        }));
        self.collisions.push(json!({
            "address": at.to_string(),
            "answers": answers,
            "extra_results": others.len(),
            "extra_acks": extra.acks,
            "damaged_results": ex.naks_sent,
            "noise_bytes": ex.noise_bytes + u64::from(extra.other_bytes),
            "stray_frames": ex.stray_frames,
        }));
        Ok(())
    }

    /// A query of a found device, decoded; failures are recorded, not fatal.
    async fn ask(&mut self, at: Address, command: Command<'_>) -> Result<Value, CtlError> {
        self.session.to = at;
        self.probes += 1;
        let r = self.session.query(&command).await;
        self.pause().await;
        match r {
            Ok(p) => match Reply::parse(&command, &p) {
                Ok(reply) => Ok(output::describe(&command, &reply).1),
                Err(e) => {
                    let e = CtlError::BadReply(format!(
                        "{} result from {at}: {e} (payload \"{}\")",
                        command.mnemonic(),
                        payload_text(&p)
                    ));
                    self.problem(at, &e);
                    Ok(Value::Null)
                }
            },
            Err(CtlError::Io(m)) => Err(CtlError::Io(m)),
            Err(e) => {
                self.problem(at, &e);
                Ok(Value::Null)
            }
        }
    }

    /// The devices of `ids` at `group.port`; `Err(Undelivered)` when the port is absent or closed.
    async fn devices(&mut self, group: u8, port: u8) -> Result<Result<(Vec<Value>, u32), Undelivered>, CtlError> {
        let mut found = Vec::new();
        let mut silent = 0u32;
        for d in self.args.devices.0.clone() {
            let at = Address::new(group, port, d);
            match self.identify(at).await? {
                Probe::Found(id) => {
                    let awake = self.ask(at, Command::AwakeStatus).await?;
                    let status = self.ask(at, Command::QueryStatusBits).await?;
                    let collision = self.collisions.iter().any(|c| c["address"] == at.to_string());
                    let mut dev = json!({ "address": at.to_string(), "device": d });
                    if let (Value::Object(m), Value::Object(idm)) = (&mut dev, id) {
                        m.extend(idm);
                        m.insert("awake".into(), awake);
                        m.insert("status".into(), status);
                        m.insert("collision".into(), collision.into());
                    }
                    found.push(dev);
                }
                Probe::Silent => silent += 1,
                Probe::Port(u) => return Ok(Err(u)),
                Probe::Unreachable | Probe::Failed => {}
            }
        }
        Ok(Ok((found, silent)))
    }
}

fn device_line(d: &Value) -> String {
    let bits = |axis: &Value| -> String {
        let set: Vec<&str> = axis
            .as_object()
            .map(|m| {
                m.iter()
                    .filter(|(k, v)| *k != "raw" && v.as_bool() == Some(true))
                    .map(|(k, _)| k.as_str())
                    .collect()
            })
            .unwrap_or_default();
        if set.is_empty() { "none".into() } else { set.join(",") }
    };
    let awake = match d["awake"]["code"].as_u64() {
        Some(0) => "ok".to_string(),
        Some(c) => format!("code {c:X}"),
        None => "?".into(),
    };
    format!(
        "device {} ({})  {:?}  serial {:?}  revision {}  awake {}  status azimuth {} ; elevation {}{}",
        d["device"],
        d["address"].as_str().unwrap_or_default(),
        d["name"].as_str().unwrap_or_default(),
        d["serial"].as_str().unwrap_or_default(),
        d["revision"].as_str().unwrap_or_default(),
        awake,
        bits(&d["status"]["azimuth"]),
        bits(&d["status"]["elevation"]),
        if d["collision"] == true {
            "  COLLISION: duplicate ID?"
        } else {
            ""
        }
    )
}

pub async fn scan(g: &Global, args: &ScanArgs) -> Result<(), CtlError> {
    let started = std::time::Instant::now();
    let timeout = args.timeout;
    // Through a GCU the ACK waits for the device (and a report says why
    // not) within gcud's delivery time-out, shorter than the TCP default
    // ACK time-out: that one stays, or a late report would meet the next probe.
    let to_gcu = g.tcp.is_some() && !args.direct;
    let session = Session::open_with(g, Address::new(255, 0, 0), |p| {
        p.retry.retries = 0;
        p.result_timeout = timeout;
        p.nic_window = p.nic_window.min(timeout);
        if !to_gcu {
            p.retry.ack_timeout = timeout;
        }
    })
    .await?;
    let through_gcu = session.over_tcp && !args.direct;
    let line = session.line.clone();
    let mut s = Scan {
        session,
        args,
        problems: Vec::new(),
        collisions: Vec::new(),
        probes: 0,
    };
    // What will be asked, before the first probe (a long scan is not silent).
    if through_gcu {
        sagebrush_host::errln!(
            "gimbalctl: scan: D? to the GCU of groups {} (unrouted groups skipped), then to devices {} \
             on ports {} of each GCU found (absent ports skipped); up to {} ms per silent address",
            args.gcus,
            args.devices,
            args.ports,
            timeout
        );
    } else {
        let (group, port) = args.bus;
        sagebrush_host::errln!(
            "gimbalctl: scan: D? to devices {} at {group}.{port}; up to {timeout} ms per silent address",
            args.devices
        );
    }
    let mut text = Vec::new();
    let mut gcus = Vec::new();
    let mut bus = Value::Null;
    if through_gcu {
        for group in args.gcus.0.clone() {
            let at = Address::new(group, 0, 0);
            let Probe::Found(id) = s.identify(at).await? else {
                continue;
            };
            text.push(format!(
                "GCU {group} ({at})  {:?}  serial {:?}  revision {}",
                id["name"].as_str().unwrap_or_default(),
                id["serial"].as_str().unwrap_or_default(),
                id["revision"].as_str().unwrap_or_default()
            ));
            let mut ports = Vec::new();
            for port in args.ports.0.clone() {
                match s.devices(group, port).await? {
                    Err(Undelivered::NoSuchPort) => {}
                    Err(u) => {
                        text.push(format!("  port {port}: {}", u.describe()));
                        ports.push(json!({ "port": port, "state": u.name(), "devices": [], "silent": 0 }));
                    }
                    Ok((devices, silent)) => {
                        sagebrush_host::errln!(
                            "gimbalctl: scan: port {group}.{port}: {} found, {silent} silent",
                            devices.len()
                        );
                        text.push(format!("  port {port}"));
                        for d in &devices {
                            text.push(format!("    {}", device_line(d)));
                        }
                        text.push(format!("    ({silent} of {} IDs silent)", args.devices.0.len()));
                        ports.push(json!({ "port": port, "state": "open", "devices": devices, "silent": silent }));
                    }
                }
            }
            let mut gcu = json!({ "group": group, "address": at.to_string(), "ports": ports });
            if let (Value::Object(m), Value::Object(idm)) = (&mut gcu, id) {
                m.extend(idm);
            }
            gcus.push(gcu);
        }
        if gcus.is_empty() {
            text.push(format!("no GCU answered D? at any of {} groups", args.gcus.0.len()));
        }
    } else {
        let (group, port) = args.bus;
        text.push(format!("bus {group}.{port} ({line})"));
        match s.devices(group, port).await? {
            Ok((devices, silent)) => {
                for d in &devices {
                    text.push(format!("  {}", device_line(d)));
                }
                text.push(format!("  ({silent} of {} IDs silent)", args.devices.0.len()));
                bus = json!({ "group": group, "port": port, "devices": devices, "silent": silent });
            }
            Err(u) => {
                text.push(format!("  {}", u.describe()));
                bus = json!({ "group": group, "port": port, "state": u.name(), "devices": [], "silent": 0 });
            }
        }
    }
    if !s.problems.is_empty() {
        text.push("problems (the scan went on):".into());
        for p in &s.problems {
            text.push(format!(
                "  {}: {} ({})",
                p["address"].as_str().unwrap_or_default(),
                p["error"].as_str().unwrap_or_default(),
                p["outcome"].as_str().unwrap_or_default()
            ));
        }
    }
    if !s.collisions.is_empty() {
        text.push("collisions (more than one answer to one address: duplicate device IDs?):".into());
        for c in &s.collisions {
            text.push(format!(
                "  {}: {} extra result(s), {} extra ACK(s), {} damaged result(s), {} noise byte(s)",
                c["address"].as_str().unwrap_or_default(),
                c["extra_results"],
                c["extra_acks"],
                c["damaged_results"],
                c["noise_bytes"]
            ));
        }
    }
    if g.json {
        sagebrush_host::outln!(
            "{}",
            json!({
                "ok": true,
                "command": "scan",
                "line": line,
                "gcus": gcus,
                "bus": bus,
                "problems": s.problems,
                "collisions": s.collisions,
                "probes": s.probes,
                "elapsed_ms": started.elapsed().as_millis() as u64,
            })
        );
    } else {
        sagebrush_host::outln!("{}", text.join("\n"));
    }
    Ok(())
}
