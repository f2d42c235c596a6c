//! A command as the router read it when it accepted it (ARCHITECTURE "Time-outs
//! derived once, commands read once"): the facts every later step needs,
//! read once through the protocol crate's command table (Tables 4, 11, 16),
//! travel with the command's frame through dispatch, the ports' queues and
//! transactions, the GCU's own answers and the reverse path. Nothing after
//! acceptance parses the command again.

use sagebrush_protocol::{Command, DataRate, ExpectedReply, FrameBuf, MountEffect, Row};

/// A command frame and what was read from it when the router accepted it.
#[derive(Clone, Debug, PartialEq, Eq)]
pub(crate) struct ReadCommand {
    pub frame: FrameBuf,
    pub facts: CommandFacts,
}

impl ReadCommand {
    /// A command frame from a link, read.
    pub fn read(frame: FrameBuf) -> Self {
        let facts = CommandFacts::read(frame.frame().payload());
        Self { frame, facts }
    }

    /// A command the router built itself (a stop): known, not read.
    pub fn built(command: &Command<'_>, frame: FrameBuf) -> Self {
        Self {
            frame,
            facts: CommandFacts::of(command),
        }
    }
}

/// What a command is, read once when the router accepts it.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) struct CommandFacts {
    /// Its row of the command table (the GCU itself answers `AW` and `D?`).
    pub row: Row,
    /// A stop or halt: it overtakes queued work.
    pub stop: bool,
    /// For a continuous motion, the stop that ends it (Tables 11, 16): the
    /// dead-man owns it, and a queued one is cancelled when its origin link
    /// goes down.
    pub stopped_by: Option<Command<'static>>,
    /// What follows its ACK, what its result looks like (an answer from
    /// another GCU must fit it) and its mnemonic.
    pub reply: ExpectedReply,
    /// A `C0`..`C7` rate change.
    pub rate: Option<DataRate>,
    /// The device registry keeps its answer: `P?` (Table 15), `V?` (Table 17).
    pub registry: bool,
    /// How it acts on the pan/tilt mount (its row's governance fact, the
    /// protocol crate's module `mount`): what the governance decides by.
    pub mount: MountEffect,
}

impl CommandFacts {
    /// It moves the pan/tilt mount to a place (`Paaaaeeee`, `Pnn`, `HO`),
    /// or where nobody can bound (`IX`, `HP`, `*mp`, an unknown command): a
    /// queued one is given up when a stop of both axes overtakes it.
    pub fn goes_to(&self) -> bool {
        matches!(
            self.mount,
            MountEffect::GoTo(_) | MountEffect::RecallPreset(_) | MountEffect::Unbounded
        )
    }

    /// A slew or a goto of the mount (or a lens motion): what the
    /// governance follows in order.
    pub fn moves(&self) -> bool {
        self.stopped_by.is_some() || self.goes_to()
    }

    /// Reads a command payload: the one place the router core parses a command.
    pub fn read(payload: &[u8]) -> Self {
        Self::of(&Command::parse(payload))
    }

    /// The facts of a command the router has in hand (a stop it issues itself).
    pub fn of(command: &Command<'_>) -> Self {
        Self {
            row: command.row(),
            stop: command.is_stop(),
            stopped_by: command.stopped_by(),
            reply: ExpectedReply::of(command),
            rate: command.data_rate_change(),
            registry: matches!(command, Command::QueryPosition | Command::QueryLens),
            mount: command.mount(),
        }
    }
}
