//! What gcud decides about the gimbals on its ports (its rules: who
//! controls a gimbal, limits, zones, tours; ARCHITECTURE "Front doors"), as
//! a door asks it: the GCU commands of port 0 (the
//! protocol crate's module `gcu`) to address `G.0.0`, answered by gcud
//! itself, so asking costs no bus time:
//!
//! - `~C PPDD`: who controls gimbal `G.PP.DD` ([`Controller`]);
//! - `~R PPDD`: release it;
//! - `~T?`, `~T+name`, `~T-name`: the tours, start one, stop one;
//! - `~B PPDD`: its travel limits and keep-out zones ([`Rules`]);
//! - `~W`: end-of-window reports on this connection
//!   ([`Client::ask_window_reports`], module `master`).
//!
//! A door shows these decisions (a refusal's holder, the controller on the
//! page, the tours); it keeps no rule of its own.

use std::fmt;

use sagebrush_protocol::gcu::{WINDOW_REPORTS_ON, parse_rules, parse_tour_list, parse_tour_reply, valid_name};
use sagebrush_protocol::{
    Address, CONTROL_UNIT, ControllerReply, GcuCommand, LINK_PORT, MAX_PAYLOAD, ResultKind, ResultTimeout, RuleItem,
    TourState,
};
use tokio::io::{AsyncRead, AsyncWrite};

use crate::client::{Client, CommandError};

/// Who controls a gimbal, as gcud answers `~C`.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum Controller {
    /// Nobody: the next link that commands it takes control.
    Nobody,
    /// A principal gcud knows (`via`: the tool or link its commands came
    /// through), or a configured link without principals (every connection
    /// of one listener is one link; `via` `None`); `yours`: the asking
    /// connection's own.
    Link {
        name: String,
        priority: u8,
        via: Option<String>,
        yours: bool,
    },
    /// gcud's tour of this name (below every link).
    Tour(String),
    /// gcud's park (below every link).
    Park,
}

impl fmt::Display for Controller {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Controller::Nobody => f.write_str("nobody"),
            Controller::Link {
                name,
                priority,
                via: None,
                ..
            } => write!(f, "link {name} (priority {priority})"),
            Controller::Link {
                name,
                priority,
                via: Some(via),
                ..
            } => write!(f, "{name} via {via} (priority {priority})"),
            Controller::Tour(name) => write!(f, "tour {name}"),
            Controller::Park => f.write_str("park"),
        }
    }
}

impl Controller {
    /// The holder in a `~C` result about gimbal `port`.`device`.
    pub fn from_result(payload: &[u8], port: u8, device: u8) -> Result<Self, CommandError> {
        let text = |b: &[u8]| String::from_utf8_lossy(b).into_owned();
        match ControllerReply::parse(payload) {
            Some((p, d, reply)) if (p, d) == (port, device) => Ok(match reply {
                ControllerReply::Nobody => Controller::Nobody,
                ControllerReply::Link {
                    priority,
                    name,
                    via,
                    yours,
                } => Controller::Link {
                    name: text(name),
                    priority,
                    via: (!via.is_empty()).then(|| text(via)),
                    yours,
                },
                ControllerReply::Tour(name) => Controller::Tour(text(name)),
                ControllerReply::Park => Controller::Park,
            }),
            _ => Err(CommandError::BadReply(format!(
                "~C result {:?} is not about gimbal {port}.{device}",
                text(payload)
            ))),
        }
    }

    /// The link's name, when a link holds control.
    pub fn link(&self) -> Option<&str> {
        match self {
            Controller::Link { name, .. } => Some(name),
            _ => None,
        }
    }
}

/// A span of one axis in hundredths of a degree, `[lo, hi]`, both ends included.
pub type Span = [i16; 2];

/// A span in degrees.
pub fn degrees(span: Span) -> [f64; 2] {
    span.map(|v| f64::from(v) / 100.0)
}

/// A gimbal's rules as gcud answers `~B`: what a door draws (it decides
/// nothing by them; gcud refuses what breaks them).
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct Rules {
    /// Pan travel no command may leave.
    pub pan_limits: Option<Span>,
    /// Tilt travel no command may leave.
    pub tilt_limits: Option<Span>,
    /// Rectangles no motion may enter: (pan, tilt).
    pub keep_out: Vec<(Span, Span)>,
    /// Presets gcud's park and tours recall: a door stores none of its own there.
    pub reserved: Vec<u8>,
}

