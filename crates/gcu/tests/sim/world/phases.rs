//! The run's phases: random traffic, a drain, a final phase in which every
//! client's last commands must end, then the invariants checked at the end
//! and the run's summary.

use super::*;

impl World {
    /// Runs until nothing is left to do or `until`; Err on a violation.
    pub(super) fn run_until(&mut self, until: u64, stop: impl Fn(&World) -> bool) -> Result<(), String> {
        while let Some(t) = self.next_time() {
            if t > until || stop(self) {
                break;
            }
            self.now = self.now.max(t);
            while let Some(entry) = self.events.first_entry() {
                if entry.key().0 > self.now {
                    break;
                }
                let ev = entry.remove();
                self.process(ev);
            }
            for g in 0..self.gcus.len() {
                if self.gcus[g].router.next_deadline().is_some_and(|d| d <= self.now) {
                    self.input(g, Input::Tick);
                }
            }
            for c in 0..self.clients.len() {
                if self.client_deadline(c).is_some_and(|d| d <= self.now) {
                    self.client_poll(c);
                }
            }
            if let Some(v) = &self.violation {
                return Err(v.clone());
            }
        }
        Ok(())
    }

    pub(super) fn random_phase(&mut self) -> Result<(), String> {
        self.run_until(RANDOM_PHASE_CAP, |w| {
            w.clients
                .iter()
                .all(|c| c.to_issue == 0 && matches!(c.state, ClientState::Idle))
        })
    }

    pub(super) fn drain(&mut self) -> Result<(), String> {
        let cap = self.now + DRAIN_CAP;
        self.run_until(cap, |_| false)?;
        if self.next_time().is_some() {
            return Err(format!("network did not settle by t={cap}"));
        }
        Ok(())
    }

    /// Faults off, everything reconnected; each client starts a motion on a
    /// reachable device and disconnects: the dead-man must stop them all.
    pub(super) fn final_phase(&mut self) -> Result<(), String> {
        self.quiet = true;
        self.log(format_args!("final phase"));
        for c in 0..self.clients.len() {
            self.clients[c].to_issue = 0;
        }
        for i in 0..self.pairs.len() {
            if !self.pairs[i].up {
                self.pair_up(i);
            }
        }
        for c in 0..self.clients.len() {
            if !self.clients[c].connected {
                self.client_up(c);
            }
        }
        for g in 0..self.gcus.len() {
            for p in 0..self.gcus[g].ports.len() {
                if !self.gcus[g].ports[p].open {
                    self.port_opened(g, p);
                }
            }
        }
        self.drain()?;
        let mut targets = Vec::new();
        for c in 0..self.clients.len() {
            let reachable: Vec<(usize, usize, usize)> = (0..self.gcus.len())
                .flat_map(|g| (0..self.gcus[g].ports.len()).map(move |p| (g, p)))
                .flat_map(|(g, p)| {
                    let sp = &self.gcus[g].ports[p];
                    (0..sp.devices.len())
                        // At the port's rate, with no switch pending (a `C0..C7`
                        // to one device of a shared bus takes it off the line).
                        .filter(move |&d| sp.devices[d].bps == sp.bps && sp.devices[d].gimbal.pending_rate.is_none())
                        .map(move |d| (g, p, d))
                })
                .collect();
            if reachable.is_empty() {
                continue;
            }
            let (g, p, d) = self.rng.pick(&reachable);
            let motion = self
                .rng
                .pick(&[&b"PL"[..], b"PR", b"TU", b"TD", b"FF", b"FN", b"ZI", b"ZO"]);
            let axis = motion_axis(&Command::parse(motion)).unwrap_or(0);
            let dest = Address::new(
                self.gcus[g].group,
                self.gcus[g].ports[p].id,
                self.gcus[g].ports[p].devices[d].gimbal.id,
            );
            self.clients[c].forced = Some((dest, motion.to_vec()));
            self.clients[c].next_at = self.now;
            targets.push((c, g, p, d, axis));
            // One at a time: a small port queue may not hold every client's.
            self.drain()?;
        }
        for &(c, g, p, d, axis) in &targets {
            if !self.gcus[g].ports[p].devices[d].gimbal.moving[axis] {
                return Err(format!(
                    "quiet network: client {c}'s motion never reached gcu {g} port {} device {}",
                    self.gcus[g].ports[p].id, self.gcus[g].ports[p].devices[d].gimbal.id
                ));
            }
        }
        for c in 0..self.clients.len() {
            self.client_down(c);
        }
        self.drain()?;
        for &(c, g, p, d, axis) in &targets {
            let sp = &self.gcus[g].ports[p];
            if sp.devices[d].bps != sp.bps {
                // Switched to another rate than its bus: no GCU can reach it.
                continue;
            }
            if self.gcus[g].ports[p].devices[d].gimbal.moving[axis] {
                return Err(format!(
                    "dead-man: client {c} gone, gcu {g} port {} device {} still moving on axis {axis}",
                    self.gcus[g].ports[p].id, self.gcus[g].ports[p].devices[d].gimbal.id
                ));
            }
            self.summary.final_motions_checked += 1;
        }
        Ok(())
    }

