//! A relay on a serial bus: a fresh pseudo-terminal for gcud's `[[port]]`
//! on one side, a gimbalsim bus's pty on the other, and the bytes carried
//! between them, but for the frames toward the gimbals that a test chooses
//! to lose (a line that drops a frame: the gimbal hears nothing, so it
//! neither ACKs nor NAKs, and gcud's ACK time-out and retransmission
//! follow). Frames are found with the protocol crate's framer; what the
//! gimbals send back passes untouched.

use std::sync::{Arc, Mutex};

use sagebrush_protocol::{Event, Frame, FrameBuf, Framer};
use tokio::io::{AsyncReadExt, AsyncWriteExt};

/// Decides, for each frame on its way to the gimbals, whether it is lost.
pub type Lose = Box<dyn FnMut(&Frame<'_>) -> bool + Send>;

/// A running relay; stops on drop.
#[derive(Debug)]
pub struct Relay {
    /// The path gcud opens (`[[port]] path`).
    pub path: String,
    lost: Arc<Mutex<Vec<(u8, String)>>>,
    stop: Option<tokio::sync::oneshot::Sender<()>>,
    thread: Option<std::thread::JoinHandle<()>>,
}

impl Relay {
    /// A relay in front of the bus at `bus_path` (a gimbalsim pty) that
    /// loses each frame toward it for which `lose` says so.
    pub fn start(bus_path: &str, mut lose: Lose) -> Self {
        let lost = Arc::new(Mutex::new(Vec::new()));
        let (path_tx, path_rx) = std::sync::mpsc::channel();
        let (stop, mut stopped) = tokio::sync::oneshot::channel::<()>();
        let bus_path = bus_path.to_owned();
        let record = Arc::clone(&lost);
        let thread = std::thread::spawn(move || {
            let runtime = tokio::runtime::Builder::new_current_thread()
                .enable_all()
                .build()
                .expect("runtime");
            runtime.block_on(async move {
                let mut master = sagebrush_host::pty::PtyMaster::open().expect("relay pty");
                let mut bus = sagebrush_host::transport::open_serial(&bus_path, 9600).expect("the bus's pty");
                path_tx.send(master.slave_path().display().to_string()).expect("path");
                let mut framer: Framer = Framer::new();
                let (mut from_gcud, mut from_bus) = ([0u8; 512], [0u8; 512]);
                loop {
                    tokio::select! {
                        _ = &mut stopped => return,
                        read = master.read(&mut from_gcud) => {
                            let Ok(n @ 1..) = read else { return };
                            let mut out = Vec::new();
                            framer.feed(&from_gcud[..n], |event| match event {
                                Event::Frame(frame) if lose(&frame) => record.lock().expect("lost").push((
                                    frame.source,
                                    String::from_utf8_lossy(frame.payload()).into_owned(),
                                )),
                                Event::Frame(frame) => out.extend_from_slice(FrameBuf::from_frame(&frame).as_bytes()),
                                Event::Ack => out.push(sagebrush_protocol::ACK),
                                Event::Nak => out.push(sagebrush_protocol::NAK),
                                Event::Nic => out.push(sagebrush_protocol::NIC),
                                // gcud sends no damaged frame on a pty.
                                Event::BadChecksum(_) => {}
                            });
                            if bus.write_all(&out).await.is_err() {
                                return;
                            }
                        }
                        read = bus.read(&mut from_bus) => {
                            let Ok(n @ 1..) = read else { return };
                            if master.write_all(&from_bus[..n]).await.is_err() {
                                return;
                            }
                        }
                    }
                }
            });
        });
        let path = path_rx.recv_timeout(super::HANG_GUARD).expect("the relay's pty");
        Self {
            path,
            lost,
            stop: Some(stop),
            thread: Some(thread),
        }
    }

    /// The frames lost so far: (source group, payload), in order.
    pub fn lost(&self) -> Vec<(u8, String)> {
        self.lost.lock().expect("lost").clone()
    }
}

impl Drop for Relay {
    fn drop(&mut self) {
        if let Some(stop) = self.stop.take() {
            let _ = stop.send(());
        }
        if let Some(thread) = self.thread.take() {
            let _ = thread.join();
        }
    }
}
