//! A seed's network, generated: GCUs with their groups, ports and buses of
//! gimbals, links between GCUs, clients, and the faults on every wire.

use super::*;

impl World {
    pub(super) fn generate(seed: u64, trace: bool) -> Self {
        let mut rng = Rng::new(seed);
        let n_gcu = rng.range(1, 3) as usize;
        let mut groups = Vec::new();
        while groups.len() < n_gcu {
            let g = rng.range(1, 60) as u8;
            if !groups.contains(&g) {
                groups.push(g);
            }
        }
        let parents: Vec<usize> = (0..n_gcu)
            .map(|i| if i == 0 { 0 } else { rng.below(i as u64) as usize })
            .collect();
        let mut pairs = Vec::new();
        let mut next_link = vec![10u32; n_gcu];
        for (child, &parent) in parents.iter().enumerate().skip(1) {
            let pl = LinkId(next_link[parent]);
            next_link[parent] += 1;
            let cl = LinkId(next_link[child]);
            next_link[child] += 1;
            pairs.push(Pair {
                parent: (parent, pl),
                child: (child, cl),
                up: true,
                epoch: 0,
            });
        }
        let devices_configured = rng.chance(500);
        let mut gcus = Vec::new();
        for (i, &group) in groups.iter().enumerate() {
            let mut config = RouterConfig::new(group);
            config.name = format!("sim gcu {group}");
            config.serial = format!("SN{seed}").chars().take(20).collect();
            config.links.ack_timeout = 40;
            config.links.retries = 3;
            config.links.queue_bound = rng.range(4, 16) as usize;
            config.links.stop_queue_bound = 16;
            config.links.idle_timeout = 20;
            config.links.answer_timeout = 4_000;
            config.links.long_answer_timeout = 8_000;
            config.links.nic_answer_timeout = 1_500;
            config.links.max_pending = 64;
            // Below the clients' ACK time-out (600), wire delays included.
            config.links.delivery_timeout = 450;
            // Child: default upstream. Every GCU: static routes to its descendants.
            for pair in &pairs {
                if pair.child.0 == i {
                    config.default_upstream = Some(pair.child.1);
                }
            }
            for (d, &dg) in groups.iter().enumerate() {
                let mut hop = d;
                while hop != 0 && parents[hop] != i {
                    hop = parents[hop];
                }
                if d != i && hop != 0 && parents[hop] == i {
                    if let Some(pair) = pairs.iter().find(|p| p.child.0 == hop) {
                        config.static_routes.insert(dg, pair.parent.1);
                    }
                }
            }
            let n_ports = rng.range(1, 3);
            let mut ports = Vec::new();
            let mut port_ids = Vec::new();
            while port_ids.len() < n_ports as usize {
                let p = rng.range(1, 8) as u8;
                if !port_ids.contains(&p) {
                    port_ids.push(p);
                }
            }
            for &pid in &port_ids {
                let n_dev = rng.range(1, 3) as usize;
                let mut ids = Vec::new();
                while ids.len() < n_dev {
                    let d = rng.range(1, 9) as u8;
                    if !ids.contains(&d) {
                        ids.push(d);
                    }
                }
                let bound = rng.range(2, 8) as usize;
                let stop_bound = rng.range(8, 32) as usize;
                // Behind a device server that may stall (fault: stalled line).
                let buffered = rng.chance(250);
                let late_answer_guard = rng.range(0, 200);
                // A line the GCU may write on while a device answers: the
                // next command to a device goes in the window before it.
                let full_duplex = rng.chance(500);
                config.ports.push(PortConfig {
                    bps: 9600,
                    retries: 2,
                    ack_timeout: 20,
                    result_timeout: 150,
                    long_result_timeout: 2_500,
                    nic_window: NIC_WINDOW,
                    broadcast_guard: 30,
                    queue_bound: bound,
                    stop_queue_bound: stop_bound,
                    idle_timeout: 10,
                    devices: devices_configured.then(|| ids.clone()),
                    late_answer_guard,
                    buffered,
                    full_duplex,
                    ..PortConfig::new(pid)
                });
                let single = n_dev == 1 && rng.chance(500);
                let devices = ids
                    .iter()
                    .map(|&id| Device {
                        ep: DeviceEndpoint::new(if single {
                            EndpointConfig::single(id)
                        } else {
                            EndpointConfig::shared(id)
                        }),
                        gimbal: Gimbal {
                            id,
                            ..Gimbal::default()
                        },
                        bps: 9600,
                        last_rx: 0,
                        shadow: Framer::new(),
                        last_command: None,
                    })
                    .collect();
                ports.push(SimPort {
                    id: pid,
                    bps: 9600,
                    open: true,
                    epoch: 0,
                    bound,
                    stop_bound,
                    devices,
                    buffered,
                    stalled_until: 0,
                    late_answer_guard,
                });
            }
            let router = Router::new(config).expect("generated config is valid");
            gcus.push(Gcu {
                group,
                router,
                ports,
                ledger: Ledger::default(),
            });
        }
        let n_clients = rng.range(1, 3) as usize;
        let mut clients = Vec::new();
        for c in 0..n_clients {
            let gcu = rng.below(n_gcu as u64) as usize;
            let group = rng.pick(&[0u8, 100, 101, 102]);
            let filter = if rng.chance(500) {
                SourceFilter::Any
            } else {
                SourceFilter::Only(vec![group])
            };
            // Over TCP (lossless, no faults on its wire), asking for
            // end-of-window reports (`~W`) on every connection.
            let tcp = rng.chance(500);
            clients.push(Client {
                tcp,
                windowed: false,
                ask_window: false,
                gcu,
                link: LinkId(100 + c as u32),
                group,
                filter,
                connected: true,
                epoch: 0,
                framer: Framer::new(),
                state: ClientState::Idle,
                issued: Vec::new(),
                nonces: BTreeSet::new(),
                counter: 0,
                to_issue: rng.range(3, 10) as usize,
                next_at: rng.below(50),
                forced: None,
                nics: 0,
                last_rx: 0,
                written: BTreeSet::new(),
                current: None,
                abandoned: BTreeSet::new(),
                gave_up: BTreeSet::new(),
                tainted_acked: BTreeMap::new(),
                wire: ClientWire::default(),
                last_report: None,
                answering: None,
            });
        }
        let level = rng.below(4);
        let (drop_pm, corrupt_pm) = match level {
            0 => (0, 0),
            1 => (10, 10),
            2 => (30, 20),
            _ => (60, 50),
        };
        let jitter = rng.range(1, 5);
        let mut w = World {
            rng,
            now: 0,
            seq: 0,
            events: BTreeMap::new(),
            fifo: BTreeMap::new(),
            gcus,
            pairs,
            clients,
            quiet: false,
            drop_pm,
            corrupt_pm,
            jitter,
            trace,
            violation: None,
            summary: Summary::default(),
            nicd: BTreeSet::new(),
            nics_at_port: BTreeMap::new(),
            input_from_gcu: false,
            acks_at_port: BTreeMap::new(),
            window_reports_at: BTreeMap::new(),
            port_damage: BTreeMap::new(),
        };
        w.log(format_args!(
            "seed {seed}: {n_gcu} gcus {groups:?}, parents {parents:?}, {n_clients} clients, drop {drop_pm}‰ corrupt {corrupt_pm}‰"
        ));
        w.start();
        w
    }
}
