//! Time-outs of the host's exchanges, in milliseconds (the tick of the
//! protocol crate's state machines on the host). On a serial line they are
//! the protocol crate's defaults ([`TransactionPolicy::serial`], the one
//! place they are derived from the line rate).

use sagebrush_protocol::MAX_FRAME_LEN;
pub use sagebrush_protocol::link::{BITS_PER_BYTE, wire_ms};
use sagebrush_protocol::link::{RetryPolicy, TransactionPolicy};

/// A bus master's time-outs on a serial line at `baud`: the protocol's
/// defaults, with the ACK wait long enough for the longest frame to go out
/// (the master's clock starts when it writes).
pub fn serial_policy(baud: u32) -> TransactionPolicy {
    TransactionPolicy::serial(baud).for_frame(MAX_FRAME_LEN, baud)
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
    fn a_master_waits_for_the_longest_frame_to_go_out() {
        let p = serial_policy(9600);
        assert_eq!(
            p.retry.ack_timeout,
            TransactionPolicy::serial(9600).retry.ack_timeout + 274
        );
        assert_eq!(wire_ms(MAX_FRAME_LEN, 9600), 274, "263 bytes");
    }
}
