//! The wires between nodes: latency, loss, damage and FIFO order per
//! direction, links between GCUs coming and going, and delivery of bytes to
//! routers, devices and clients.

use super::*;

impl World {
    /// Bytes over a wire without a line rate (a link, a client's
    /// connection): through the wire's faults, then delivered in order.
    pub(super) fn send_on_wire(&mut self, from: Node, to: Node, bytes: Vec<u8>, epoch: u64) {
        if let Some((at, bytes)) = self.wire(from, to, bytes) {
            self.schedule(
                at,
                Ev::Bytes {
                    to,
                    bytes,
                    epoch,
                    bps: 0,
                },
            );
        }
    }

    pub(super) fn write_link(&mut self, g: usize, link: LinkId, bytes: Vec<u8>) {
        if let Some(i) = self
            .pairs
            .iter()
            .position(|p| p.parent == (g, link) || p.child == (g, link))
        {
            let pair = &self.pairs[i];
            if !pair.up {
                return self.violation(format!("gcu {g} wrote to down {link}"));
            }
            let to = if pair.parent == (g, link) {
                pair.child
            } else {
                pair.parent
            };
            let epoch = pair.epoch;
            let to = Node::Link { g: to.0, link: to.1 };
            self.send_on_wire(Node::Link { g, link }, to, bytes, epoch);
            return;
        }
        if let Some(c) = self.clients.iter().position(|cl| cl.gcu == g && cl.link == link) {
            if !self.clients[c].connected {
                return self.violation(format!("gcu {g} wrote to disconnected client {link}"));
            }
            let epoch = self.clients[c].epoch;
            self.log(format_args!("gcu {g} {link} (client {c}) <- {bytes:02X?}"));
            // Frame by frame: one write may carry an ACK and several frames.
            let mut framer: Framer = Framer::new();
            let written = &mut self.clients[c].written;
            let mut reports = Vec::new();
            framer.feed(&bytes, |e| {
                if let sagebrush_protocol::Event::Frame(f) = e {
                    written.insert(FrameBuf::from_frame(&f).as_bytes().to_vec());
                    if let Ok(r) = DeliveryReport::parse(f.payload()) {
                        reports.push((f.dest.group, r));
                    }
                }
            });
            for (group, report) in reports.into_iter().filter(|(_, r)| r.failure.is_none()) {
                self.window_report_written(c, group, &report);
            }
            let to = Node::Client { c };
            self.send_on_wire(Node::Link { g, link }, to, bytes, epoch);
            return;
        }
        self.violation(format!("gcu {g} wrote to unknown {link}"));
    }

    /// gcud wrote the report `00` to client `c` (`~W`: its port's NIC
    /// window passed with no NIC): no NIC of that command may have reached
    /// the port within the window just passed (1.4.2); one that did was
    /// this command's, and the report then attributes the window to the
    /// wrong outcome.
    fn window_report_written(&mut self, c: usize, group: u8, report: &DeliveryReport) {
        let key = (report.dest, group, report.command_checksum);
        let now = self.now;
        self.window_reports_at.insert(key, now);
        let inside = self
            .nics_at_port
            .get(&key)
            .is_some_and(|at| at.iter().any(|&t| t + NIC_WINDOW >= now && t <= now));
        if inside {
            self.violation(format!(
                "gcu wrote client {c} the end of the NIC window of {} although its NIC came within it",
                report.dest
            ));
        }
    }

    /// A device's ACK or NIC of command `key` reaches gcud's port: a NIC
    /// within the window after the ACK (1.4.2) must not follow a report
    /// `00` written since that ACK (the report came before the window
    /// passed).
    pub(super) fn nic_reaches_port(&mut self, key: CommandKey, bytes: &[u8]) {
        let now = self.now;
        if bytes.first() == Some(&ACK) {
            self.acks_at_port.insert(key, now);
        }
        if !bytes.contains(&NIC) {
            return;
        }
        self.nics_at_port.entry(key).or_default().push(now);
        let ack = self.acks_at_port.get(&key).copied();
        let early_report = ack
            .is_some_and(|ack| now < ack + NIC_WINDOW && self.window_reports_at.get(&key).is_some_and(|&r| r >= ack));
        if early_report {
            self.violation(format!(
                "gcu reported the end of the NIC window of {} before a NIC that came within it",
                key.0
            ));
        }
    }

