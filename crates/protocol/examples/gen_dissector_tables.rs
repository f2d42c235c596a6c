//! Writes the Wireshark dissector's tables from the protocol crate's tables:
//! `cargo run -p sagebrush-protocol --example gen_dissector_tables [PATH]`
//! (default `tools/wireshark/sagebrush_tables.lua` of the workspace). The
//! `dissector_tables` test fails while the file in the tree is stale.
use std::path::PathBuf;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let path = std::env::args_os().nth(1).map(PathBuf::from).unwrap_or_else(|| {
        PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../tools/wireshark/sagebrush_tables.lua")
    });
    let mut text = String::new();
    sagebrush_protocol::dissector::write_lua_tables(&mut text)?;
    std::fs::write(&path, text).map_err(|e| format!("{}: {e}", path.display()))?;
    println!("wrote {}", path.display());
    Ok(())
}
