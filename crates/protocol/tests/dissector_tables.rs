//! The dissector's generated tables (`tools/wireshark/sagebrush_tables.lua`)
//! are what the protocol crate's tables write, and the samples they are
//! written from cover every command row.
use std::collections::BTreeSet;

use sagebrush_protocol::dissector::{ARGUMENT_SAMPLES, write_lua_tables};
use sagebrush_protocol::{Command, Row};

#[test]
fn committed_lua_tables_match_the_protocol_tables() {
    let path = concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../../tools/wireshark/sagebrush_tables.lua"
    );
    let committed = std::fs::read_to_string(path).unwrap_or_else(|e| panic!("{path}: {e}"));
    let mut generated = String::new();
    write_lua_tables(&mut generated).expect("writing into a String");
    if committed != generated {
        let line = committed
            .lines()
            .zip(generated.lines())
            .position(|(a, b)| a != b)
            .map_or(committed.lines().count().min(generated.lines().count()) + 1, |i| i + 1);
        panic!(
            "{path} is stale (first difference at line {line}): run \
             `cargo run -p sagebrush-protocol --example gen_dissector_tables`"
        );
    }
}

#[test]
fn samples_cover_every_row() {
    let mut covered: BTreeSet<Row> = Command::FIXED.iter().map(|(_, c)| c.row()).collect();
    for sample in ARGUMENT_SAMPLES {
        let command = Command::parse_strict(sample)
            .unwrap_or_else(|e| panic!("sample {:?}: {e}", String::from_utf8_lossy(sample)));
        covered.insert(command.row());
    }
    covered.insert(Command::Unknown(&[]).row());
    covered.insert(Command::Extended(sagebrush_protocol::Extended::ALL[0], &[]).row());
    let rows: BTreeSet<Row> = Row::ALL.into_iter().collect();
    let missing: Vec<_> = rows.difference(&covered).collect();
    assert!(missing.is_empty(), "rows without a dissector sample: {missing:?}");
}

/// The generated table is keyed by mnemonic, and a per-axis row has one
/// per axis: where a sample names an axis (`P` or `T` at byte 1 or 2) and
/// the other axis is a command of the same row, that one is a sample too.
#[test]
fn samples_name_both_axes_of_a_per_axis_row() {
    for sample in ARGUMENT_SAMPLES {
        let row = Command::parse(sample).row();
        for at in 1..=2.min(sample.len() - 1) {
            let other = match sample[at] {
                b'P' => b'T',
                b'T' => b'P',
                _ => continue,
            };
            let mut twin = sample.to_vec();
            twin[at] = other;
            if Command::parse_strict(&twin).is_ok_and(|c| c.row() == row) {
                assert!(
                    ARGUMENT_SAMPLES.contains(&twin.as_slice()),
                    "{:?} is a sample, {:?} (the other axis) is not",
                    String::from_utf8_lossy(sample),
                    String::from_utf8_lossy(&twin)
                );
            }
        }
    }
}
