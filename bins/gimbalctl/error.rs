//! Why `gimbalctl` failed, each with its documented exit code (see
//! [`crate::cli::EXIT_CODES`]).

use std::fmt;

use sagebrush_client::CommandError;
use sagebrush_protocol::Undelivered;
use serde_json::Value;

use crate::cli::{EXIT_STOP_UNCONFIRMED, EXIT_STOPPED_SHORT, EXIT_WAIT_TIMEOUT};

/// Exit code of an undelivered command: 7 + the report's failure code
/// (ARCHITECTURE "Delivery contract"), so 8..=19, one per reason; the
/// governance's refusals and later rows (codes 0x0D and up) 10 + the code, 23..=27, past
/// the codes of `--wait` and `--for` (20..=22).
pub const fn undelivered_exit_code(failure: Undelivered) -> u8 {
    match failure.code() {
        code @ 0..=0x0C => 7 + code,
        code => 10 + code,
    }
}

/// A failure, with a message naming what was wrong.
#[derive(Debug)]
pub enum CtlError {
    /// The port or connection failed (exit 1).
    Io(String),
    /// The arguments cannot be sent (exit 2).
    Usage(String),
    /// NAK after all retries (exit 3).
    Nak(String),
    /// No ACK after all retries (exit 4).
    NoAck(String),
    /// `scan`: nothing answered D? at any address asked (exit 4); the
    /// scan's JSON fields.
    NothingAnswered(String, Value),
    /// The device answered NIC (exit 5).
    Nic(String),
    /// ACKed but no result in time (exit 6).
    NoResult(String),
    /// A result that is not the command's (exit 7).
    BadReply(String),
    /// A GCU reported that it could not deliver the command, or refused it
    /// (exit 8..=19, 23..=27).
    Undelivered(Undelivered, String),
    /// `--wait`: the motion ended away from its target (exit 20); JSON fields.
    StoppedShort(String, Value),
    /// `--wait`: still moving when the wait timed out (exit 21); JSON fields.
    WaitTimeout(String, Value),
    /// The stop after `--for`/`--hold` was not acknowledged (exit 22): why.
    StopUnconfirmed(String, Box<CtlError>),
    /// SIGINT or SIGTERM ended the command (`--capture`: once the capture
    /// file was complete; `scan`: with what it found so far as JSON
    /// fields) (exit 128 + the signal's number, 130 or 143, as a shell
    /// reports a process killed by it).
    Interrupted(String, u8, Value),
}

impl CtlError {
    pub fn exit_code(&self) -> u8 {
        match self {
            CtlError::Io(_) => 1,
            CtlError::Usage(_) => 2,
            CtlError::Nak(_) => 3,
            CtlError::NoAck(_) | CtlError::NothingAnswered(..) => 4,
            CtlError::Nic(_) => 5,
            CtlError::NoResult(_) => 6,
            CtlError::BadReply(_) => 7,
            CtlError::Undelivered(failure, _) => undelivered_exit_code(*failure),
            CtlError::StoppedShort(..) => EXIT_STOPPED_SHORT,
            CtlError::WaitTimeout(..) => EXIT_WAIT_TIMEOUT,
            CtlError::StopUnconfirmed(..) => EXIT_STOP_UNCONFIRMED,
            CtlError::Interrupted(_, code, _) => *code,
        }
    }

    /// The short name used as `outcome` in JSON.
    pub fn kind(&self) -> &'static str {
        match self {
            CtlError::Io(_) => "io",
            CtlError::Usage(_) => "usage",
            CtlError::Nak(_) => "nak",
            CtlError::NoAck(_) | CtlError::NothingAnswered(..) => "no_ack",
            CtlError::Nic(_) => "nic",
            CtlError::NoResult(_) => "no_result",
            CtlError::BadReply(_) => "bad_result",
            CtlError::Undelivered(failure, _) => failure.name(),
            CtlError::StoppedShort(..) => "stopped_short",
            CtlError::WaitTimeout(..) => "wait_timeout",
            CtlError::StopUnconfirmed(..) => "stop_unconfirmed",
            CtlError::Interrupted(..) => "interrupted",
        }
    }

    /// Extra typed JSON fields of this failure (merged into the error object).
    pub fn detail(&self) -> Value {
        match self {
            CtlError::StoppedShort(_, v)
            | CtlError::WaitTimeout(_, v)
            | CtlError::Interrupted(_, _, v)
            | CtlError::NothingAnswered(_, v) => v.clone(),
            CtlError::StopUnconfirmed(_, why) => serde_json::json!({
                "stop_outcome": why.kind(),
                "stop_exit_code": why.exit_code(),
            }),
            _ => Value::Null,
        }
    }

    fn message(&self) -> &str {
        match self {
            CtlError::Io(m)
            | CtlError::Usage(m)
            | CtlError::Nak(m)
            | CtlError::NoAck(m)
            | CtlError::NothingAnswered(m, _)
            | CtlError::Nic(m)
            | CtlError::NoResult(m)
            | CtlError::BadReply(m)
            | CtlError::Undelivered(_, m)
            | CtlError::StoppedShort(m, _)
            | CtlError::WaitTimeout(m, _)
            | CtlError::StopUnconfirmed(m, _)
            | CtlError::Interrupted(m, _, _) => m,
        }
    }
}

