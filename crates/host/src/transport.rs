//! Byte streams to a bus or a link (ARCHITECTURE "Layers", 3): serial ports via
//! tokio-serial (8N1, 1.5.1) and TCP. Errors name the device or address.

use std::io;
use std::pin::Pin;
use std::task::{Context, Poll};

use tokio::io::{AsyncRead, AsyncWrite, ReadBuf};
use tokio::net::TcpStream;
use tokio_serial::{
    ClearBuffer, DataBits, FlowControl, Parity, SerialPort, SerialPortBuilderExt, SerialStream, StopBits,
};

/// A `--baud` argument: one of the protocol's line rates, in bit/s
/// (a clap value parser).
pub fn parse_baud(text: &str) -> Result<u32, String> {
    text.parse::<sagebrush_protocol::DataRate>()
        .ok()
        .and_then(sagebrush_protocol::DataRate::bits_per_second)
        .ok_or_else(|| format!("{text:?}: {}", sagebrush_protocol::NotAProtocolRate))
}

/// Opens `path` as a serial line at `baud`, 8 data bits, no parity, one
/// stop bit (1.5.1), discarding whatever was waiting in its buffers. The
/// port is opened non-exclusively so that a pseudo-terminal left in use by
/// a killed client does not lock others out.
pub fn open_serial(path: &str, baud: u32) -> io::Result<SerialStream> {
    let port = tokio_serial::new(path, baud)
        .data_bits(DataBits::Eight)
        .parity(Parity::None)
        .stop_bits(StopBits::One)
        .flow_control(FlowControl::None)
        .open_native_async()
        .map_err(|e| io::Error::other(format!("cannot open serial port {path} at {baud} bit/s: {e}")))?;
    let mut port = port;
    port.set_exclusive(false)
        .map_err(|e| io::Error::other(format!("serial port {path}: {e}")))?;
    port.clear(ClearBuffer::All)
        .map_err(|e| io::Error::other(format!("serial port {path}: cannot flush: {e}")))?;
    Ok(port)
}

/// An adapter read latency above this (ms) is warned of: it holds short
/// replies back, so a bus cannot reach its line rate (README "USB adapters").
pub const LATENCY_TIMER_WARN_MS: u32 = 2;

/// The read latency timer (ms) of the USB serial adapter behind `path`
/// (FTDI's `latency_timer`, 16 by default), read from the sysfs mounted at
/// `sys` (`/sys`), `path` resolved through its symbolic links (udev's
/// `/dev/gimbal-bus-1`); None where there is none (another adapter, a pty).
pub fn latency_timer_ms(path: &std::path::Path, sys: &std::path::Path) -> Option<u32> {
    let device = std::fs::canonicalize(path).ok()?;
    let name = device.file_name()?;
    let file = sys.join("class/tty").join(name).join("device/latency_timer");
    std::fs::read_to_string(file).ok()?.trim().parse().ok()
}

/// Changes a serial line's rate (after an acknowledged `C0..C7`, Table 4).
pub fn set_baud(port: &mut SerialStream, baud: u32) -> io::Result<()> {
    port.set_baud_rate(baud)
        .map_err(|e| io::Error::other(format!("cannot switch the serial line to {baud} bit/s: {e}")))
}

/// Connects to `addr` (`host:port`), with the no-delay option a
/// request/response protocol wants.
pub async fn connect_tcp(addr: &str) -> io::Result<TcpStream> {
    let stream = TcpStream::connect(addr)
        .await
        .map_err(|e| io::Error::new(e.kind(), format!("cannot connect to {addr}: {e}")))?;
    tune_tcp(&stream)?;
    Ok(stream)
}

/// Idle time before the first keepalive probe of a TCP line.
pub const KEEPALIVE_IDLE: std::time::Duration = std::time::Duration::from_secs(10);
/// Time between keepalive probes; after [`KEEPALIVE_PROBES`] unanswered
/// ones the connection is reset, so a half-open peer is found in about 25 s.
pub const KEEPALIVE_INTERVAL: std::time::Duration = std::time::Duration::from_secs(5);
pub const KEEPALIVE_PROBES: u32 = 3;

/// Frames go out at once (no Nagle delay), and a half-open peer (a client
/// that hung, a cable pulled) is found by TCP keepalive, so that its link
/// goes down and the dead-man stops what it left moving.
pub fn tune_tcp(stream: &TcpStream) -> io::Result<()> {
    stream.set_nodelay(true)?;
    let keepalive = socket2::TcpKeepalive::new()
        .with_time(KEEPALIVE_IDLE)
        .with_interval(KEEPALIVE_INTERVAL)
        .with_retries(KEEPALIVE_PROBES);
    socket2::SockRef::from(stream).set_tcp_keepalive(&keepalive)
}