impl Rules {
    /// The rules in a `~B` result about gimbal `port`.`device`.
    pub fn from_result(payload: &[u8], port: u8, device: u8) -> Result<Self, CommandError> {
        match parse_rules(payload) {
            Some((p, d, items)) if (p, d) == (port, device) => {
                let mut rules = Rules::default();
                for item in items {
                    match item {
                        RuleItem::PanLimits(s) => rules.pan_limits = Some(s),
                        RuleItem::TiltLimits(s) => rules.tilt_limits = Some(s),
                        RuleItem::KeepOut { pan, tilt } => rules.keep_out.push((pan, tilt)),
                        RuleItem::Reserved(n) => rules.reserved.push(n),
                    }
                }
                Ok(rules)
            }
            _ => Err(CommandError::BadReply(format!(
                "~B result {:?} is not about gimbal {port}.{device}",
                String::from_utf8_lossy(payload)
            ))),
        }
    }
}

/// A tour's state in words (JSON, pages): `running`, `waiting`, `stopped`.
pub fn tour_state_name(state: TourState) -> &'static str {
    state.name()
}

/// One of gcud's tours, as `~T?` lists it.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Tour {
    pub name: String,
    pub state: TourState,
}

/// What became of a tour started or stopped (`~T+`, `~T-`).
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct TourOutcome {
    pub state: TourState,
    /// Started while a link holds the gimbal: the holder it waits for.
    pub waiting_for: Option<String>,
}

/// A GCU command, owned (it waits in a session's queue).
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum GcuRequest {
    /// `~C`: who controls gimbal `port`.`device`.
    Controller(u8, u8),
    /// `~R`: release gimbal `port`.`device`.
    Release(u8, u8),
    /// `~T?`.
    TourList,
    /// `~T+name`.
    TourStart(String),
    /// `~T-name`.
    TourStop(String),
    /// `~B`: the rules of gimbal `port`.`device`.
    Rules(u8, u8),
    /// `~W`: end-of-window reports on this connection.
    WindowReports,
    /// `~U name`: the connection's next commands act for this user of the
    /// door (`None`: for the door itself; ARCHITECTURE "Principals").
    ActFor(Option<String>),
}

/// The answer to a [`GcuRequest`].
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum GcuAnswer {
    Controller(Controller),
    Released,
    Tours(Vec<Tour>),
    Tour(TourOutcome),
    Rules(Rules),
    /// gcud will report the end of each NIC window on this connection.
    WindowReports,
    /// gcud takes the connection's next commands as the user's.
    Acting,
}

