//! The clients of a scale case: one task per connection on a tokio
//! runtime of their own thread, each doing one exchange at a time (the
//! command, its ACK, its result ACKed, as `benches/gcud.rs`'s client) as
//! fast as the answers come, or a slewing operator's script.

use std::sync::Arc;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::time::{Duration, Instant};

use sagebrush_protocol::{ACK, Address, Command as Cmd, DeliveryReport, Event, FrameBuf, Framer};
use tokio::io::{AsyncReadExt, AsyncWriteExt};
use tokio::net::TcpStream;

/// What a client does.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Script {
    /// `P?` after `P?`, every one timed.
    Query,
    /// Pan left then right, 3 s each, a `P?` every 200 ms renewing the slew's lease.
    Slew,
}

/// One client: where it connects and what it sends.
#[derive(Debug, Clone)]
pub struct Target {
    pub addr: String,
    pub dest: Address,
    pub script: Script,
}

/// The clients' runtime and what they count.
pub struct Clients {
    /// Exchanges completed, per client.
    pub done: Arc<Vec<AtomicU64>>,
    /// Exchanges that ended in a delivery report or nothing in time.
    pub failed: Arc<AtomicU64>,
    measuring: Arc<AtomicBool>,
    stop: Arc<AtomicBool>,
    thread: Option<std::thread::JoinHandle<Vec<u32>>>,
}

impl Clients {
    /// Connects every target and starts its script.
    pub fn start(targets: Vec<Target>) -> Self {
        let done: Arc<Vec<AtomicU64>> = Arc::new(targets.iter().map(|_| AtomicU64::new(0)).collect());
        let failed = Arc::new(AtomicU64::new(0));
        let measuring = Arc::new(AtomicBool::new(false));
        let stop = Arc::new(AtomicBool::new(false));
        let thread = {
            let (done, failed, measuring, stop) = (done.clone(), failed.clone(), measuring.clone(), stop.clone());
            std::thread::spawn(move || {
                let rt = tokio::runtime::Builder::new_current_thread()
                    .enable_all()
                    .build()
                    .expect("runtime");
                rt.block_on(async move {
                    let tasks: Vec<_> = targets
                        .into_iter()
                        .enumerate()
                        .map(|(i, t)| {
                            let shared = (done.clone(), failed.clone(), measuring.clone(), stop.clone());
                            tokio::spawn(run(i, t, shared))
                        })
                        .collect();
                    let mut latencies = Vec::new();
                    for t in tasks {
                        latencies.extend(t.await.expect("client task"));
                    }
                    latencies
                })
            })
        };
        Self {
            done,
            failed,
            measuring,
            stop,
            thread: Some(thread),
        }
    }

    /// Exchanges completed so far, per client.
    pub fn counts(&self) -> Vec<u64> {
        self.done.iter().map(|a| a.load(Ordering::Relaxed)).collect()
    }

    /// From now on every exchange's latency is kept.
    pub fn measure(&self) {
        self.measuring.store(true, Ordering::Relaxed);
    }

    /// Stops the clients; the latencies kept, in microseconds, sorted.
    pub fn stop(mut self) -> Vec<u32> {
        self.measuring.store(false, Ordering::Relaxed);
        self.stop.store(true, Ordering::Relaxed);
        let mut all = self
            .thread
            .take()
            .map(|t| t.join().expect("clients"))
            .unwrap_or_default();
        all.sort_unstable();
        all
    }
}

type Shared = (Arc<Vec<AtomicU64>>, Arc<AtomicU64>, Arc<AtomicBool>, Arc<AtomicBool>);

async fn run(i: usize, target: Target, (done, failed, measuring, stop): Shared) -> Vec<u32> {
    let mut latencies = Vec::new();
    let Ok(mut stream) = TcpStream::connect(&target.addr).await else {
        failed.fetch_add(1, Ordering::Relaxed);
        return latencies;
    };
    stream.set_nodelay(true).expect("nodelay");
    let frame = |c: Cmd<'_>| FrameBuf::build(target.dest, 0, |b| c.encode(b).map(<[u8]>::len)).expect("encode");
    let query = frame(Cmd::QueryPosition);
    let (left, right) = (frame(Cmd::PanLeft), frame(Cmd::PanRight));
    let mut framer = Framer::new();
    let started = Instant::now();
    let mut slewing = None::<bool>;
    while !stop.load(Ordering::Relaxed) {
        let request = match target.script {
            Script::Query => &query,
            Script::Slew => {
                let phase = (started.elapsed().as_secs() / 3) % 2 == 0;
                if slewing != Some(phase) {
                    slewing = Some(phase);
                    if phase { &left } else { &right }
                } else {
                    tokio::time::sleep(Duration::from_millis(200)).await;
                    &query
                }
            }
        };
        let t = Instant::now();
        match exchange(
            &mut stream,
            &mut framer,
            request,
            matches!(request, r if std::ptr::eq(r, &query)),
        )
        .await
        {
            Some(true) => {
                if measuring.load(Ordering::Relaxed) {
                    latencies.push(t.elapsed().as_micros().min(u128::from(u32::MAX)) as u32);
                }
                done[i].fetch_add(1, Ordering::Relaxed);
            }
            Some(false) => {
                failed.fetch_add(1, Ordering::Relaxed);
            }
            None => break,
        }
    }
    latencies
}

/// One exchange: Some(true) delivered (the ACK, and the result when
/// `result` is expected), Some(false) a delivery report or nothing within
/// 5 s, None the connection closed.
async fn exchange(stream: &mut TcpStream, framer: &mut Framer, request: &FrameBuf, result: bool) -> Option<bool> {
    stream.write_all(request.as_bytes()).await.ok()?;
    let (mut acked, mut answered, mut report) = (false, !result, false);
    let mut buf = [0u8; 512];
    let deadline = tokio::time::Instant::now() + Duration::from_secs(5);
    while !(report || (acked && answered)) {
        let n = match tokio::time::timeout_at(deadline, stream.read(&mut buf)).await {
            Err(_) => return Some(false),
            Ok(Ok(0) | Err(_)) => return None,
            Ok(Ok(n)) => n,
        };
        let mut frames = 0;
        framer.feed(&buf[..n], |e| match e {
            Event::Ack => acked = true,
            Event::Frame(f) => {
                frames += 1;
                match DeliveryReport::parse(f.payload()) {
                    Ok(_) => report = true,
                    Err(_) => answered = true,
                }
            }
            _ => {}
        });
        for _ in 0..frames {
            stream.write_all(&[ACK]).await.ok()?;
        }
    }
    Some(!report)
}
