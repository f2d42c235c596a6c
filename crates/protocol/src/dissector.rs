//! The Wireshark dissector's tables (`tools/wireshark/sagebrush_tables.lua`),
//! written from this crate's tables so that the dissector copies none by
//! hand: every command row with its mnemonic, description, answer and
//! result shape (Tables 4, 11, 16 "RESPONSE"), the rev 1.9 names in
//! matching order (1.2), the data-rate codes (Table 4 `Cn`), the Table 5
//! awake bits, the delivery report codes and the capture record header's
//! codes (kind, direction, role).
//!
//! `cargo run -p sagebrush-protocol --example gen_dissector_tables` writes
//! the file; the `dissector_tables` test fails when the file in the tree
//! differs from what these tables write.

use core::fmt::{self, Write};

use crate::capture_record::{Direction, RECORD_HEADER_LEN, RecordKind, Role};
use crate::command::{Command, Extended};
use crate::reply::AwakeStatus;
use crate::report::{REPORT_LEN, REPORT_MARK, Undelivered};
use crate::units::DataRate;

/// One command of every row that takes arguments, one per mnemonic (both
/// axes where the mnemonic names the axis). The fixed rows come from
/// [`Command::FIXED`], the rev 1.9 ones from [`Extended::ALL`].
pub const ARGUMENT_SAMPLES: &[&[u8]] = &[
    b"#01",
    b"C3",
    b"GRP0F",
    b"GRT0F",
    b"L2",
    b"L9",
    b"LS000FFF000FFF",
    b"AP?",
    b"AT?",
    b"AP0100",
    b"AT0100",
    b"P0064FF9C",
    b"P0A",
    b"P?0A",
    b"RP?",
    b"RT?",
    b"RP0200",
    b"RT0200",
    b"SP5",
    b"ST5",
    b"S0A",
    b"S?0A",
    b"VM1",
    b"F5",
    b"V123456",
    b"Z5",
    b"ZB",
    b"*x0c,9600,8,1,0",
    b"*x0tAB",
    b"*x0r010",
    b"*x0n",
    b"*x0f",
];

/// A Lua string literal (`"` and `\` escaped; the tables are ASCII).
struct Lua<'a>(&'a str);

/// A description as a Lua string literal, without the documentation's
/// markup (code spans and link brackets).
struct Prose<'a>(&'a str);

impl fmt::Display for Lua<'_> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        literal(f, self.0.chars())
    }
}