impl GcuRequest {
    fn command(&self) -> Result<GcuCommand<'_>, CommandError> {
        let named = |name: &str| {
            if valid_name(name.as_bytes()) {
                Ok(())
            } else {
                Err(CommandError::Usage(format!(
                    "tour name {name:?}: expected 1 to 32 of A-Z a-z 0-9 _ -"
                )))
            }
        };
        Ok(match self {
            GcuRequest::Controller(p, d) => GcuCommand::Controller(*p, *d),
            GcuRequest::Release(p, d) => GcuCommand::Release(*p, *d),
            GcuRequest::TourList => GcuCommand::TourList,
            GcuRequest::Rules(p, d) => GcuCommand::Rules(*p, *d),
            GcuRequest::WindowReports => GcuCommand::WindowReports,
            GcuRequest::ActFor(user) => {
                if let Some(user) = user {
                    if !valid_name(user.as_bytes()) {
                        return Err(CommandError::Usage(format!(
                            "user name {user:?}: gcud knows principals by 1 to 32 of A-Z a-z 0-9 _ -"
                        )));
                    }
                }
                GcuCommand::ActFor(user.as_deref().map(str::as_bytes))
            }
            GcuRequest::TourStart(name) => {
                named(name)?;
                GcuCommand::TourStart(name.as_bytes())
            }
            GcuRequest::TourStop(name) => {
                named(name)?;
                GcuCommand::TourStop(name.as_bytes())
            }
        })
    }

    /// The payload and the answer it gets.
    pub fn encode(&self) -> Result<(Vec<u8>, ResultKind), CommandError> {
        let command = self.command()?;
        let mut buf = [0u8; MAX_PAYLOAD];
        let len = command
            .encode(&mut buf)
            .ok_or_else(|| CommandError::Usage(format!("{self:?} does not fit a frame")))?;
        let expect = if command.has_result() {
            ResultKind::Required(ResultTimeout::Normal)
        } else {
            ResultKind::None
        };
        Ok((buf[..len].to_vec(), expect))
    }

    /// The answer in `result` (the result frame's payload, if any).
    pub fn answer(&self, result: Option<&[u8]>) -> Result<GcuAnswer, CommandError> {
        let text = |b: &[u8]| String::from_utf8_lossy(b).into_owned();
        let bad = |what: &str, payload: &[u8]| {
            CommandError::BadReply(format!("{what} result {:?} is not one of gcud's", text(payload)))
        };
        let payload = match (self, result) {
            (GcuRequest::Release(..), _) => return Ok(GcuAnswer::Released),
            (GcuRequest::ActFor(_), _) => return Ok(GcuAnswer::Acting),
            (_, Some(p)) => p,
            (_, None) => return Err(CommandError::NoResult(format!("gcud sent no result for {self:?}"))),
        };
        match self {
            GcuRequest::Controller(p, d) => Controller::from_result(payload, *p, *d).map(GcuAnswer::Controller),
            GcuRequest::Release(..) => Ok(GcuAnswer::Released),
            GcuRequest::ActFor(_) => Ok(GcuAnswer::Acting),
            GcuRequest::Rules(p, d) => Rules::from_result(payload, *p, *d).map(GcuAnswer::Rules),
            GcuRequest::WindowReports if payload == WINDOW_REPORTS_ON => Ok(GcuAnswer::WindowReports),
            GcuRequest::WindowReports => Err(bad("~W", payload)),
            GcuRequest::TourList => {
                let entries = parse_tour_list(payload).ok_or_else(|| bad("~T?", payload))?;
                let mut tours = Vec::new();
                for entry in entries {
                    let (name, state) = entry.ok_or_else(|| bad("~T?", payload))?;
                    tours.push(Tour {
                        name: text(name),
                        state,
                    });
                }
                Ok(GcuAnswer::Tours(tours))
            }
            GcuRequest::TourStart(_) | GcuRequest::TourStop(_) => {
                let (state, holder) = parse_tour_reply(payload).ok_or_else(|| bad("~T", payload))?;
                Ok(GcuAnswer::Tour(TourOutcome {
                    state,
                    waiting_for: (!holder.is_empty()).then(|| text(holder)),
                }))
            }
        }
    }

    /// As errors name it.
    fn named(&self) -> String {
        match self {
            GcuRequest::Controller(p, d) => format!("~C{p:02X}{d:02X} (who controls {p}.{d})"),
            GcuRequest::Release(p, d) => format!("~R{p:02X}{d:02X} (release {p}.{d})"),
            GcuRequest::TourList => "~T? (the tours)".to_owned(),
            GcuRequest::Rules(p, d) => format!("~B{p:02X}{d:02X} (the rules of {p}.{d})"),
            GcuRequest::WindowReports => "~W (end-of-window reports)".to_owned(),
            GcuRequest::ActFor(Some(user)) => format!("~U{user} (act for user {user})"),
            GcuRequest::ActFor(None) => "~U (act for the door itself)".to_owned(),
            GcuRequest::TourStart(name) => format!("~T+{name} (start tour {name})"),
            GcuRequest::TourStop(name) => format!("~T-{name} (stop tour {name})"),
        }
    }
}

impl<S: AsyncRead + AsyncWrite + Unpin> Client<S> {
    /// `request` to the GCU of `group` (its port 0); its answer. gcud
    /// answers an unknown tour or gimbal NIC ([`CommandError::Nic`]), a
    /// release by a link that may not ([`CommandError::Refused`]).
    pub async fn gcu(&mut self, group: u8, request: &GcuRequest) -> Result<GcuAnswer, CommandError> {
        let (payload, expect) = request.encode()?;
        let to = Address::new(group, LINK_PORT, CONTROL_UNIT);
        let ex = self.exchange_expecting(to, &payload, expect, &request.named()).await?;
        let result = ex.result.as_ref().map(|f| f.frame().payload());
        request.answer(result)
    }

