//! What follows a command's ACK (the "RESPONSE" column of Tables 4, 11 and
//! 16): nothing, a result of a given shape, or (rev 1.9 set/read commands)
//! a result only when the command reads. The command table (`command.rs`)
//! states it per row; the reply parser (`reply.rs`) dispatches on the shape.
//! Both depend on this module, neither on the other's internals.

/// How long a result may take, as a class; the durations are the user's.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum ResultTimeout {
    /// Queries answered from memory.
    Normal,
    /// `IX`: the initialisation sequence moves both axes to their switches.
    Long,
}

/// What follows the ACK of a command (Tables 4, 11, 16 "RESPONSE").
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum ResultKind {
    /// ACK only (a NIC may still follow).
    None,
    /// ACK + a result frame (or a NIC).
    Required(ResultTimeout),
    /// A rev 1.9 set/read command: a result only when it reads.
    Optional,
}

/// A row's answer fact (the "RESPONSE" column): what follows the ACK and,
/// when a result can, its shape. [`Command::result_kind`] and the reply
/// dispatch ([`crate::Reply::parse`], [`crate::Reply::answers`]) both come
/// from it, so a query cannot have a result kind without a reply shape.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub(crate) enum Answer {
    /// ACK only.
    Ack,
    /// ACK and a result of this shape.
    Result(ResultTimeout, Shape),
    /// A rev 1.9 set/read command: a result of this shape when it reads.
    Optional(Shape),
}

impl Answer {
    /// An ACK and a result answered from memory.
    pub(crate) const fn normal(shape: Shape) -> Self {
        Answer::Result(ResultTimeout::Normal, shape)
    }

    pub(crate) const fn kind(self) -> ResultKind {
        match self {
            Answer::Ack => ResultKind::None,
            Answer::Result(timeout, _) => ResultKind::Required(timeout),
            Answer::Optional(_) => ResultKind::Optional,
        }
    }

    /// The result's shape, if one can follow.
    pub(crate) const fn shape(self) -> Option<Shape> {
        match self {
            Answer::Ack => None,
            Answer::Result(_, shape) | Answer::Optional(shape) => Some(shape),
        }
    }
}

/// The shape of result a command expects: one per [`crate::Reply`] variant. Each
/// command's row in the command table (`command.rs`) names its shape in its
/// answer fact; `Reply::parse` dispatches on it and `Reply::answers`
/// compares with it, both exhaustively.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub(crate) enum Shape {
    AwakeStatus,
    MaxDataRate,
    Identity,
    Errors,
    StatusBits,
    RateGains,
    Initialization,
    Limits,
    Relays,
    Accelerations,
    Acceleration,
    Rates,
    Rate,
    VerifyHome,
    Position,
    Lens,
    AuxCount,
    AuxData,
    Raw,
}

impl Answer {
    /// The answer's name in generated tables: `ack`, `result` or `optional`.
    pub(crate) const fn name(self) -> &'static str {
        match self {
            Answer::Ack => "ack",
            Answer::Result(..) => "result",
            Answer::Optional(_) => "optional",
        }
    }
}

impl Shape {
    /// The shape's short name in generated tables (the Wireshark dissector
    /// decodes a result by it).
    pub(crate) const fn name(self) -> &'static str {
        match self {
            Shape::AwakeStatus => "awake",
            Shape::MaxDataRate => "maxrate",
            Shape::Identity => "identity",
            Shape::Errors => "errors",
            Shape::StatusBits => "statusbits",
            Shape::RateGains => "gains",
            Shape::Initialization => "init",
            Shape::Limits => "limits",
            Shape::Relays => "relays",
            Shape::Accelerations => "accels",
            Shape::Acceleration => "accel",
            Shape::Rates => "rates",
            Shape::Rate => "rate",
            Shape::VerifyHome => "home",
            Shape::Position => "position",
            Shape::Lens => "lens",
            Shape::AuxCount => "auxcount",
            Shape::AuxData => "auxdata",
            Shape::Raw => "raw",
        }
    }
}
