//! MAVLink 2 over TCP (`tcp_listen`, `tcp`): each connection's bytes are
//! read into messages by the `mavlink` crate's reader (which keeps partial
//! frames between reads) on a blocking thread, and every message this
//! program sends goes to every connection through a bounded queue: a peer
//! that does not read loses messages, it never stalls the others.

use std::io::{self, Read};
use std::net::SocketAddr;
use std::sync::{Arc, Mutex};
use std::time::Duration;

use mavlink::MavHeader;
use mavlink::dialects::common::MavMessage;
use tokio::io::{AsyncReadExt, AsyncWriteExt};
use tokio::net::{TcpListener, TcpStream};
use tokio::sync::mpsc;
use tracing::{info, warn};

use crate::link::Stats;

/// What is done with each intact message that comes in.
pub type Handler = Arc<dyn Fn(MavHeader, MavMessage) + Send + Sync>;

/// The most TCP connections served at once (each has a reader thread).
pub const MAX_CONNECTIONS: usize = 8;
/// Messages waiting to be written to one connection.
const QUEUE: usize = 256;
/// How long a `tcp` endpoint waits before connecting again.
pub const RECONNECT: Duration = Duration::from_secs(2);

/// The open connections' write queues.
#[derive(Debug, Default)]
pub struct Streams {
    conns: Mutex<Vec<mpsc::Sender<Arc<[u8]>>>>,
}

impl Streams {
    /// Queues `bytes` (one frame) for every open connection.
    pub fn send(&self, bytes: &[u8]) {
        let mut conns = self.conns.lock().unwrap_or_else(|p| p.into_inner());
        conns.retain(|c| !c.is_closed());
        if conns.is_empty() {
            return;
        }
        let bytes: Arc<[u8]> = bytes.into();
        for c in conns.iter() {
            let _ = c.try_send(Arc::clone(&bytes));
        }
    }

    /// A new connection's queue, or `None` when [`MAX_CONNECTIONS`] are open.
    fn add(&self) -> Option<mpsc::Receiver<Arc<[u8]>>> {
        let mut conns = self.conns.lock().unwrap_or_else(|p| p.into_inner());
        conns.retain(|c| !c.is_closed());
        if conns.len() >= MAX_CONNECTIONS {
            return None;
        }
        let (tx, rx) = mpsc::channel(QUEUE);
        conns.push(tx);
        Some(rx)
    }
}

/// Chunks read from a socket, as the blocking `Read` the reader wants.
struct Chunks {
    rx: std::sync::mpsc::Receiver<Vec<u8>>,
    chunk: Vec<u8>,
    at: usize,
}

impl Read for Chunks {
    fn read(&mut self, buf: &mut [u8]) -> io::Result<usize> {
        while self.at == self.chunk.len() {
            match self.rx.recv() {
                Ok(chunk) => (self.chunk, self.at) = (chunk, 0),
                Err(_) => return Ok(0),
            }
        }
        let n = buf.len().min(self.chunk.len() - self.at);
        buf[..n].copy_from_slice(&self.chunk[self.at..self.at + n]);
        self.at += n;
        Ok(n)
    }
}

/// Serves one connection until it closes.
async fn serve(stream: TcpStream, peer: SocketAddr, streams: Arc<Streams>, stats: Arc<Stats>, handler: Handler) {
    let Some(mut out) = streams.add() else {
        warn!(%peer, max = MAX_CONNECTIONS, "too many MAVLink TCP connections: refused");
        return;
    };
    let _ = stream.set_nodelay(true);
    let (mut rd, mut wr) = stream.into_split();
    let writer = tokio::spawn(async move {
        while let Some(bytes) = out.recv().await {
            if wr.write_all(&bytes).await.is_err() {
                return;
            }
        }
    });
    let (chunk_tx, chunk_rx) = std::sync::mpsc::channel::<Vec<u8>>();
    let (msg_tx, mut msg_rx) = mpsc::channel::<(MavHeader, MavMessage)>(QUEUE);
    let decoder = tokio::task::spawn_blocking(move || {
        let mut reader = mavlink::MavlinkReader::new(Chunks {
            rx: chunk_rx,
            chunk: Vec::new(),
            at: 0,
        });
        loop {
            match reader.read_any_message::<MavMessage>() {
                Ok(m) => {
                    if msg_tx.blocking_send(m).is_err() {
                        return;
                    }
                }
                Err(mavlink::error::MessageReadError::Parse(_)) => continue,
                Err(_) => return,
            }
        }
    });
    let dispatch = tokio::spawn(async move {
        while let Some((header, message)) = msg_rx.recv().await {
            Stats::count(&stats.received);
            handler(header, message);
        }
    });
    let mut buf = vec![0u8; 4096];
    loop {
        match rd.read(&mut buf).await {
            Ok(0) | Err(_) => break,
            Ok(n) => {
                if chunk_tx.send(buf[..n].to_vec()).is_err() {
                    break;
                }
            }
        }
    }
    // The reader sees the end, then the dispatcher; the writer stops now.
    drop(chunk_tx);
    writer.abort();
    let _ = decoder.await;
    let _ = dispatch.await;
    info!(%peer, "MAVLink TCP connection closed");
}

/// `tcp_listen`: accepts connections for ever.
pub async fn listen(listener: TcpListener, streams: Arc<Streams>, stats: Arc<Stats>, handler: Handler) {
    loop {
        match listener.accept().await {
            Ok((stream, peer)) => {
                info!(%peer, "MAVLink TCP connection accepted");
                tokio::spawn(serve(
                    stream,
                    peer,
                    Arc::clone(&streams),
                    Arc::clone(&stats),
                    Arc::clone(&handler),
                ));
            }
            Err(e) => {
                warn!(error = %e, "accept failed");
                tokio::time::sleep(Duration::from_millis(100)).await;
            }
        }
    }
}

/// `tcp`: keeps a connection to `to` open, connecting again after [`RECONNECT`].
pub async fn connect(to: String, streams: Arc<Streams>, stats: Arc<Stats>, handler: Handler) {
    loop {
        match TcpStream::connect(&to).await {
            Ok(stream) => {
                let peer = stream
                    .peer_addr()
                    .unwrap_or_else(|_| SocketAddr::from(([0, 0, 0, 0], 0)));
                info!(%peer, "MAVLink TCP connected");
                serve(
                    stream,
                    peer,
                    Arc::clone(&streams),
                    Arc::clone(&stats),
                    Arc::clone(&handler),
                )
                .await;
            }
            Err(e) => warn!(to = %to, error = %e, "MAVLink TCP connection failed"),
        }
        tokio::time::sleep(RECONNECT).await;
    }
}