    /// Asks the GCU of `group` for end-of-window reports on this connection
    /// (`~W`); whether it agreed. A GCU that answers NIC (a serial line, an
    /// older gcud) does not send them: the master then waits its own NIC
    /// window after each ACK, as before. Other errors are errors.
    pub async fn ask_window_reports(&mut self, group: u8) -> Result<bool, CommandError> {
        match self.gcu(group, &GcuRequest::WindowReports).await {
            Ok(_) => {
                self.master_mut().set_window_reports(true);
                Ok(true)
            }
            Err(CommandError::Nic(_)) => Ok(false),
            Err(e) => Err(e),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use sagebrush_protocol::gcu::{encode_tour_list, encode_tour_reply};

    #[test]
    fn answers_are_read_into_owned_values() {
        let mut buf = [0u8; 64];
        let n = ControllerReply::Link {
            priority: 80,
            name: b"operators",
            via: b"",
            yours: false,
        }
        .encode(1, 2, &mut buf)
        .unwrap();
        let link = Controller::Link {
            name: "operators".into(),
            priority: 80,
            via: None,
            yours: false,
        };
        assert_eq!(
            GcuRequest::Controller(1, 2).answer(Some(&buf[..n])),
            Ok(GcuAnswer::Controller(link.clone()))
        );
        assert_eq!(link.to_string(), "link operators (priority 80)");
        assert_eq!(link.link(), Some("operators"));
        assert!(
            matches!(
                GcuRequest::Controller(1, 3).answer(Some(&buf[..n])),
                Err(CommandError::BadReply(_))
            ),
            "an answer about another gimbal is not this one's"
        );
        let n = ControllerReply::Tour(b"perimeter").encode(1, 2, &mut buf).unwrap();
        assert_eq!(
            Controller::from_result(&buf[..n], 1, 2).unwrap().to_string(),
            "tour perimeter"
        );

        let n = encode_tour_list(
            [(&b"north"[..], TourState::Running), (b"gate", TourState::Stopped)],
            &mut buf,
        );
        assert_eq!(
            GcuRequest::TourList.answer(Some(&buf[..n])),
            Ok(GcuAnswer::Tours(vec![
                Tour {
                    name: "north".into(),
                    state: TourState::Running
                },
                Tour {
                    name: "gate".into(),
                    state: TourState::Stopped
                },
            ]))
        );
        let n = encode_tour_reply(TourState::Waiting, b"operators", &mut buf).unwrap();
        assert_eq!(
            GcuRequest::TourStart("north".into()).answer(Some(&buf[..n])),
            Ok(GcuAnswer::Tour(TourOutcome {
                state: TourState::Waiting,
                waiting_for: Some("operators".into())
            }))
        );
        assert_eq!(GcuRequest::Release(1, 2).answer(None), Ok(GcuAnswer::Released));
        assert!(matches!(
            GcuRequest::TourList.answer(Some(b"~Lbad")),
            Err(CommandError::BadReply(_))
        ));
    }

    #[test]
    fn rules_are_read_into_owned_values() {
        let mut buf = [0u8; 64];
        let n = sagebrush_protocol::gcu::encode_rules(
            1,
            2,
            [
                RuleItem::PanLimits([-9000, 9000]),
                RuleItem::Reserved(1),
                RuleItem::KeepOut {
                    pan: [-5000, -3000],
                    tilt: [-3000, 1000],
                },
            ],
            &mut buf,
        );
        let rules = Rules {
            pan_limits: Some([-9000, 9000]),
            tilt_limits: None,
            keep_out: vec![([-5000, -3000], [-3000, 1000])],
            reserved: vec![1],
        };
        assert_eq!(
            GcuRequest::Rules(1, 2).answer(Some(&buf[..n])),
            Ok(GcuAnswer::Rules(rules))
        );
        assert!(matches!(
            GcuRequest::Rules(1, 3).answer(Some(&buf[..n])),
            Err(CommandError::BadReply(_))
        ));
        assert_eq!(degrees([-9000, 4550]), [-90.0, 45.5]);
        assert_eq!(GcuRequest::Rules(1, 0x0A).encode().unwrap().0, b"~B010A");
    }

    #[test]
    fn requests_encode_as_the_protocol_crate_reads_them() {
        let (payload, expect) = GcuRequest::Controller(1, 0x0A).encode().unwrap();
        assert_eq!(payload, b"~C010A");
        assert_eq!(expect, ResultKind::Required(ResultTimeout::Normal));
        let (payload, expect) = GcuRequest::Release(1, 2).encode().unwrap();
        assert_eq!(payload, b"~R0102");
        assert_eq!(expect, ResultKind::None);
        assert_eq!(GcuRequest::TourStop("gate".into()).encode().unwrap().0, b"~T-gate");
        assert!(matches!(
            GcuRequest::TourStart("no spaces".into()).encode(),
            Err(CommandError::Usage(_))
        ));
    }
}
