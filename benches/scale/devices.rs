//! The devices behind every port of a scale case, all served by one thread
//! (epoll over the pseudo-terminals' master sides and a timerfd): the
//! protocol crate's instant device endpoint, or a bus of `sagebrush-sim`
//! gimbals (the governed case), each line timed at its bit rate as on a
//! half-duplex bus (as `support::paced_device` does for one line): a byte
//! heard is through one byte-time after the line was free, an answer is
//! written when its last byte would be through. Unpaced (`baud` None), an
//! answer is written at once.

use std::cmp::Reverse;
use std::collections::BinaryHeap;
use std::fs::File;
use std::io::{Read, Write};
use std::os::fd::AsFd;
use std::os::unix::fs::OpenOptionsExt;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::time::{Duration, Instant};

use nix::sys::epoll::{Epoll, EpollCreateFlags, EpollEvent, EpollFlags, EpollTimeout};
use nix::sys::time::TimeSpec;
use nix::sys::timerfd::{ClockId, Expiration, TimerFd, TimerFlags, TimerSetTimeFlags};
use sagebrush_protocol::device::{DeviceEndpoint, DeviceHandler, EndpointConfig, ReplyTo, Response};
use sagebrush_protocol::{Angle, Command as Cmd, Position, Reply, ResultKind};

/// What answers on a port's line.
pub enum Model {
    /// `P?` answered with a position at once, every command without a
    /// result acknowledged, the rest NIC.
    Instant(Box<DeviceEndpoint>, InstantGimbal),
    /// A bus of one simulated gimbal (motion, limits of its own).
    Sim(Box<sagebrush_sim::Bus>),
}

impl Model {
    pub fn instant() -> Self {
        Self::Instant(Box::new(DeviceEndpoint::new(EndpointConfig::single(1))), InstantGimbal)
    }

    pub fn sim(port: u8) -> Self {
        let config = sagebrush_sim::BusConfig {
            devices: vec![sagebrush_sim::GimbalConfig {
                serial: format!("SIM-{port}"),
                start_initialized: true,
                ..sagebrush_sim::GimbalConfig::at(1)
            }],
            ..sagebrush_sim::BusConfig::default()
        };
        Self::Sim(Box::new(sagebrush_sim::Bus::new(config, 0).expect("simulated bus")))
    }
}

/// The instant reference gimbal's answers.
#[derive(Debug, Default)]
pub struct InstantGimbal;

impl DeviceHandler for InstantGimbal {
    fn handle(&mut self, command: Cmd<'_>, _: ReplyTo, _: u64) -> Response<'_> {
        match command {
            Cmd::QueryPosition => Response::Reply(Reply::Position(Position {
                pan: Angle(100),
                tilt: Angle(-20),
            })),
            c if c.result_kind() == ResultKind::None => Response::Done,
            _ => Response::Nic,
        }
    }
}

/// One port's device and the state of its line.
struct Line {
    master: File,
    /// Held open so that the master never reads end of file when gcud or
    /// socat close the slave (epoll would report it without end).
    _slave: File,
    model: Model,
    line_free: Instant,
    /// Answer bytes waiting for `due`.
    pending: Vec<u8>,
    due: Option<Instant>,
}

/// The devices' thread and what it counts.
pub struct Devices {
    pub paths: Vec<String>,
    /// Commands each port's device answered (`P?` and every other).
    pub answered: Arc<Vec<AtomicU64>>,
    stop: Arc<AtomicBool>,
    thread: Option<std::thread::JoinHandle<()>>,
}

impl Devices {
    /// `ports` lines, port `i + 1` served by `model(i + 1)`, timed at `baud`.
    pub fn start(ports: usize, baud: Option<u32>, model: impl Fn(u8) -> Model) -> Self {
        let mut lines = Vec::with_capacity(ports);
        let mut paths = Vec::with_capacity(ports);
        for i in 0..ports {
            let (master, path) = super::support::pty();
            nix::fcntl::fcntl(&master, nix::fcntl::FcntlArg::F_SETFL(nix::fcntl::OFlag::O_NONBLOCK))
                .expect("non-blocking master");
            let slave = std::fs::OpenOptions::new()
                .read(true)
                .write(true)
                .custom_flags(nix::libc::O_NOCTTY)
                .open(&path)
                .expect("open the slave");
            // Raw until gcud or socat configure it: no echo of what the device writes.
            let mut t = nix::sys::termios::tcgetattr(&slave).expect("termios");
            nix::sys::termios::cfmakeraw(&mut t);
            nix::sys::termios::tcsetattr(&slave, nix::sys::termios::SetArg::TCSANOW, &t).expect("raw");
            lines.push(Line {
                master,
                _slave: slave,
                model: model(i as u8 + 1),
                line_free: Instant::now(),
                pending: Vec::with_capacity(64),
                due: None,
            });
            paths.push(path);
        }
        let answered: Arc<Vec<AtomicU64>> = Arc::new((0..ports).map(|_| AtomicU64::new(0)).collect());
        let stop = Arc::new(AtomicBool::new(false));
        let thread = {
            let (answered, stop) = (answered.clone(), stop.clone());
            std::thread::spawn(move || serve(lines, baud, &answered, &stop))
        };
        Self {
            paths,
            answered,
            stop,
            thread: Some(thread),
        }
    }