impl fmt::Display for CtlError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.message())
    }
}

impl From<std::io::Error> for CtlError {
    fn from(e: std::io::Error) -> Self {
        CtlError::Io(tls_hint(e.to_string()))
    }
}

/// What a TLS failure with gcud means to its operator (rustls's words
/// name the protocol's event, not the configuration to change).
fn tls_hint(message: String) -> String {
    let hint = if message.contains("close_notify") {
        "gcud closed the TLS connection: its log says why (is your certificate's CN a \
         [[principal]] of its configuration?)"
    } else if message.contains("CertificateRequired") {
        "gcud requires a client certificate: give --tls-cert and --tls-key (or GIMBALCTL_TLS_CERT, GIMBALCTL_TLS_KEY)"
    } else if message.contains("UnknownIssuer") || message.contains("BadSignature") {
        "gcud's certificate is not signed by the CA of --tls-ca"
    } else if message.contains("UnknownCA") || message.contains("DecryptError") {
        "gcud does not trust your certificate: it is not signed by gcud's client_ca"
    } else if message.contains("NotValidForName") {
        "gcud's certificate does not name the host of --tcp (gimbalctl tls init --host)"
    } else {
        return message;
    };
    // rustls's own words, without the link to its manual.
    let words = message.split(": https://").next().unwrap_or(&message);
    format!("{hint} ({words})")
}

impl From<CommandError> for CtlError {
    fn from(e: CommandError) -> Self {
        match e {
            CommandError::Io(m) => CtlError::Io(tls_hint(m)),
            CommandError::Usage(m) => CtlError::Usage(m),
            CommandError::Nak(m) => CtlError::Nak(m),
            CommandError::NoAck(m) => CtlError::NoAck(m),
            CommandError::Nic(m) => CtlError::Nic(m),
            CommandError::NoResult(m) => CtlError::NoResult(m),
            CommandError::BadReply(m) => CtlError::BadReply(m),
            // A refusal is no failure to deliver: the GCU's rules kept it from the bus.
            CommandError::Refused(failure, m) => CtlError::Undelivered(
                failure,
                m.replacen("refused by gcud: ", "refused, nothing sent to the gimbal: ", 1),
            ),
            CommandError::Undelivered(failure, m) if failure.is_refusal() => CtlError::Undelivered(
                failure,
                m.replacen("not delivered: ", "refused, nothing sent to the gimbal: ", 1)
                    .replacen("(reported by GCU", "(by the rules of GCU", 1),
            ),
            CommandError::Undelivered(failure, m) => CtlError::Undelivered(failure, m),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_tls_failure_says_what_to_change() {
        let closed =
            tls_hint("peer closed connection without sending TLS close_notify: https://docs.rs/rustls/x".into());
        assert!(
            closed.contains("[[principal]]") && !closed.contains("https://"),
            "{closed}"
        );
        let required = tls_hint("received fatal alert: CertificateRequired".into());
        assert!(required.contains("--tls-cert"), "{required}");
        assert_eq!(tls_hint("Connection reset by peer".into()), "Connection reset by peer");
    }

    #[test]
    fn every_report_row_has_its_own_exit_code_apart_from_the_others() {
        let codes: Vec<u8> = Undelivered::ALL.iter().map(|f| undelivered_exit_code(*f)).collect();
        let mut unique = codes.clone();
        unique.sort_unstable();
        unique.dedup();
        assert_eq!(unique.len(), codes.len(), "{codes:?}");
        for code in codes {
            assert!(
                (8..=19).contains(&code) || (23..=32).contains(&code),
                "{code} clashes with the exit codes of --wait and --for (20..=22)"
            );
        }
        assert_eq!(undelivered_exit_code(Undelivered::NotInControl), 23);
        assert_eq!(undelivered_exit_code(Undelivered::Expired), 19);
    }
}
