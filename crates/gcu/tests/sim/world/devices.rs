//! The buses: simulated gimbals (the protocol crate's `DeviceEndpoint`
//! with a small motion model as its handler), their ports, and what happens
//! when a port is lost or opened.

use super::*;

/// Motion axes of a gimbal: pan, tilt, focus, zoom.
pub(super) const AXES: usize = 4;

pub(super) fn motion_axis(c: &Command<'_>) -> Option<usize> {
    match c {
        Command::PanLeft | Command::PanRight => Some(0),
        Command::TiltUp | Command::TiltDown => Some(1),
        Command::FocusFar | Command::FocusNear => Some(2),
        Command::ZoomIn | Command::ZoomOut => Some(3),
        _ => None,
    }
}

pub(super) fn stopped_axes(c: &Command<'_>) -> &'static [usize] {
    match c {
        Command::PanStop => &[0],
        Command::TiltStop => &[1],
        Command::FocusStop => &[2],
        Command::ZoomStop => &[3],
        Command::Halt | Command::Stop | Command::StopMotion => &[0, 1],
        _ => &[],
    }
}

#[derive(Debug, Default)]
pub(super) struct Gimbal {
    pub(super) id: u8,
    pub(super) moving: [bool; AXES],
    pub(super) echo: Vec<u8>,
    pub(super) pending_rate: Option<u32>,
    pub(super) deferred: Option<ReplyTo>,
}

impl DeviceHandler for Gimbal {
    fn handle(&mut self, command: Command<'_>, reply_to: ReplyTo, _now: u64) -> Response<'_> {
        if let Some(axis) = motion_axis(&command) {
            self.moving[axis] = true;
            return Response::Done;
        }
        for &axis in stopped_axes(&command) {
            self.moving[axis] = false;
        }
        match command {
            Command::AwakeStatus => Response::Reply(Reply::AwakeStatus(AwakeStatus::new(0).unwrap_or_default())),
            Command::QueryPosition => Response::Reply(Reply::Position(Position::default())),
            Command::Identify => match Identity::new(self.id, *b"19", b"sim gimbal", b"SIM") {
                Ok(id) => Response::Reply(Reply::Identity(id)),
                Err(_) => Response::Nic,
            },
            Command::Initialize => {
                self.deferred = Some(reply_to);
                Response::Deferred
            }
            Command::SetDataRate(rate) => match rate.bits_per_second() {
                Some(bps) => {
                    self.pending_rate = Some(bps);
                    Response::Done
                }
                None => Response::Nic,
            },
            Command::Extended(Extended::UserParameters, args) if !args.is_empty() => {
                self.echo = args.to_vec();
                Response::Reply(Reply::Raw(&self.echo))
            }
            Command::AutoFocusOn | Command::AutoFocusOff => Response::Nic,
            _ => Response::Done,
        }
    }
}

#[derive(Debug)]
pub(super) struct Device {
    pub(super) ep: DeviceEndpoint,
    pub(super) gimbal: Gimbal,
    pub(super) bps: u32,
    /// Last byte heard: a device abandons a partial frame after silence.
    pub(super) last_rx: u64,
}

#[derive(Debug)]
pub(super) struct SimPort {
    pub(super) id: u8,
    /// The GCU side's line rate.
    pub(super) bps: u32,
    pub(super) open: bool,
    pub(super) epoch: u64,
    pub(super) bound: usize,
    pub(super) stop_bound: usize,
    pub(super) devices: Vec<Device>,
}

impl World {
    pub(super) fn port_lost(&mut self, g: usize, p: usize) {
        let sp = &mut self.gcus[g].ports[p];
        sp.open = false;
        sp.epoch += 1;
        let port = sp.id;
        self.gcus[g].ledger.pending_stops.remove(&port);
        self.input(g, Input::PortLost { port });
    }

    pub(super) fn port_opened(&mut self, g: usize, p: usize) {
        let sp = &mut self.gcus[g].ports[p];
        sp.open = true;
        let port = sp.id;
        self.input(g, Input::PortOpened { port });
    }

    pub(super) fn device_writes(&mut self, g: usize, p: usize, d: usize, out: Vec<u8>, epoch: u64, bps: u32) {
        if out.is_empty() {
            return;
        }
        if let Some((at, bytes)) = self.wire(Node::Device { g, p, d }, Node::Port { g, p }, out) {
            self.schedule(
                at,
                Ev::Bytes {
                    to: Node::Port { g, p },
                    bytes,
                    epoch,
                    bps,
                },
            );
        }
    }
}