/// A serial line or a TCP link, as one stream type.
#[derive(Debug)]
pub enum SerialOrTcp {
    Serial(SerialStream),
    Tcp(TcpStream),
    /// gcud's client listener over TLS (module `tls`).
    Tls(Box<crate::tls::client::TlsStream<TcpStream>>),
}

impl SerialOrTcp {
    /// What the line is, for messages.
    pub fn describe(&self) -> String {
        match self {
            SerialOrTcp::Serial(s) => format!("serial {}", s.name().unwrap_or_default()),
            SerialOrTcp::Tcp(t) => match t.peer_addr() {
                Ok(a) => format!("tcp {a}"),
                Err(_) => "tcp".into(),
            },
            SerialOrTcp::Tls(t) => match t.get_ref().0.peer_addr() {
                Ok(a) => format!("tls {a}"),
                Err(_) => "tls".into(),
            },
        }
    }
}

impl AsyncRead for SerialOrTcp {
    fn poll_read(self: Pin<&mut Self>, cx: &mut Context<'_>, buf: &mut ReadBuf<'_>) -> Poll<io::Result<()>> {
        match self.get_mut() {
            SerialOrTcp::Serial(s) => Pin::new(s).poll_read(cx, buf),
            SerialOrTcp::Tcp(t) => Pin::new(t).poll_read(cx, buf),
            SerialOrTcp::Tls(t) => Pin::new(t.as_mut()).poll_read(cx, buf),
        }
    }
}

impl AsyncWrite for SerialOrTcp {
    fn poll_write(self: Pin<&mut Self>, cx: &mut Context<'_>, buf: &[u8]) -> Poll<io::Result<usize>> {
        match self.get_mut() {
            SerialOrTcp::Serial(s) => Pin::new(s).poll_write(cx, buf),
            SerialOrTcp::Tcp(t) => Pin::new(t).poll_write(cx, buf),
            SerialOrTcp::Tls(t) => Pin::new(t.as_mut()).poll_write(cx, buf),
        }
    }

    fn poll_flush(self: Pin<&mut Self>, cx: &mut Context<'_>) -> Poll<io::Result<()>> {
        match self.get_mut() {
            SerialOrTcp::Serial(s) => Pin::new(s).poll_flush(cx),
            SerialOrTcp::Tcp(t) => Pin::new(t).poll_flush(cx),
            SerialOrTcp::Tls(t) => Pin::new(t.as_mut()).poll_flush(cx),
        }
    }

    fn poll_shutdown(self: Pin<&mut Self>, cx: &mut Context<'_>) -> Poll<io::Result<()>> {
        match self.get_mut() {
            SerialOrTcp::Serial(s) => Pin::new(s).poll_shutdown(cx),
            SerialOrTcp::Tcp(t) => Pin::new(t).poll_shutdown(cx),
            SerialOrTcp::Tls(t) => Pin::new(t.as_mut()).poll_shutdown(cx),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[tokio::test]
    async fn tcp_lines_have_keepalive_and_no_delay() {
        let listener = tokio::net::TcpListener::bind("127.0.0.1:0").await.expect("bind");
        let addr = listener.local_addr().expect("address").to_string();
        let stream = connect_tcp(&addr).await.expect("connect");
        let sock = socket2::SockRef::from(&stream);
        assert!(sock.keepalive().expect("SO_KEEPALIVE"));
        assert_eq!(sock.tcp_keepalive_time().expect("TCP_KEEPIDLE"), KEEPALIVE_IDLE);
        assert_eq!(
            sock.tcp_keepalive_interval().expect("TCP_KEEPINTVL"),
            KEEPALIVE_INTERVAL
        );
        assert_eq!(sock.tcp_keepalive_retries().expect("TCP_KEEPCNT"), KEEPALIVE_PROBES);
        assert!(stream.nodelay().expect("TCP_NODELAY"));
    }
}

#[cfg(test)]
mod latency_tests {
    use super::*;

    #[test]
    fn the_latency_timer_is_read_through_the_devices_links() {
        let root = tempfile::tempdir().unwrap();
        let (dev, sys) = (root.path().join("dev"), root.path().join("sys"));
        std::fs::create_dir_all(&dev).unwrap();
        std::fs::write(dev.join("ttyUSB7"), "").unwrap();
        std::os::unix::fs::symlink(dev.join("ttyUSB7"), dev.join("gimbal-bus-1")).unwrap();
        let attr = sys.join("class/tty/ttyUSB7/device");
        std::fs::create_dir_all(&attr).unwrap();
        std::fs::write(attr.join("latency_timer"), "16\n").unwrap();
        assert_eq!(latency_timer_ms(&dev.join("gimbal-bus-1"), &sys), Some(16));
        std::fs::write(dev.join("pts9"), "").unwrap();
        assert_eq!(latency_timer_ms(&dev.join("pts9"), &sys), None, "no adapter, no timer");
        assert_eq!(latency_timer_ms(&dev.join("absent"), &sys), None);
    }
}
