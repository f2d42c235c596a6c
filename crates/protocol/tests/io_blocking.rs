//! `io::blocking` over an in-memory line: the device adapter with
//! byte-by-byte and chunked reads, noise, a damaged frame and a master's
//! NAK; the master adapter with noise, a NAK and retransmission, a damaged
//! result NAKed and sent again, and a silent line.

mod io_pipe;

use std::cell::Cell;
use std::convert::Infallible;

use embedded_io::{ErrorType, Read, ReadReady, Write};
use io_pipe::{Clock, Gimbal, Peer, Pipe, device_answers, device_stream, expected_device_answers, frame, policy};
use sagebrush_protocol::io::Error;
use sagebrush_protocol::io::blocking::{Device, Master};
use sagebrush_protocol::*;

struct Line(Pipe);

impl ErrorType for Line {
    type Error = Infallible;
}

impl Read for Line {
    fn read(&mut self, buf: &mut [u8]) -> Result<usize, Infallible> {
        Ok(self.0.read_into(buf))
    }
}

impl ReadReady for Line {
    fn read_ready(&mut self) -> Result<bool, Infallible> {
        Ok(!self.0.rx.is_empty())
    }
}

impl Write for Line {
    fn write(&mut self, buf: &[u8]) -> Result<usize, Infallible> {
        Ok(self.0.write_from(buf))
    }
    fn flush(&mut self) -> Result<(), Infallible> {
        Ok(())
    }
}

#[test]
fn device_answers_the_same_for_any_chunking() {
    let stream = device_stream();
    assert_eq!(device_answers(), expected_device_answers());
    for chunk in [1, 2, 3, 7, 9, 64, 1024] {
        let line = Line(Pipe::new(&stream, chunk));
        let mut device: Device<Line> = Device::new(line, EndpointConfig::single(12));
        let mut gimbal = Gimbal::default();
        let mut now = 0;
        let mut clock = || {
            now += 1;
            now
        };
        let mut read = 0;
        let end = loop {
            match device.poll(&mut gimbal, &mut clock) {
                Ok(n) => read += n,
                Err(e) => break e,
            }
        };
        assert_eq!(end, Error::EndOfStream, "chunk {chunk}");
        assert_eq!(read, stream.len(), "chunk {chunk}");
        let line = device.io();
        assert_eq!(line.0.reads, stream.len().div_ceil(chunk), "chunk {chunk}");
        assert_eq!(line.0.tx, expected_device_answers(), "chunk {chunk}");
        assert_eq!(gimbal.handled, ["P?", "P?"], "chunk {chunk}");
        let stats = device.endpoint().stats();
        assert_eq!(
            (stats.frames_accepted, stats.naks_sent, stats.results_resent),
            (2, 1, 1)
        );
        let framer = device.endpoint().framer();
        assert_eq!(
            framer.skipped_bytes(),
            5 + 9,
            "chunk {chunk}: the noise and the damaged HO"
        );
        assert_eq!(framer.stats().bad_checksums, 1, "chunk {chunk}");
    }
}

#[test]
fn device_silence_hook_rescans_after_a_false_start() {
    // A false start announcing 16 bytes of payload swallows a whole `AW`.
    let aw = frame(Address::new(5, 1, 12), 2, b"AW");
    let mut stream = vec![0xF8, 0x05, 0x01, 0x0C, 0x02, 0x10];
    stream.extend(&aw);
    let mut device: Device<Line> = Device::new(Line(Pipe::new(&stream, 4)), EndpointConfig::single(12));
    let mut gimbal = Gimbal::default();
    let mut clock = || 0;
    while device.poll(&mut gimbal, &mut clock).is_ok() {}
    assert!(device.io().0.tx.is_empty(), "waits for the false start's bytes");
    device.line_idle(&mut gimbal, &mut clock).unwrap();
    assert_eq!(gimbal.handled, ["AW"]);
    assert_eq!(device.io().0.tx[0], ACK);
}

