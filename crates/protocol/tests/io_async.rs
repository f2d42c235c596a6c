//! `io::asynch` over an in-memory async line, run by `embassy_futures`'
//! `block_on`: the device adapter with byte-by-byte and chunked reads,
//! noise, a damaged frame and a master's NAK, its silence timer; the master
//! adapter with noise, a NAK and retransmission, a damaged result NAKed and
//! sent again, and a silent line.

mod io_pipe;

use std::cell::Cell;
use std::convert::Infallible;
use std::future::{Future, poll_fn, ready};
use std::task::Poll;

use embassy_futures::block_on;
use embedded_io_async::{ErrorType, Read, Write};
use io_pipe::{Clock, Gimbal, Peer, Pipe, device_stream, expected_device_answers, frame, policy};
use sagebrush_protocol::io::Error;
use sagebrush_protocol::io::asynch::{Device, Master};
use sagebrush_protocol::*;

/// An async line: a read with nothing waiting stays pending (until the
/// caller's timer wins) unless the line is `closed`, which ends the stream.
struct Line {
    pipe: Pipe,
    closed: bool,
}

impl ErrorType for Line {
    type Error = Infallible;
}

impl Read for Line {
    async fn read(&mut self, buf: &mut [u8]) -> Result<usize, Infallible> {
        poll_fn(|_| {
            if self.pipe.rx.is_empty() && !self.closed {
                Poll::Pending
            } else {
                Poll::Ready(Ok(self.pipe.read_into(buf)))
            }
        })
        .await
    }
}

impl Write for Line {
    async fn write(&mut self, buf: &[u8]) -> Result<usize, Infallible> {
        Ok(self.pipe.write_from(buf))
    }
    async fn flush(&mut self) -> Result<(), Infallible> {
        Ok(())
    }
}

/// A timer that never fires: the read always wins.
fn never() -> impl Future<Output = ()> {
    poll_fn(|_| Poll::Pending)
}

#[test]
fn device_answers_the_same_for_any_chunking() {
    let stream = device_stream();
    assert_eq!(io_pipe::device_answers(), expected_device_answers());
    for chunk in [1, 2, 3, 7, 64, 1024] {
        let line = Line {
            pipe: Pipe::new(&stream, chunk),
            closed: true,
        };
        let mut device: Device<Line> = Device::new(line, EndpointConfig::single(12));
        let mut gimbal = Gimbal::default();
        let mut clock = || 0;
        let mut read = 0;
        let end = block_on(async {
            loop {
                match device.poll(&mut gimbal, &mut clock, never()).await {
                    Ok(n) => read += n,
                    Err(e) => break e,
                }
            }
        });
        assert_eq!(end, Error::EndOfStream, "chunk {chunk}");
        assert_eq!(read, stream.len(), "chunk {chunk}");
        assert_eq!(device.io().pipe.reads, stream.len().div_ceil(chunk), "chunk {chunk}");
        assert_eq!(device.io().pipe.tx, expected_device_answers(), "chunk {chunk}");
        assert_eq!(gimbal.handled, ["P?", "P?"], "chunk {chunk}");
        let stats = device.endpoint().stats();
        assert_eq!(
            (stats.frames_accepted, stats.naks_sent, stats.results_resent),
            (2, 1, 1)
        );
    }
}

#[test]
fn device_silence_timer_rescans_after_a_false_start() {
    // A false start announcing 16 bytes of payload swallows a whole `AW`.
    let aw = frame(Address::new(5, 1, 12), 2, b"AW");
    let mut stream = vec![0xF8, 0x05, 0x01, 0x0C, 0x02, 0x10];
    stream.extend(&aw);
    let line = Line {
        pipe: Pipe::new(&stream, 4),
        closed: false,
    };
    let mut device: Device<Line> = Device::new(line, EndpointConfig::single(12));
    let mut gimbal = Gimbal::default();
    let mut clock = || 0;
    block_on(async {
        // Every byte read while the timer is pending; nothing to answer yet.
        let mut read = 0;
        while read < stream.len() {
            read += device.poll(&mut gimbal, &mut clock, never()).await.unwrap();
        }
        assert!(device.io().pipe.tx.is_empty(), "waits for the false start's bytes");
        // Nothing more comes: the silence timer wins the race.
        assert_eq!(device.poll(&mut gimbal, &mut clock, ready(())).await, Ok(0));
    });
    assert_eq!(gimbal.handled, ["AW"]);
    assert_eq!(device.io().pipe.tx[0], ACK);
}

fn master_line(chunk: usize, noise: &[u8], peer: Option<Peer>) -> Line {
    let mut pipe = Pipe::new(noise, chunk);
    pipe.peer = peer;
    Line { pipe, closed: false }
}

/// `P?` to 5.1.12; the deadline timer jumps the clock to the deadline.
fn query(master: &mut Master<Line>, clock: &Clock) -> (Outcome, u8, Option<Position>) {
    let dest = Address::new(5, 1, 12);
    let command = Command::QueryPosition;
    let frame = FrameBuf::build(dest, 2, |buf| command.encode(buf).map(<[u8]>::len)).unwrap();
    let mut transaction = Transaction::new(dest, &command, policy());
    // Polled only when the read is pending (the adapter polls the read first).
    let sleep_until = |deadline: u64| {
        poll_fn(move |_| {
            clock.0.set(clock.0.get().max(deadline));
            Poll::Ready(())
        })
    };
    let exchange = block_on(master.transact(&frame, &mut transaction, &mut || clock.tick(), sleep_until)).unwrap();
    let position = exchange
        .result
        .map(|frame| match Reply::parse(&command, frame.frame().payload()) {
            Ok(Reply::Position(p)) => p,
            other => panic!("not a position: {other:?}"),
        });
    (exchange.outcome, exchange.transmissions, position)
}

#[test]
fn master_through_noise_a_nak_and_a_damaged_result() {
    for chunk in [1, 3, 64] {
        let mut peer = Peer::new(12);
        peer.damage_commands = 1; // the gimbal NAKs the first transmission
        peer.damage_results = 1; // the master NAKs the first result
        let mut master: Master<Line> = Master::new(master_line(chunk, &[0x00, 0x13, 0x41, 0x7E], Some(peer)));
        let clock = Clock(Cell::new(0));
        let got = query(&mut master, &clock);
        assert_eq!(got, (Outcome::Result, 2, Some(io_pipe::POSITION)), "chunk {chunk}");
        let pipe = &master.io().pipe;
        let command = frame(Address::new(5, 1, 12), 2, b"P?");
        let mut written = command.clone();
        written.extend(&command);
        written.extend([NAK, ACK]);
        assert_eq!(
            pipe.tx, written,
            "chunk {chunk}: command twice, NAK for the damaged result, ACK"
        );
        let peer = pipe.peer.as_ref().unwrap();
        assert_eq!(peer.endpoint.stats().naks_sent, 1);
        assert_eq!(peer.endpoint.stats().results_resent, 1);
        // A second exchange on the same master and framer.
        assert_eq!(query(&mut master, &clock).0, Outcome::Result);
    }
}

#[test]
fn master_gives_up_on_a_silent_line() {
    let mut master: Master<Line> = Master::new(master_line(1, &[], None));
    let clock = Clock(Cell::new(0));
    assert_eq!(query(&mut master, &clock), (Outcome::Failed(TxFailure::NoAck), 3, None));
}