    /// Faults of one write: dropped, or delivered at a time (FIFO per wire),
    /// perhaps with one byte corrupted.
    pub(super) fn wire(&mut self, from: Node, to: Node, mut bytes: Vec<u8>) -> Option<(u64, Vec<u8>)> {
        let mut damaged = false;
        if !self.quiet && !self.over_tcp(from) && !self.over_tcp(to) {
            if self.rng.chance(self.drop_pm) {
                return None;
            }
            if !bytes.is_empty() && self.rng.chance(self.corrupt_pm) {
                let at = self.rng.below(bytes.len() as u64) as usize;
                bytes[at] ^= self.rng.range(1, 255) as u8;
                damaged = true;
            }
        }
        if let Node::Client { c } = to {
            // A damaged frame can leave a bare 0x06 behind (a phantom ACK)
            // or form another valid frame: the client's wire remembers which.
            let relayed = self.input_from_gcu && bytes.contains(&NIC);
            let bus_tainted = match from {
                Node::Link { g, .. } => self
                    .port_damage
                    .get(&g)
                    .is_some_and(|&t| t <= self.now && self.now - t <= 2 * SILENCE),
                _ => false,
            };
            self.clients[c]
                .wire
                .scheduled(damaged, relayed, bus_tainted && bytes.contains(&NIC));
        }
        let delay = 1 + self.rng.below(self.jitter);
        let last = self.fifo.entry((from, to)).or_insert(0);
        let at = (*last).max(self.now + delay);
        *last = at;
        if let (Node::Port { g, .. }, true) = (to, damaged) {
            self.port_damage.insert(g, at);
        }
        Some((at, bytes))
    }

    /// Whether `node` is a TCP client or its link: its wire loses and
    /// damages nothing.
    fn over_tcp(&self, node: Node) -> bool {
        match node {
            Node::Client { c } => self.clients[c].tcp,
            Node::Link { g, link } => self.clients.iter().any(|cl| cl.tcp && cl.gcu == g && cl.link == link),
            _ => false,
        }
    }

    pub(super) fn pair_up(&mut self, i: usize) {
        let (parent, child) = (self.pairs[i].parent, self.pairs[i].child);
        self.pairs[i].up = true;
        let any = SourceFilter::Any;
        self.input(
            parent.0,
            Input::LinkUp {
                link: parent.1,
                config: LinkConfig::new(LinkKind::Downstream, any.clone()),
            },
        );
        self.input(
            child.0,
            Input::LinkUp {
                link: child.1,
                config: LinkConfig::new(LinkKind::Upstream, any),
            },
        );
    }

    pub(super) fn pair_down(&mut self, i: usize) {
        let (parent, child) = (self.pairs[i].parent, self.pairs[i].child);
        self.pairs[i].up = false;
        self.pairs[i].epoch += 1;
        self.input(parent.0, Input::LinkDown { link: parent.1 });
        self.input(child.0, Input::LinkDown { link: child.1 });
    }

    pub(super) fn deliver(&mut self, to: Node, bytes: Vec<u8>, epoch: u64, bps: u32) {
        match to {
            Node::Device { g, p, d } => {
                let now = self.now;
                let sp = &mut self.gcus[g].ports[p];
                if sp.epoch != epoch {
                    return;
                }
                let port_epoch = sp.epoch;
                let dev = &mut sp.devices[d];
                if dev.bps != bps {
                    return; // another line rate: garbage to this device
                }
                let mut out = Vec::new();
                dev.last_rx = now;
                dev.heard(&bytes);
                dev.ep
                    .receive(&bytes, now, &mut dev.gimbal, &mut |b: &[u8]| out.extend_from_slice(b));
                let sent_at = dev.bps;
                if let Some(new) = dev.gimbal.pending_rate.take() {
                    dev.bps = new;
                }
                let deferred = dev.gimbal.deferred.take();
                self.device_writes(g, p, d, out, port_epoch, sent_at);
                self.schedule(now + SILENCE, Ev::DeviceIdle { g, p, d, since: now });
                if let Some(reply_to) = deferred {
                    let at = self.now + self.rng.range(200, 2_000);
                    self.schedule(at, Ev::Deferred { g, p, d, to: reply_to });
                }
            }
            Node::Port { g, p } => {
                let sp = &self.gcus[g].ports[p];
                if sp.epoch != epoch || !sp.open || sp.bps != bps {
                    return;
                }
                let port = sp.id;
                self.log(format_args!("gcu {g} port {port} -> {bytes:02X?}"));
                self.input(
                    g,
                    Input::Bytes {
                        line: LineId::Port(port),
                        bytes: &bytes,
                    },
                );
            }
            Node::Link { g, link } => {
                let Some(pair) = self
                    .pairs
                    .iter()
                    .find(|p| p.parent == (g, link) || p.child == (g, link))
                else {
                    // A client's link.
                    if let Some(c) = self.clients.iter().position(|cl| cl.gcu == g && cl.link == link) {
                        if self.clients[c].epoch == epoch && self.clients[c].connected {
                            self.input(
                                g,
                                Input::Bytes {
                                    line: LineId::Link(link),
                                    bytes: &bytes,
                                },
                            );
                        }
                    }
                    return;
                };
                if pair.epoch == epoch && pair.up {
                    self.input(
                        g,
                        Input::Bytes {
                            line: LineId::Link(link),
                            bytes: &bytes,
                        },
                    );
                }
            }
            Node::Client { c } => {
                let (damaged, relayed) = self.clients[c].wire.arrived();
                if self.clients[c].epoch == epoch && self.clients[c].connected {
                    self.client_receive(c, &bytes, damaged, relayed);
                }
            }
        }
    }
}