#[test]
fn device_sends_a_deferred_result() {
    let mut device: Device<Line> = Device::new(Line(Pipe::new(&[], 1)), EndpointConfig::single(12));
    let to = ReplyTo {
        dest: Address::new(2, 1, 12),
        source: 5,
        answered: true,
    };
    device.send_reply(to, &Reply::Position(io_pipe::POSITION)).unwrap();
    let (result, _) = Frame::parse(&device.io().0.tx).unwrap();
    assert_eq!(
        (result.dest, result.source, result.payload()),
        (to.dest, 5, &b"0064FF9C"[..])
    );
}

fn master_line(chunk: usize, noise: &[u8], peer: Peer) -> Line {
    let mut pipe = Pipe::new(noise, chunk);
    pipe.peer = Some(peer);
    Line(pipe)
}

fn query(master: &mut Master<Line>, clock: &Clock) -> io_pipe_result::Got {
    let dest = Address::new(5, 1, 12);
    let command = Command::QueryPosition;
    let frame = FrameBuf::build(dest, 2, |buf| command.encode(buf).map(<[u8]>::len)).unwrap();
    let mut transaction = Transaction::new(dest, &command, policy());
    let exchange = master.transact(&frame, &mut transaction, &mut || clock.tick()).unwrap();
    io_pipe_result::Got::from(&command, exchange)
}

mod io_pipe_result {
    use sagebrush_protocol::io::Exchange;
    use sagebrush_protocol::*;

    /// An exchange's outcome, transmissions and parsed result.
    #[derive(Debug, PartialEq)]
    pub struct Got {
        pub outcome: Outcome,
        pub transmissions: u8,
        pub position: Option<Position>,
    }

    impl Got {
        pub fn from(command: &Command<'_>, exchange: Exchange) -> Self {
            let position = exchange
                .result
                .map(|frame| match Reply::parse(command, frame.frame().payload()) {
                    Ok(Reply::Position(p)) => p,
                    other => panic!("not a position: {other:?}"),
                });
            Self {
                outcome: exchange.outcome,
                transmissions: exchange.transmissions,
                position,
            }
        }
    }
}

#[test]
fn master_through_noise_a_nak_and_a_damaged_result() {
    for chunk in [1, 3, 64] {
        let mut peer = Peer::new(12);
        peer.damage_commands = 1; // the gimbal NAKs the first transmission
        peer.damage_results = 1; // the master NAKs the first result
        let mut master: Master<Line> = Master::new(master_line(chunk, &[0x00, 0x13, 0x41, 0x7E], peer));
        let clock = Clock(Cell::new(0));
        let got = query(&mut master, &clock);
        assert_eq!(got.outcome, Outcome::Result, "chunk {chunk}");
        assert_eq!(got.transmissions, 2, "chunk {chunk}: NAK, then the frame again");
        assert_eq!(got.position, Some(io_pipe::POSITION), "chunk {chunk}");
        let line = &master.io().0;
        let command = frame(Address::new(5, 1, 12), 2, b"P?");
        let mut written = command.clone();
        written.extend(&command);
        written.extend([NAK, ACK]);
        assert_eq!(
            line.tx, written,
            "chunk {chunk}: command twice, NAK for the damaged result, ACK"
        );
        let peer = line.peer.as_ref().unwrap();
        assert_eq!(peer.endpoint.stats().naks_sent, 1);
        assert_eq!(peer.endpoint.stats().results_resent, 1);
        assert_eq!(peer.gimbal.handled, ["P?"]);
        // A second exchange on the same master and framer.
        let got = query(&mut master, &clock);
        assert_eq!((got.outcome, got.transmissions), (Outcome::Result, 1));
    }
}

#[test]
fn master_gives_up_on_a_silent_line() {
    // No peer: nothing ever answers.
    let mut master: Master<Line> = Master::new(Line(Pipe::new(&[], 1)));
    let clock = Clock(Cell::new(0));
    let got = query(&mut master, &clock);
    assert_eq!(got.outcome, Outcome::Failed(TxFailure::NoAck));
    assert_eq!(got.transmissions, 3, "first transmission and two retries");
    assert_eq!(got.position, None);
}
