//! `gimbalctl scan`: what is reachable. Through gcud: GCUs (D? to G.0.0,
//! Table 4/6), their ports, and on each port the devices that answer D?
//! (then AW, Table 5, and I?, Table 6B). On a bus: the devices at one
//! GROUP.PORT. Only queries, one at a time, `--interval` apart; every
//! failure other than silence is reported per address and the sweep goes
//! on; a second answer to one address (duplicate IDs) is a collision.
//! Progress goes to stderr ([`Progress`]); SIGINT or SIGTERM ends the scan
//! with what it found so far printed, and exit 130 or 143.

use std::time::{Duration, Instant};

use sagebrush_host::hex::payload_text;
use sagebrush_protocol::{Address, Command, DeliveryReport, FrameBuf, Reply, Undelivered};
use serde_json::{Map, Value, json};

use crate::cli::{Global, ScanArgs};
use crate::error::CtlError;
use crate::output;
use crate::progress::Progress;
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

/// One port's sweep, as far as it went.
#[derive(Debug)]
struct PortFound {
    port: u8,
    /// `None` while open; why the GCU would not deliver to it otherwise.
    state: Option<Undelivered>,
    devices: Vec<Value>,
    silent: u32,
    /// IDs of `--devices` asked so far (all of them unless interrupted).
    asked: usize,
}

/// A GCU that answered D?, with its ports swept so far.
#[derive(Debug)]
struct GcuFound {
    group: u8,
    id: Value,
    ports: Vec<PortFound>,
}

/// What the scan has found so far: printed at its end, or when it is interrupted.
#[derive(Debug, Default)]
struct Found {
    /// Groups asked for their GCU so far.
    groups_asked: usize,
    gcus: Vec<GcuFound>,
    /// On a bus: its group and the sweep of its devices.
    bus: Option<(u8, PortFound)>,
    problems: Vec<Value>,
    collisions: Vec<Value>,
    probes: u64,
}

struct Scan<'a> {
    session: Session,
    args: &'a ScanArgs,
    progress: Progress,
    found: Found,
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

impl Probe {
    /// Whether the probe went onto a bus (a GCU's refusal does not: no
    /// such port, port closed, no route), so that `--interval` applies.
    fn reached_a_bus(&self) -> bool {
        !matches!(self, Probe::Port(_) | Probe::Unreachable)
    }
}