    /// Commands answered so far, per port.
    pub fn counts(&self) -> Vec<u64> {
        self.answered.iter().map(|a| a.load(Ordering::Relaxed)).collect()
    }
}

impl Drop for Devices {
    fn drop(&mut self) {
        self.stop.store(true, Ordering::Relaxed);
        if let Some(t) = self.thread.take() {
            let _ = t.join();
        }
    }
}

const TIMER: u64 = u64::MAX;

fn serve(mut lines: Vec<Line>, baud: Option<u32>, answered: &[AtomicU64], stop: &AtomicBool) {
    let byte = baud.map_or(Duration::ZERO, |b| Duration::from_secs_f64(10.0 / f64::from(b)));
    let epoch = Instant::now();
    let ms = |at: Instant| at.duration_since(epoch).as_millis() as u64;
    let epoll = Epoll::new(EpollCreateFlags::EPOLL_CLOEXEC).expect("epoll");
    let timer = TimerFd::new(ClockId::CLOCK_MONOTONIC, TimerFlags::TFD_NONBLOCK).expect("timerfd");
    epoll
        .add(timer.as_fd(), EpollEvent::new(EpollFlags::EPOLLIN, TIMER))
        .expect("add timer");
    for (i, line) in lines.iter().enumerate() {
        epoll
            .add(line.master.as_fd(), EpollEvent::new(EpollFlags::EPOLLIN, i as u64))
            .expect("add master");
    }
    // Answers (and simulated buses' deadlines) by time; stale entries skipped.
    let mut heap: BinaryHeap<Reverse<(Instant, usize)>> = BinaryHeap::new();
    let mut armed: Option<Instant> = None;
    let mut events = vec![EpollEvent::empty(); 256];
    let mut buf = [0u8; 512];
    let mut answer = Vec::with_capacity(512);
    while !stop.load(Ordering::Relaxed) {
        let next = heap.peek().map(|Reverse((at, _))| *at);
        if next != armed {
            match next {
                Some(at) => {
                    let left = at
                        .saturating_duration_since(Instant::now())
                        .max(Duration::from_nanos(1));
                    timer
                        .set(Expiration::OneShot(TimeSpec::from(left)), TimerSetTimeFlags::empty())
                        .expect("arm");
                }
                None => timer.unset().expect("disarm"),
            }
            armed = next;
        }
        let n = epoll.wait(&mut events, EpollTimeout::from(100u16)).unwrap_or(0);
        for event in &events[..n] {
            let i = event.data();
            if i == TIMER {
                let _ = timer.wait(); // non-blocking: consumes the expiration
                armed = None;
                continue;
            }
            let line = &mut lines[i as usize];
            let Ok(got) = line.master.read(&mut buf) else { continue };
            let read_at = Instant::now();
            line.line_free = line.line_free.max(read_at);
            answer.clear();
            let before = answer.len();
            match &mut line.model {
                Model::Instant(endpoint, handler) => {
                    for b in &buf[..got] {
                        line.line_free += byte;
                        let now = ms(line.line_free);
                        endpoint.receive(std::slice::from_ref(b), now, handler, &mut |out| {
                            if out.len() > 1 {
                                answered[i as usize].fetch_add(1, Ordering::Relaxed);
                            }
                            answer.extend_from_slice(out)
                        });
                    }
                }
                Model::Sim(bus) => {
                    line.line_free += byte * got as u32;
                    bus.receive(&buf[..got], ms(line.line_free));
                }
            }
            if answer.len() > before {
                line.line_free += byte * (answer.len() - before) as u32;
                line.pending.extend_from_slice(&answer);
                line.due = Some(line.line_free);
                heap.push(Reverse((line.line_free, i as usize)));
            }
            if let Model::Sim(bus) = &line.model {
                if let Some(at) = bus.next_deadline() {
                    heap.push(Reverse((epoch + Duration::from_millis(at), i as usize)));
                }
            }
        }
        let now = Instant::now();
        while let Some(&Reverse((at, i))) = heap.peek() {
            if at > now {
                break;
            }
            heap.pop();
            let line = &mut lines[i];
            if let Model::Sim(bus) = &mut line.model {
                let t = ms(now);
                bus.poll(t);
                let mut wrote = false;
                while let Some(out) = bus.pop_due(t) {
                    wrote |= out.bytes.len() > 1;
                    line.pending.extend_from_slice(&out.bytes);
                }
                if wrote {
                    answered[i].fetch_add(1, Ordering::Relaxed);
                }
                if let Some(at) = bus.next_deadline() {
                    heap.push(Reverse((epoch + Duration::from_millis(at.max(t + 1)), i)));
                }
                if !line.pending.is_empty() {
                    let _ = line.master.write_all(&line.pending);
                    line.pending.clear();
                }
                continue;
            }
            if line.due.is_some_and(|due| due <= now) {
                line.due = None;
                let _ = line.master.write_all(&line.pending);
                line.pending.clear();
            }
        }
    }
}