    pub(super) fn check_end(&mut self) -> Result<(), String> {
        for (g, gcu) in self.gcus.iter().enumerate() {
            let open: Vec<_> = gcu.ledger.accepted.difference(&gcu.ledger.finished).collect();
            if !open.is_empty() {
                return Err(format!("gcu {g}: commands without outcome: {open:?}"));
            }
            if !gcu.ledger.untold.is_empty() {
                return Err(format!(
                    "gcu {g}: origins never told whether these were delivered: {:?}",
                    gcu.ledger.untold
                ));
            }
            if gcu.router.in_progress() != 0 {
                return Err(format!(
                    "gcu {g}: {} commands still in progress",
                    gcu.router.in_progress()
                ));
            }
            let stats = gcu.router.stats();
            for sp in gcu.ports.iter().filter(|sp| sp.buffered) {
                let retransmits = stats.ports.get(&sp.id).map_or(0, |p| p.line.retransmits);
                if retransmits != 0 {
                    return Err(format!(
                        "gcu {g}: {retransmits} retransmissions into the device server of port {}",
                        sp.id
                    ));
                }
            }
            if stats.router.accepted != stats.router.finished() {
                return Err(format!(
                    "gcu {g}: accepted {} != finished {}",
                    stats.router.accepted,
                    stats.router.finished()
                ));
            }
            for sp in &gcu.ports {
                let ps = &stats.ports[&sp.id];
                if ps.queue_high_water > sp.bound + sp.stop_bound {
                    return Err(format!(
                        "gcu {g} port {}: queue reached {} > {}",
                        sp.id, ps.queue_high_water, sp.bound
                    ));
                }
            }
            for (link, ls) in &stats.links {
                if ls.queued != ls.delivered + ls.failed + ls.queue_len as u64 {
                    return Err(format!("gcu {g} {link}: frames unaccounted {ls:?}"));
                }
                if ls.queue_high_water > 32 {
                    return Err(format!("gcu {g} {link}: link queue reached {}", ls.queue_high_water));
                }
            }
        }
        Ok(())
    }

    pub(super) fn finish_summary(&mut self) -> Summary {
        let mut s = self.summary.clone();
        for gcu in &self.gcus {
            let st = gcu.router.stats();
            let r = st.router;
            s.accepted += r.accepted;
            s.results += r.results;
            s.nics += r.nics;
            s.completed += r.completed;
            s.no_result += r.no_result;
            s.unreachable += r.unreachable;
            s.forwarded += r.forwarded;
            s.dropped += r.dropped.total();
            s.dead_man_stops += r.dead_man_stops;
            s.client_repeats += st.links.values().map(|l| l.repeats).sum::<u64>();
            s.rate_switches += st.ports.values().map(|p| p.rate_switches).sum::<u64>();
            s.pipelined += st.ports.values().map(|p| p.pipelined).sum::<u64>();
            s.retransmits += st.ports.values().map(|p| p.line.retransmits).sum::<u64>()
                + st.links.values().map(|l| l.line.retransmits).sum::<u64>();
        }
        s.end_time = self.now;
        s
    }
}
