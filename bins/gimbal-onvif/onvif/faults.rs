//! The faults the operations answer with when the gimbal or gcud cannot do
//! what was asked (ONVIF Core 5.11.2 and the PTZ service's fault lists).

use sagebrush_client::CommandError;
use sagebrush_protocol::Undelivered;

use crate::soap::Fault;

/// A failure of the gimbal as a fault naming the reason (never a success).
pub fn gimbal(e: CommandError) -> Fault {
    let sub = match e {
        CommandError::Refused(rule, reason) => return refusal(rule, reason),
        CommandError::Io(_) => "ter:GcudUnreachable",
        CommandError::Undelivered(..) => "ter:NotDelivered",
        CommandError::Nic(_) => "ter:NotSupportedByGimbal",
        CommandError::Usage(_) => return Fault::invalid_arg("ter:OutOfRange", e.to_string()),
        _ => "ter:GimbalFailed",
    };
    Fault::receiver(&["ter:Action", sub], e.to_string())
}

/// A command gcud refused by its rules (ARCHITECTURE "Front doors"), as
/// the fault a VMS expects, with gcud's reason (the holder named):
/// - another link controls the gimbal: `env:Receiver ter:Action
///   ter:NotInControl` (ONVIF Core's generic "Action Failed"; the device
///   cannot act now, the request itself was sound);
/// - beyond a travel limit: `env:Sender ter:InvalidArgVal
///   ter:InvalidPosition` (PTZ: "the requested position is out of bounds");
/// - into a keep-out zone: `env:Sender ter:InvalidArgVal
///   ter:UnreachablePosition` (PTZ: "the requested position is not
///   reachable");
/// - the gimbal's position unknown to gcud while it has limits or zones:
///   `env:Receiver ter:Action ter:PositionUnknown`;
/// - any other of gcud's refusals (a command it cannot bound, a rate or
///   preset it could not learn, stops limited, not permitted):
///   `env:Receiver ter:Action ter:Refused`, gcud's reason in words (it
///   was named "not in control" whatever it was).
fn refusal(rule: Undelivered, reason: String) -> Fault {
    match rule {
        Undelivered::NotInControl => Fault::receiver(&["ter:Action", "ter:NotInControl"], reason),
        Undelivered::TravelLimit => Fault::sender(&["ter:InvalidArgVal", "ter:InvalidPosition"], reason),
        Undelivered::KeepOut => Fault::sender(&["ter:InvalidArgVal", "ter:UnreachablePosition"], reason),
        Undelivered::PositionUnknown => Fault::receiver(&["ter:Action", "ter:PositionUnknown"], reason),
        _ => Fault::receiver(&["ter:Action", "ter:Refused"], reason),
    }
}

/// An operation this device does not offer (ONVIF Core 5.11.2.3).
pub fn not_supported(operation: &str) -> Fault {
    Fault::receiver(
        &["ter:ActionNotSupported"],
        format!("{operation} is not supported by this device"),
    )
}

/// Writing the preset names' file failed.
pub fn state(e: String) -> Fault {
    Fault::receiver(&["ter:Action"], e)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn gcuds_refusals_are_faults_a_vms_expects_with_gcuds_words() {
        let refused = |rule: Undelivered, why: &str| gimbal(CommandError::Refused(rule, why.to_owned()));
        let f = refused(
            Undelivered::NotInControl,
            "refused by gcud: pan right (CCW) until PS for 5.1.1: link operators (priority 80) controls the gimbal",
        );
        assert_eq!(
            (f.sender, f.subcodes.as_slice()),
            (false, &["ter:Action", "ter:NotInControl"][..])
        );
        assert_eq!(f.status(crate::soap::Version::Soap12), 500);
        let text = f.envelope(crate::soap::Version::Soap12);
        assert!(text.contains("link operators (priority 80)"), "{text}");
        let f = refused(Undelivered::TravelLimit, "beyond");
        assert_eq!(
            (f.sender, f.subcodes.as_slice()),
            (true, &["ter:InvalidArgVal", "ter:InvalidPosition"][..])
        );
        let f = refused(Undelivered::KeepOut, "zone");
        assert_eq!(f.subcodes, ["ter:InvalidArgVal", "ter:UnreachablePosition"]);
        let f = refused(Undelivered::PositionUnknown, "where?");
        assert_eq!(f.subcodes, ["ter:Action", "ter:PositionUnknown"]);
        let f = refused(Undelivered::RateUnknown, "which rate?");
        assert_eq!(f.subcodes, ["ter:Action", "ter:Refused"], "not named a control refusal");
        // A failure to deliver stays one.
        let f = gimbal(CommandError::Undelivered(Undelivered::DeviceSilent, "silent".into()));
        assert_eq!(f.subcodes, ["ter:Action", "ter:NotDelivered"]);
    }
}
