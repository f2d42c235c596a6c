//! The MAVLink messages this door composes to answer: COMMAND_ACK for
//! every refusal and result, STATUSTEXT (at most 50 bytes) for what gcud
//! says about who holds a gimbal or why it refused.

use mavlink::dialects::common::{COMMAND_ACK_DATA, MavCmd, MavMessage, MavResult, MavSeverity, STATUSTEXT_DATA};
use sagebrush_client::governance::Controller;
use sagebrush_protocol::Undelivered;

use crate::routing::control::Sender;

/// COMMAND_ACK of `command` to `to`: the one answer builder for every refusal and result.
pub fn ack(command: MavCmd, result: MavResult, to: Sender) -> MavMessage {
    MavMessage::COMMAND_ACK(COMMAND_ACK_DATA {
        command,
        result,
        target_system: to.0,
        target_component: to.1,
        ..COMMAND_ACK_DATA::DEFAULT
    })
}

/// STATUSTEXT's words for `holder` (at most 50 bytes, cut at a character).
pub fn holder_text(holder: &Controller) -> String {
    fit(format!("{holder} controls the gimbal"))
}

/// The words of a refusal by gcud (the holder, or the rule).
pub fn refusal_text(rule: Undelivered, holder: Option<&Controller>) -> String {
    match (rule, holder) {
        (Undelivered::NotInControl, Some(h)) => holder_text(h),
        (Undelivered::NotInControl, None) => "denied by gcud: another link controls the gimbal".to_owned(),
        (Undelivered::TravelLimit, _) => "denied by gcud: beyond the travel limits".to_owned(),
        (Undelivered::KeepOut, _) => "denied by gcud: path enters a keep-out zone".to_owned(),
        _ => "denied by gcud: it does not know where it points".to_owned(),
    }
}

/// `text` cut to STATUSTEXT's 50 bytes at a character boundary.
fn fit(mut text: String) -> String {
    while text.len() > 50 {
        text.pop();
    }
    text
}

/// A STATUSTEXT of `severity`.
pub fn statustext(severity: MavSeverity, text: &str) -> MavMessage {
    MavMessage::STATUSTEXT(STATUSTEXT_DATA {
        severity,
        text: fit(text.to_owned()).as_str().into(),
        id: 0,
        chunk_seq: 0,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn holders_and_refusals_are_told_in_50_bytes() {
        let ops = Controller::Link {
            name: "operators".into(),
            priority: 80,
            via: None,
            yours: false,
        };
        assert_eq!(holder_text(&ops), "link operators (priority 80) controls the gimbal");
        let long = Controller::Link {
            name: "é".repeat(32),
            priority: 80,
            via: None,
            yours: false,
        };
        let text = holder_text(&long);
        assert!(text.len() <= 50 && text.starts_with("link éé"), "{text}");
        assert_eq!(
            refusal_text(Undelivered::KeepOut, Some(&ops)),
            "denied by gcud: path enters a keep-out zone"
        );
        assert_eq!(refusal_text(Undelivered::NotInControl, Some(&ops)), holder_text(&ops));
    }
}
