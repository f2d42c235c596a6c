//! A serial port as the router task reads and writes it (ARCHITECTURE
//! "Data path", "Scale"): configured by the serialport crate as
//! `sagebrush_host::transport::open_serial` configures a line (8N1, no
//! flow control, not exclusive, buffers discarded), read and written
//! through a file of its own registered with tokio, where a read shorter
//! than the buffer ends the readiness until the kernel signals more, as
//! tokio does for a TCP stream. tokio-serial keeps the readiness after
//! every read, so each read of a bus was followed by one that found
//! nothing (`EAGAIN`): a system call per answer a relay does not make.
//!
//! The file is registered for reading only. A pseudo-terminal (and a tty
//! driver's write room) signals "writable" each time the other side takes
//! bytes: registered for both, every command gcud wrote woke it again when
//! the device read it, a wake-up with nothing to do per transaction ("Scale").
//! A write goes straight to the file; only one that finds the kernel's
//! buffer full registers a second descriptor of the port for writability,
//! dropped once the bytes are through.

use std::fs::File;
use std::io::{self, Read, Write};
use std::os::unix::fs::OpenOptionsExt;
use std::pin::Pin;
use std::task::{Context, Poll, ready};

use serialport::{SerialPort, TTYPort};
use tokio::io::unix::AsyncFd;
use tokio::io::{AsyncRead, AsyncWrite, Interest, ReadBuf};

use crate::lines::{LineRate, LineStream};

/// An open serial port's bytes; its rate is switched through the handle
/// it was configured through ([`SerialLine::open`]).
#[derive(Debug)]
pub struct SerialLine {
    /// Registered for reading only (module doc).
    io: AsyncFd<File>,
    /// A second descriptor of the port registered for writability, while a
    /// write waits for room in the kernel's buffer.
    write_room: Option<AsyncFd<File>>,
}

impl SerialLine {
    /// Opens `path` at `baud`: its bytes, and the handle it was configured
    /// through, never read nor registered with the runtime, to switch its
    /// rate (Table 4 `C0..C7`). Errors name the port.
    pub fn open(path: &str, baud: u32) -> io::Result<(Self, TTYPort)> {
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
        let io = register(file, Interest::READABLE).map_err(|e| named(&e))?;
        Ok((Self { io, write_room: None }, control))
    }
}

/// `file` registered with the runtime for `interest`.
fn register(file: File, interest: Interest) -> io::Result<AsyncFd<File>> {
    // The file is the AsyncFd's for as long as it lives (never forgotten
    // nor closed apart), the I/O safety `AsyncFd::register_with_interest`
    // asks for, which `with_interest` assumes; `register_with_interest` is
    // `unsafe`, forbidden here.
    #[allow(deprecated)]
    AsyncFd::with_interest(file, interest)
}

impl LineStream for SerialLine {}

impl LineRate for TTYPort {
    fn set_baud(&mut self, baud: u32) -> io::Result<()> {
        self.set_baud_rate(baud)
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
            if let Some(room) = &mut this.write_room {
                let mut guard = ready!(room.poll_write_ready_mut(cx))?;
                match guard.try_io(|file| file.get_mut().write(buf)) {
                    Ok(Ok(n)) => {
                        if n == buf.len() {
                            this.write_room = None;
                        }
                        return Poll::Ready(Ok(n));
                    }
                    Ok(Err(e)) => return Poll::Ready(Err(e)),
                    Err(_would_block) => continue,
                }
            }
            match this.io.get_mut().write(buf) {
                Err(e) if e.kind() == io::ErrorKind::WouldBlock => {
                    let file = this.io.get_ref().try_clone()?;
                    this.write_room = Some(register(file, Interest::WRITABLE)?);
                }
                done => return Poll::Ready(done),
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

#[cfg(test)]
mod tests {
    use super::*;
    use std::os::fd::AsRawFd;
    use std::time::Duration;
    use tokio::io::AsyncWriteExt;

    const EPOLLOUT: u32 = 0x004;

    /// The events `fd` is registered for in this process's epoll sets
    /// (`/proc/self/fdinfo` of each, "tfd: FD events: HEX ...").
    fn registered(fd: std::os::fd::RawFd) -> Vec<u32> {
        let mut found = Vec::new();
        for entry in std::fs::read_dir("/proc/self/fd").expect("fds").flatten() {
            let epoll = std::fs::read_link(entry.path()).is_ok_and(|l| l.to_string_lossy() == "anon_inode:[eventpoll]");
            let info = std::fs::read_to_string(format!("/proc/self/fdinfo/{}", entry.file_name().to_string_lossy()));
            for line in info.iter().filter(|_| epoll).flat_map(|i| i.lines()) {
                let words: Vec<&str> = line.split_whitespace().collect();
                if let ["tfd:", tfd, "events:", events, ..] = words[..]
                    && tfd.parse() == Ok(fd)
                {
                    found.push(u32::from_str_radix(events, 16).expect("hex"));
                }
            }
        }
        found
    }

    /// The port is registered for reading only (a pseudo-terminal signals
    /// "writable" whenever the device takes bytes: a wake-up per command
    /// otherwise). A write that finds the kernel's buffer full waits for
    /// room (a second descriptor registered for writability then) and goes
    /// through when the device reads; that registration goes after.
    #[tokio::test]
    async fn a_write_that_finds_the_buffer_full_waits_for_room_then_goes_through() {
        let pty = nix::pty::openpty(None, None).expect("a pseudo-terminal");
        let path = std::fs::read_link(format!("/proc/self/fd/{}", pty.slave.as_raw_fd())).expect("its path");
        let (mut line, _control) = SerialLine::open(path.to_str().expect("a path"), 9600).expect("opened");
        let events = registered(line.io.as_raw_fd());
        assert!(
            !events.is_empty() && events.iter().all(|e| e & EPOLLOUT == 0),
            "registered for reading only: {events:x?}"
        );
        let data: Vec<u8> = (0..1 << 20).map(|i: u32| i as u8).collect();
        let mut written = 0;
        let cx = &mut Context::from_waker(std::task::Waker::noop());
        while let Poll::Ready(n) = Pin::new(&mut line).poll_write(cx, &data[written..]) {
            written += n.expect("written");
            assert!(written < data.len(), "the pseudo-terminal took 1 MiB unread");
        }
        let room = line.write_room.as_ref().expect("waiting for room").as_raw_fd();
        assert!(registered(room).iter().any(|e| e & EPOLLOUT != 0), "its room awaited");
        let mut master = File::from(pty.master);
        let total = data.len();
        let reader = std::thread::spawn(move || {
            let (mut got, mut buf) = (Vec::with_capacity(total), vec![0; 65536]);
            while got.len() < total {
                let n = master.read(&mut buf).expect("read");
                got.extend_from_slice(&buf[..n]);
            }
            got
        });
        tokio::time::timeout(Duration::from_secs(60), line.write_all(&data[written..]))
            .await
            .expect("the rest written once the device reads")
            .expect("written");
        assert!(line.write_room.is_none(), "no longer registered for writability");
        assert!(reader.join().expect("reader") == data, "every byte, in order");
    }
}