impl Scan<'_> {
    fn problem(&mut self, at: Address, e: &CtlError) {
        self.found.problems.push(json!({
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

    /// D? to `at`; then a short listen for a second answer. One step of the progress.
    async fn identify(&mut self, at: Address) -> Result<Probe, CtlError> {
        self.session.to = at;
        self.found.probes += 1;
        self.progress
            .advance(1, format!("D? to {at}; {} device(s) found", self.devices_found()));
        let payload = crate::request::encode(&Command::Identify)?;
        let result = self.session.exchange(&Command::Identify, &payload).await;
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
                        Probe::Failed
                    } else if let Some(id) = identity(p) {
                        self.check_collision(at, &id, &ex).await?;
                        Probe::Found(id)
                    } else {
                        let e = CtlError::BadReply(format!(
                            "D? result from {at} is no Table 6 identity: \"{}\"",
                            payload_text(p)
                        ));
                        self.problem(at, &e);
                        Probe::Failed
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
        if probe.reached_a_bus() {
            self.pause().await;
        }
        Ok(probe)
    }

    fn devices_found(&self) -> usize {
        let on_gcus: usize = self
            .found
            .gcus
            .iter()
            .flat_map(|g| &g.ports)
            .map(|p| p.devices.len())
            .sum();
        on_gcus + self.found.bus.as_ref().map_or(0, |(_, p)| p.devices.len())
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
        self.found.collisions.push(json!({
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
        self.found.probes += 1;
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

    /// The port being swept: the last one of the last GCU, or the bus.
    fn sweeping(&mut self) -> Option<&mut PortFound> {
        match &mut self.found.bus {
            Some((_, port)) => Some(port),
            None => self.found.gcus.last_mut().and_then(|g| g.ports.last_mut()),
        }
    }

    /// A device that answered D? at `at`: its identity, AW and I? results.
    async fn device(&mut self, at: Address, id: Value) -> Result<Value, CtlError> {
        let awake = self.ask(at, Command::AwakeStatus).await?;
        let status = self.ask(at, Command::QueryStatusBits).await?;
        let collision = self.found.collisions.iter().any(|c| c["address"] == at.to_string());
        let mut dev = json!({ "address": at.to_string(), "device": at.device });
        if let (Value::Object(m), Value::Object(idm)) = (&mut dev, id) {
            m.extend(idm);
            m.insert("awake".into(), awake);
            m.insert("status".into(), status);
            m.insert("collision".into(), collision.into());
        }
        Ok(dev)
    }

    /// The devices of `--devices` at `group.port`, into [`Scan::sweeping`]
    /// as they answer; its `state` says when the port is absent or closed.
    async fn devices(&mut self, group: u8, port: u8) -> Result<(), CtlError> {
        let ids = self.args.devices.0.clone();
        for (i, &d) in ids.iter().enumerate() {
            let at = Address::new(group, port, d);
            let (device, silent) = match self.identify(at).await? {
                Probe::Found(id) => (Ok(Some(self.device(at, id).await?)), false),
                Probe::Silent => (Ok(None), true),
                Probe::Port(u) => (Err(u), false),
                Probe::Unreachable | Probe::Failed => (Ok(None), false),
            };
            let Some(sweep) = self.sweeping() else {
                return Ok(());
            };
            sweep.asked = i + 1;
            sweep.silent += u32::from(silent);
            match device {
                Ok(Some(dev)) => {
                    let line = format!("gimbalctl: scan: found {at}: {}", dev["name"]);
                    sweep.devices.push(dev);
                    self.progress.line(&line);
                }
                Ok(None) => {}
                Err(u) => {
                    sweep.state = Some(u);
                    // The port's other IDs are not asked: done, as far as the progress goes.
                    let rest = (ids.len() - i - 1) as u64;
                    self.progress.advance(rest, format!("{group}.{port}: {}", u.describe()));
                    return Ok(());
                }
            }
        }
        Ok(())
    }

    /// Through gcud: the GCU of each group of `--gcus`, each port of
    /// `--ports` on those that answered, the devices of `--devices` on each.
    async fn through_gcu(&mut self) -> Result<(), CtlError> {
        let per_gcu = (self.args.ports.0.len() * self.args.devices.0.len()) as u64;
        for group in self.args.gcus.0.clone() {
            let at = Address::new(group, 0, 0);
            self.found.groups_asked += 1;
            let Probe::Found(id) = self.identify(at).await? else {
                continue;
            };
            self.progress.plan(per_gcu);
            self.progress.line(&format!(
                "gimbalctl: scan: GCU {group} answered: {:?}; its ports {} next",
                id["name"].as_str().unwrap_or_default(),
                self.args.ports
            ));
            self.found.gcus.push(GcuFound {
                group,
                id,
                ports: Vec::new(),
            });
            for port in self.args.ports.0.clone() {
                if let Some(gcu) = self.found.gcus.last_mut() {
                    gcu.ports.push(PortFound::new(port));
                }
                self.devices(group, port).await?;
                let Some(swept) = self.sweeping() else { continue };
                match swept.state {
                    Some(Undelivered::NoSuchPort) => {
                        if let Some(gcu) = self.found.gcus.last_mut() {
                            gcu.ports.pop();
                        }
                    }
                    Some(_) => {}
                    None => {
                        let line = format!(
                            "gimbalctl: scan: port {group}.{port}: {} found, {} silent",
                            swept.devices.len(),
                            swept.silent
                        );
                        self.progress.line(&line);
                    }
                }
            }
        }
        Ok(())
    }

    /// On a bus: the devices of `--devices` at `--bus`.
    async fn on_the_bus(&mut self) -> Result<(), CtlError> {
        let (group, port) = self.args.bus;
        self.found.bus = Some((group, PortFound::new(port)));
        self.devices(group, port).await
    }
}

impl PortFound {
    fn new(port: u8) -> Self {
        Self {
            port,
            state: None,
            devices: Vec::new(),
            silent: 0,
            asked: 0,
        }
    }

    fn json(&self) -> Value {
        json!({
            "port": self.port,
            "state": self.state.map_or("open", Undelivered::name),
            "devices": self.devices,
            "silent": self.silent,
            "asked": self.asked,
        })
    }

    /// Its lines of the tree, each after `indent`; `of` IDs were to be asked.
    fn text(&self, indent: &str, of: usize, out: &mut Vec<String>) {
        for d in &self.devices {
            out.push(format!("{indent}{}", device_line(d)));
        }
        if self.asked == of {
            out.push(format!("{indent}({} of {of} IDs silent)", self.silent));
        } else {
            out.push(format!(
                "{indent}({} of {} IDs asked silent; {} not asked: interrupted)",
                self.silent,
                self.asked,
                of - self.asked
            ));
        }
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

impl Found {
    /// The tree GCU -> port -> device (or the bus), then problems and collisions.
    fn text(&self, args: &ScanArgs, line: &str, interrupted: bool) -> String {
        let of = args.devices.0.len();
        let mut text = Vec::new();
        if let Some((group, port)) = &self.bus {
            text.push(format!("bus {group}.{} ({line})", port.port));
            match port.state {
                Some(u) => text.push(format!("  {}", u.describe())),
                None => port.text("  ", of, &mut text),
            }
        } else {
            for gcu in &self.gcus {
                text.push(format!(
                    "GCU {} ({})  {:?}  serial {:?}  revision {}",
                    gcu.group,
                    Address::new(gcu.group, 0, 0),
                    gcu.id["name"].as_str().unwrap_or_default(),
                    gcu.id["serial"].as_str().unwrap_or_default(),
                    gcu.id["revision"].as_str().unwrap_or_default()
                ));
                // A port interrupted before its first answer says nothing yet.
                for port in gcu.ports.iter().filter(|p| p.asked > 0) {
                    match port.state {
                        Some(u) => text.push(format!("  port {}: {}", port.port, u.describe())),
                        None => {
                            text.push(format!("  port {}", port.port));
                            port.text("    ", of, &mut text);
                        }
                    }
                }
            }
            if self.gcus.is_empty() {
                text.push(match interrupted {
                    false => format!("no GCU answered D? at any of {} groups", self.groups_asked),
                    true => format!(
                        "no GCU answered D? at the {} of {} groups asked before the interrupt",
                        self.groups_asked,
                        args.gcus.0.len()
                    ),
                });
            }
        }
        if !self.problems.is_empty() {
            text.push("problems (the scan went on):".into());
            for p in &self.problems {
                text.push(format!(
                    "  {}: {} ({})",
                    p["address"].as_str().unwrap_or_default(),
                    p["error"].as_str().unwrap_or_default(),
                    p["outcome"].as_str().unwrap_or_default()
                ));
            }
        }
        if !self.collisions.is_empty() {
            text.push("collisions (more than one answer to one address: duplicate device IDs?):".into());
            for c in &self.collisions {
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
        text.join("\n")
    }

    /// The scan's JSON fields (README, "JSON": Scan).
    fn json(&self, line: &str, elapsed: Duration) -> Map<String, Value> {
        let gcus: Vec<Value> = self
            .gcus
            .iter()
            .map(|gcu| {
                let ports: Vec<Value> = gcu.ports.iter().filter(|p| p.asked > 0).map(PortFound::json).collect();
                let mut v =
                    json!({ "group": gcu.group, "address": Address::new(gcu.group, 0, 0).to_string(), "ports": ports });
                if let (Value::Object(m), Value::Object(idm)) = (&mut v, &gcu.id) {
                    m.extend(idm.clone());
                }
                v
            })
            .collect();
        let bus = self.bus.as_ref().map_or(Value::Null, |(group, port)| {
            let mut v = port.json();
            if let Value::Object(m) = &mut v {
                m.insert("group".into(), (*group).into());
            }
            v
        });
        let mut m = Map::new();
        m.insert("line".into(), line.into());
        m.insert("gcus".into(), gcus.into());
        m.insert("bus".into(), bus);
        m.insert("problems".into(), self.problems.clone().into());
        m.insert("collisions".into(), self.collisions.clone().into());
        m.insert("probes".into(), self.probes.into());
        m.insert("elapsed_ms".into(), (elapsed.as_millis() as u64).into());
        m
    }
}

/// A scan interrupted while connecting: nothing found, nothing asked.
fn interrupted_before_a_probe(signal: &str, code: u8) -> CtlError {
    CtlError::Interrupted(
        format!("scan interrupted by {signal} while connecting, before its first probe"),
        code,
        Value::Null,
    )
}

pub async fn scan(g: &Global, args: &ScanArgs) -> Result<(), CtlError> {
    use tokio::signal::unix::{SignalKind, signal};
    let started = Instant::now();
    let timeout = args.timeout;
    // Through a GCU the ACK waits for the device (and a report says why
    // not) within gcud's delivery time-out, shorter than the TCP default
    // ACK time-out: that one stays, or a late report would meet the next probe.
    let to_gcu = g.tcp.is_some() && !g.direct;
    // From here on SIGINT and SIGTERM end the scan: with what it found printed,
    // and a --capture file completed (the session is dropped first).
    let mut int = signal(SignalKind::interrupt())?;
    let mut term = signal(SignalKind::terminate())?;
    let open = Session::open_with(g, Address::new(255, 0, 0), |p| {
        p.retry.retries = 0;
        p.result_timeout = timeout;
        p.nic_window = p.nic_window.min(timeout);
        if !to_gcu {
            p.retry.ack_timeout = timeout;
        }
    });
    let session = tokio::select! {
        session = open => session?,
        _ = int.recv() => return Err(interrupted_before_a_probe("SIGINT", 130)),
        _ = term.recv() => return Err(interrupted_before_a_probe("SIGTERM", 143)),
    };
    let through_gcu = session.gcud;
    let line = session.line.clone();
    // The identity probes planned so far: more as GCUs answer.
    let planned = match through_gcu {
        true => args.gcus.0.len(),
        false => args.devices.0.len(),
    };
    let mut s = Scan {
        session,
        args,
        progress: Progress::new(planned as u64, "addresses"),
        found: Found::default(),
    };
    // What will be asked, before the first probe (a long scan is not silent).
    if through_gcu {
        let every_id = match args.devices.0.len() {
            254 => "",
            _ => " (--devices 1-254 asks every ID)",
        };
        s.progress.line(&format!(
            "gimbalctl: scan: D? to the GCU of groups {} (unrouted groups skipped), then to devices {} \
             on ports {} of each GCU found (absent ports skipped); each silent device costs the GCU's \
             retries on its bus{every_id}",
            args.gcus, args.devices, args.ports,
        ));
    } else {
        let (group, port) = args.bus;
        s.progress.line(&format!(
            "gimbalctl: scan: D? to devices {} at {group}.{port}; up to {timeout} ms per silent address",
            args.devices
        ));
    }
    let interrupted = {
        let sweep = async {
            match through_gcu {
                true => s.through_gcu().await,
                false => s.on_the_bus().await,
            }
        };
        tokio::pin!(sweep);
        tokio::select! {
            swept = &mut sweep => {
                swept?;
                None
            }
            _ = int.recv() => Some(("SIGINT", 130)),
            _ = term.recv() => Some(("SIGTERM", 143)),
        }
    };
    s.progress.clear();
    let fields = s.found.json(&line, started.elapsed());
    let Some((signal, code)) = interrupted else {
        if s.found.gcus.is_empty() && s.devices_found() == 0 {
            // Nothing answered: the tree says so on stdout, the exit code to scripts.
            if !g.json {
                sagebrush_host::outln!("{}", s.found.text(args, &line, false));
            }
            return Err(CtlError::NothingAnswered(
                format!("scan: nothing answered D? at the {} address(es) asked", s.found.probes),
                Value::Object(fields),
            ));
        }
        if g.json {
            let mut value = json!({ "ok": true, "command": "scan" });
            if let Value::Object(m) = &mut value {
                m.extend(fields);
            }
            sagebrush_host::outln!("{value}");
        } else {
            sagebrush_host::outln!("{}", s.found.text(args, &line, false));
        }
        return Ok(());
    };
    // What was found so far: as text here, in the failure object with --json.
    if !g.json {
        sagebrush_host::outln!("{}", s.found.text(args, &line, true));
    }
    Err(CtlError::Interrupted(
        format!(
            "scan interrupted by {signal} after {} probe(s); what it found so far is printed",
            s.found.probes
        ),
        code,
        Value::Object(fields),
    ))
}
