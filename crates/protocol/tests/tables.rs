//! The command table's name columns: every row has a script name of its
//! own (snake_case, as scripts and JSON see it) and a description.
use std::collections::BTreeSet;

use sagebrush_protocol::{Command, Extended, Row};

#[test]
fn every_row_has_its_own_script_name_and_a_description() {
    let mut seen = BTreeSet::new();
    for row in Row::ALL {
        let name = row.script_name();
        assert!(
            !name.is_empty()
                && name
                    .bytes()
                    .all(|b| b.is_ascii_lowercase() || b.is_ascii_digit() || b == b'_'),
            "{row:?}: script name {name:?} is not snake_case"
        );
        assert!(seen.insert(name), "{row:?}: script name {name:?} used twice");
    }
    assert_eq!(Command::parse(b"HS").script_name(), "motors_stop");
    assert_eq!(Command::parse(b"RP0200").script_name(), "set_rate");
    for (_, command) in Command::FIXED {
        assert!(!command.description().is_empty(), "{command:?}");
    }
    for ext in Extended::ALL {
        assert!(ext.description().starts_with('`'), "{ext:?}: {}", ext.description());
    }
}