impl fmt::Display for Prose<'_> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        literal(f, self.0.chars().filter(|c| !matches!(c, '`' | '[' | ']')))
    }
}

fn literal(f: &mut fmt::Formatter<'_>, text: impl Iterator<Item = char>) -> fmt::Result {
    f.write_char('"')?;
    for c in text {
        if c == '"' || c == '\\' {
            f.write_char('\\')?;
        }
        f.write_char(c)?;
    }
    f.write_char('"')
}

/// One command's row; `fixed`: its mnemonic is its whole wire form.
fn command_row(out: &mut impl Write, command: &Command<'_>, fixed: bool) -> fmt::Result {
    let answer = command.answer();
    write!(
        out,
        "    [{}] = {{ answer = {}, description = {}",
        Lua(command.mnemonic()),
        Lua(answer.name()),
        Prose(command.description())
    )?;
    if let Some(shape) = answer.shape() {
        write!(out, ", shape = {}", Lua(shape.name()))?;
    }
    if fixed {
        out.write_str(", fixed = true")?;
    }
    out.write_str(" },\n")
}

/// Writes the Lua tables file (a chunk that returns one table).
pub fn write_lua_tables(out: &mut impl Write) -> fmt::Result {
    out.write_str(
        "-- GENERATED from the sagebrush-protocol crate's tables (crates/protocol/src/dissector.rs):\n\
         -- do not edit. Regenerate: cargo run -p sagebrush-protocol --example gen_dissector_tables\n\
         local T = {}\n\n\
         -- Commands by mnemonic (Tables 4, 11, 16): answer is ack, result or optional\n\
         -- (a rev 1.9 set/read command answers with a result only when it reads);\n\
         -- fixed: the row takes no arguments (its mnemonic is its wire form).\n\
         T.commands = {\n",
    )?;
    for (_, command) in Command::FIXED {
        command_row(out, command, true)?;
    }
    for sample in ARGUMENT_SAMPLES {
        command_row(out, &Command::parse(sample), false)?;
    }
    command_row(out, &Command::Unknown(&[]), false)?;
    out.write_str(
        "}\n\n-- Rev 1.9 commands published by name only (1.2), matched as prefixes in this order.\nT.extended = {\n",
    )?;
    for ext in Extended::ALL {
        let answer = ext.answer();
        write!(
            out,
            "    {{ name = {}, answer = {}",
            Lua(ext.name()),
            Lua(answer.name())
        )?;
        if let Some(shape) = answer.shape() {
            write!(out, ", shape = {}", Lua(shape.name()))?;
        }
        writeln!(out, ", description = {} }},", Prose(ext.description()))?;
    }
    out.write_str("}\n\n-- Table 4 `Cn`: data rate codes, bit/s (8..F reserved).\nT.data_rates = {")?;
    for code in 0..=15 {
        if let Some(bps) = DataRate::from_code(code).and_then(DataRate::bits_per_second) {
            write!(out, " [{code}] = {bps},")?;
        }
    }
    out.write_str(" }\n\n-- Table 5: awake status bits, lowest first.\nT.awake_bits = {\n")?;
    for (bit, _, meaning) in AwakeStatus::BITS {
        writeln!(out, "    {{ mask = {bit}, name = {} }},", Lua(meaning))?;
    }
    write!(
        out,
        "}}\n\n-- A delivery report's payload: its mark and length (ARCHITECTURE \"Delivery contract\").\n\
         T.report_mark = {}\nT.report_len = {REPORT_LEN}\n",
        Lua(core::str::from_utf8(&[REPORT_MARK]).unwrap_or("!"))
    )?;
    out.write_str("\n-- Delivery report codes: name and meaning.\nT.report_codes = {\n    [0x00] = { name = \"delivered\", meaning = \"delivered\" },\n")?;
    for u in Undelivered::ALL {
        writeln!(
            out,
            "    [0x{:02X}] = {{ name = {}, meaning = {} }},",
            u.code(),
            Lua(u.name()),
            Lua(u.describe())
        )?;
    }
    code_rows(
        out,
        "Capture record kinds (header byte 1, docs/capture.md).",
        "T.record_kinds",
        RecordKind::ALL.map(|k| (k.code(), k.name(), k.describe())),
    )?;
    code_rows(
        out,
        "Capture record directions (header byte 2), seen from the capturing program.",
        "T.directions",
        Direction::ALL.map(|d| (d.code(), d.name(), d.describe())),
    )?;
    code_rows(
        out,
        "Capture record roles (header byte 3): which way commands flow on the line.",
        "T.roles",
        Role::ALL.map(|r| (r.code(), r.name(), r.describe())),
    )?;
    write!(
        out,
        "}}\n\n-- Bytes of the capture record header before the raw bytes (docs/capture.md).\n\
         T.record_header_len = {RECORD_HEADER_LEN}\n\nreturn T\n"
    )
}

/// Closes the table before, then `-- comment`, `table = {` and one row
/// per code of a `code_table!`: its name and meaning.
fn code_rows<const N: usize>(
    out: &mut impl Write,
    comment: &str,
    table: &str,
    rows: [(u8, &str, &str); N],
) -> fmt::Result {
    write!(out, "}}\n\n-- {comment}\n{table} = {{\n")?;
    for (code, name, meaning) in rows {
        writeln!(
            out,
            "    [{code}] = {{ name = {}, meaning = {} }},",
            Lua(name),
            Lua(meaning)
        )?;
    }
    Ok(())
}
