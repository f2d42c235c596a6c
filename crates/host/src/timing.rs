//! Time-outs of one exchange derived from the line rate (1.4.2: "if no ACK
//! or NAK is received within a time-out period, the message should be
//! re-transmitted"). Everything is in milliseconds, the tick of the
//! protocol crate's state machines on the host.

use sagebrush_protocol::MAX_FRAME_LEN;
use sagebrush_protocol::link::{RetryPolicy, TransactionPolicy};

/// Bits on the wire per byte: start, 8 data, stop (1.5.1).
pub const BITS_PER_BYTE: u64 = 10;

/// Milliseconds `bytes` take on a line at `baud`, rounded up.
pub fn wire_ms(bytes: usize, baud: u32) -> u64 {
    (bytes as u64 * BITS_PER_BYTE * 1000).div_ceil(u64::from(baud.max(1)))
}

/// Default exchange time-outs on a serial line at `baud`:
/// - ACK: our longest frame out plus the ACK back, twice over, + 50 ms turnaround;
/// - result: a longest frame back, twice over, + 250 ms for the device to think;
/// - NIC window after an ACK: two bytes + 40 ms;
/// - `IX` result: 60 s (the sequence drives both axes to their switches);
/// - broadcast guard: a longest frame + 50 ms; 3 retries.
pub fn serial_policy(baud: u32) -> TransactionPolicy {
    TransactionPolicy {
        retry: RetryPolicy {
            ack_timeout: 2 * wire_ms(MAX_FRAME_LEN + 1, baud) + 50,
            retries: 3,
        },
        result_timeout: 2 * wire_ms(MAX_FRAME_LEN, baud) + 250,
        long_result_timeout: 60_000,
        nic_window: wire_ms(2, baud) + 40,
        broadcast_guard: wire_ms(MAX_FRAME_LEN, baud) + 50,
    }
}

/// Default time-outs toward a GCU over TCP: the GCU ACKs at once (hop by
/// hop) but a result crosses its port transaction, retries included.
pub fn tcp_policy() -> TransactionPolicy {
    TransactionPolicy {
        retry: RetryPolicy {
            ack_timeout: 1000,
            retries: 3,
        },
        result_timeout: 5000,
        long_result_timeout: 60_000,
        nic_window: 300,
        broadcast_guard: 200,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn scales_with_baud() {
        assert_eq!(wire_ms(96, 9600), 100);
        let slow = serial_policy(1200);
        let fast = serial_policy(115_200);
        assert!(slow.retry.ack_timeout > 10 * fast.retry.ack_timeout);
        assert_eq!(fast.retry.ack_timeout, 2 * 23 + 50);
    }
}
