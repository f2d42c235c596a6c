//! Capture started and stopped while a program runs (gcud's SIGUSR1):
//! [`CaptureSwitch`] holds the running capture, and each interface's
//! [`Tap`] follows it, at one atomic load per call while capture is off;
//! [`Tapped`] taps a whole stream.

use std::io;
use std::pin::Pin;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::{Arc, Mutex};
use std::task::{Context, Poll};
use std::time::SystemTime;

use tokio::io::{AsyncRead, AsyncWrite, ReadBuf};

use super::handle::{Capture, InterfaceId};
use super::record::{Direction, Role};

/// The capture a program may start and stop while it runs; [`Tap`]s follow it.
#[derive(Debug, Default)]
pub struct CaptureSwitch {
    on: AtomicBool,
    generation: AtomicU64,
    current: Mutex<Option<Capture>>,
}

impl CaptureSwitch {
    pub fn new() -> Arc<Self> {
        Arc::new(Self::default())
    }

    /// Records into `capture` from now on; returns the capture it replaces (stop it).
    pub fn start(&self, capture: Capture) -> Option<Capture> {
        let mut current = self.current.lock().unwrap_or_else(|e| e.into_inner());
        let old = current.replace(capture);
        self.generation.fetch_add(1, Ordering::AcqRel);
        self.on.store(true, Ordering::Release);
        old
    }

    /// Stops recording; returns the capture to [`Capture::stop`].
    pub fn stop(&self) -> Option<Capture> {
        let mut current = self.current.lock().unwrap_or_else(|e| e.into_inner());
        self.on.store(false, Ordering::Release);
        self.generation.fetch_add(1, Ordering::AcqRel);
        current.take()
    }

    /// Whether a capture is running (it may have stopped itself: see [`Capture::is_active`]).
    pub fn current(&self) -> Option<Capture> {
        self.current.lock().unwrap_or_else(|e| e.into_inner()).clone()
    }

    /// A tap for one interface named `name`.
    pub fn tap(self: &Arc<Self>, name: impl Into<String>, role: Role) -> Tap {
        Tap {
            switch: self.clone(),
            name: name.into(),
            role,
            bound: None,
        }
    }
}

/// One interface's hook into a [`CaptureSwitch`]: call [`Tap::inbound`]
/// with what was read and [`Tap::outbound`] with what is written. While
/// capture is off each call is one atomic load.
#[derive(Debug)]
pub struct Tap {
    switch: Arc<CaptureSwitch>,
    name: String,
    role: Role,
    bound: Option<(u64, Capture, InterfaceId)>,
}

impl Tap {
    #[inline]
    pub fn inbound(&mut self, bytes: &[u8]) {
        if self.switch.on.load(Ordering::Relaxed) {
            self.record(Direction::Inbound, bytes);
        }
    }

    #[inline]
    pub fn outbound(&mut self, bytes: &[u8]) {
        if self.switch.on.load(Ordering::Relaxed) {
            self.record(Direction::Outbound, bytes);
        }
    }

    #[cold]
    fn record(&mut self, dir: Direction, bytes: &[u8]) {
        let at = SystemTime::now();
        let generation = self.switch.generation.load(Ordering::Acquire);
        if self.bound.as_ref().is_none_or(|(g, _, _)| *g != generation) {
            if let Some((_, old, id)) = self.bound.take() {
                old.close_interface(id);
            }
            let Some(capture) = self.switch.current() else { return };
            let id = capture.interface(&self.name, self.role);
            self.bound = Some((generation, capture, id));
        }
        if let Some((_, capture, id)) = &self.bound {
            capture.record(*id, dir, at, bytes);
        }
    }
}

impl Drop for Tap {
    fn drop(&mut self) {
        if let Some((_, capture, id)) = &self.bound {
            capture.close_interface(*id);
        }
    }
}

/// A stream whose bytes a [`Tap`] records: what is read as inbound, what is
/// written as outbound. For programs whose line is one stream (gimbalctl,
/// gimbalsim); gcud taps its pumps directly.
#[derive(Debug)]
pub struct Tapped<S> {
    inner: S,
    tap: Tap,
}

impl<S> Tapped<S> {
    pub fn new(inner: S, tap: Tap) -> Self {
        Self { inner, tap }
    }

    pub fn get_ref(&self) -> &S {
        &self.inner
    }

    pub fn get_mut(&mut self) -> &mut S {
        &mut self.inner
    }
}

impl<S: AsyncRead + Unpin> AsyncRead for Tapped<S> {
    fn poll_read(self: Pin<&mut Self>, cx: &mut Context<'_>, buf: &mut ReadBuf<'_>) -> Poll<io::Result<()>> {
        let this = self.get_mut();
        let before = buf.filled().len();
        let polled = Pin::new(&mut this.inner).poll_read(cx, buf);
        if let Poll::Ready(Ok(())) = &polled {
            let read = &buf.filled()[before..];
            if !read.is_empty() {
                this.tap.inbound(read);
            }
        }
        polled
    }
}

impl<S: AsyncWrite + Unpin> AsyncWrite for Tapped<S> {
    fn poll_write(self: Pin<&mut Self>, cx: &mut Context<'_>, buf: &[u8]) -> Poll<io::Result<usize>> {
        let this = self.get_mut();
        let polled = Pin::new(&mut this.inner).poll_write(cx, buf);
        if let Poll::Ready(Ok(n)) = &polled {
            this.tap.outbound(&buf[..*n]);
        }
        polled
    }

    fn poll_flush(self: Pin<&mut Self>, cx: &mut Context<'_>) -> Poll<io::Result<()>> {
        Pin::new(&mut self.get_mut().inner).poll_flush(cx)
    }

    fn poll_shutdown(self: Pin<&mut Self>, cx: &mut Context<'_>) -> Poll<io::Result<()>> {
        Pin::new(&mut self.get_mut().inner).poll_shutdown(cx)
    }
}
