//! A serial port as the router task reads and writes it (ARCHITECTURE
//! "Data path", "Scale"): configured by the serialport crate as
//! `sagebrush_host::transport::open_serial` configures a line (8N1, no
//! flow control, not exclusive, buffers discarded), read and written
//! through a file of its own registered with tokio, where a read shorter
//! than the buffer ends the readiness until the kernel signals more, as
//! tokio does for a TCP stream. tokio-serial keeps the readiness after
//! every read, so each read of a bus was followed by one that found
//! nothing (`EAGAIN`): a system call per answer a relay does not make.

use std::fs::File;
use std::io::{self, Read, Write};
use std::os::unix::fs::OpenOptionsExt;
use std::pin::Pin;
use std::task::{Context, Poll, ready};

use serialport::{SerialPort, TTYPort};
use tokio::io::unix::AsyncFd;
use tokio::io::{AsyncRead, AsyncWrite, ReadBuf};

use crate::lines::LineStream;

/// An open serial port: its bytes, and its control (line rate).
pub struct SerialLine {
    io: AsyncFd<File>,
    /// The handle the port was configured through, kept to switch its rate
    /// (Table 4 `C0..C7`); never read, never registered with the runtime.
    control: TTYPort,
}

impl std::fmt::Debug for SerialLine {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("SerialLine")
            .field("port", &self.control.name())
            .finish()
    }
}

impl SerialLine {
    /// Opens `path` at `baud`; errors name the port.
    pub fn open(path: &str, baud: u32) -> io::Result<Self> {
        let named = |e: &dyn std::fmt::Display| io::Error::other(format!("serial port {path}: {e}"));
        let mut control = serialport::new(path, baud)
            .data_bits(serialport::DataBits::Eight)
            .parity(serialport::Parity::None)
            .stop_bits(serialport::StopBits::One)
            .flow_control(serialport::FlowControl::None)
            .open_native()
            .map_err(|e| io::Error::other(format!("cannot open serial port {path} at {baud} bit/s: {e}")))?;
        // Not exclusive: the second open below, and a pseudo-terminal left
        // in use by a killed client does not lock others out.
        control.set_exclusive(false).map_err(|e| named(&e))?;
        let file = std::fs::OpenOptions::new()
            .read(true)
            .write(true)
            .custom_flags(nix::libc::O_NOCTTY | nix::libc::O_NONBLOCK)
            .open(path)
            .map_err(|e| named(&e))?;
        control
            .clear(serialport::ClearBuffer::All)
            .map_err(|e| io::Error::other(format!("serial port {path}: cannot flush: {e}")))?;
        // The file is the AsyncFd's for as long as it lives (never
        // forgotten nor closed apart), the I/O safety `AsyncFd::register`
        // asks for, which `new` assumes; `register` is `unsafe`, forbidden
        // here.
        #[allow(deprecated)]
        let io = AsyncFd::new(file).map_err(|e| named(&e))?;
        Ok(Self { io, control })
    }
}

impl LineStream for SerialLine {
    fn set_baud(&mut self, baud: u32) -> io::Result<()> {
        self.control
            .set_baud_rate(baud)
            .map_err(|e| io::Error::other(format!("cannot switch the serial line to {baud} bit/s: {e}")))
    }
}

impl AsyncRead for SerialLine {
    fn poll_read(self: Pin<&mut Self>, cx: &mut Context<'_>, buf: &mut ReadBuf<'_>) -> Poll<io::Result<()>> {
        let this = self.get_mut();
        loop {
            let mut guard = ready!(this.io.poll_read_ready_mut(cx))?;
            let unfilled = buf.initialize_unfilled();
            let wanted = unfilled.len();
            match guard.try_io(|file| file.get_mut().read(unfilled)) {
                Ok(Ok(n)) => {
                    if n < wanted {
                        // The kernel's buffer is empty: wait for its next signal.
                        guard.clear_ready();
                    }
                    buf.advance(n);
                    return Poll::Ready(Ok(()));
                }
                Ok(Err(e)) => return Poll::Ready(Err(e)),
                Err(_would_block) => continue,
            }
        }
    }
}

impl AsyncWrite for SerialLine {
    fn poll_write(self: Pin<&mut Self>, cx: &mut Context<'_>, buf: &[u8]) -> Poll<io::Result<usize>> {
        let this = self.get_mut();
        loop {
            let mut guard = ready!(this.io.poll_write_ready_mut(cx))?;
            match guard.try_io(|file| file.get_mut().write(buf)) {
                Ok(Ok(n)) => {
                    if n < buf.len() {
                        guard.clear_ready();
                    }
                    return Poll::Ready(Ok(n));
                }
                Ok(Err(e)) => return Poll::Ready(Err(e)),
                Err(_would_block) => continue,
            }
        }
    }

    fn poll_flush(self: Pin<&mut Self>, _: &mut Context<'_>) -> Poll<io::Result<()>> {
        Poll::Ready(Ok(()))
    }

    fn poll_shutdown(self: Pin<&mut Self>, _: &mut Context<'_>) -> Poll<io::Result<()>> {
        Poll::Ready(Ok(()))
    }
}
