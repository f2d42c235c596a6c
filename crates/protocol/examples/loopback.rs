//! A host and a gimbal on an in-memory "bus": the host runs a
//! `Transaction` for `P?`, the gimbal firmware loop feeds its UART bytes
//! into a `DeviceEndpoint` by DMA (`spare_capacity_mut` + `commit`).
//!
//! `cargo run -p sagebrush-protocol --example loopback`

use sagebrush_protocol::*;

/// The gimbal's command handler: it answers where it points (`P?`) and
/// NICs the rest (the firmware in `firmware/` implements every row).
struct Gimbal(Position);

impl DeviceHandler for Gimbal {
    fn handle(&mut self, command: Command<'_>, _reply_to: ReplyTo, _now: u64) -> Response<'_> {
        match command {
            Command::QueryPosition => Response::Reply(Reply::Position(self.0)),
            _ => Response::Nic,
        }
    }
}

fn main() {
    // ---- host side: build the command frame and start the exchange.
    let dest = Address::new(5, 1, 12);
    let command = Command::QueryPosition;
    let frame = FrameBuf::build(dest, 2, |buf| command.encode(buf).map(<[u8]>::len)).expect("fits");
    let policy = TransactionPolicy {
        retry: RetryPolicy {
            ack_timeout: 50,
            retries: 2,
        },
        result_timeout: 200,
        long_result_timeout: 30_000,
        nic_window: 20,
        broadcast_guard: 20,
    };
    let mut transaction = Transaction::new(dest, &command, policy);
    let mut host_rx: Framer = Framer::new();
    let mut to_device: Vec<u8> = Vec::new();
    let mut to_host: Vec<u8> = Vec::new();
    let mut now = 0;
    if transaction.start(now) == TransactionStep::Send {
        to_device.extend_from_slice(frame.as_bytes());
    }

    // ---- device side: the firmware loop.
    let mut endpoint: DeviceEndpoint = DeviceEndpoint::new(EndpointConfig::single(12));
    let mut gimbal = Gimbal(Position::new(Angle(100), Angle(-100)));

    let outcome = loop {
        now += 1;
        // UART RX "DMA": at most 4 bytes per tick land in the framer.
        let spare = endpoint.spare_capacity_mut();
        let n = spare.len().min(4).min(to_device.len());
        spare[..n].copy_from_slice(&to_device[..n]);
        to_device.drain(..n);
        endpoint.commit(n, now, &mut gimbal, &mut |bytes: &[u8]| {
            to_host.extend_from_slice(bytes)
        });

        // Host: bytes from the bus into its framer, events into the transaction.
        let mut step = TransactionStep::Wait;
        host_rx.feed(&to_host, |event| {
            if let Event::Frame(f) = event {
                // Frames are acknowledged hop by hop.
                to_device.push(ACK);
                println!(
                    "host: result frame {:?}: {:?}",
                    f.dest,
                    Reply::parse(&command, f.payload())
                );
            }
            if step == TransactionStep::Wait {
                step = transaction.on_event(&event, now);
            }
        });
        to_host.clear();
        if step == TransactionStep::Wait {
            step = transaction.poll(now);
        }
        match step {
            TransactionStep::Send => to_device.extend_from_slice(frame.as_bytes()),
            TransactionStep::Wait => {}
            TransactionStep::Done(outcome) => break outcome,
        }
    };
    println!(
        "host: outcome {outcome:?} after {} transmission(s)",
        transaction.transmissions()
    );
    assert_eq!(outcome, Outcome::Result);

    println!(
        "sizes: FrameBuf {} B, Framer {} B, Framer<263> {} B, DeviceEndpoint {} B, Transaction {} B",
        size_of::<FrameBuf>(),
        size_of::<Framer>(),
        size_of::<Framer<263>>(),
        size_of::<DeviceEndpoint>(),
        size_of::<Transaction>()
    );
}
