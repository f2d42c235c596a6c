//! The sizes README.md prints ("Sizes", measured on x86-64) are the sizes
//! the types have, so that the figure a user budgets from cannot go stale.
#![cfg(target_pointer_width = "64")]

use std::mem::size_of;

use sagebrush_protocol::{DeviceEndpoint, FrameBuf, Framer, MAX_FRAME_LEN, Transaction};

#[test]
fn readme_sizes_are_the_types_sizes() {
    let readme = include_str!("../README.md");
    let expected = [
        format!("Largest frame: {MAX_FRAME_LEN} bytes"),
        format!(
            "`Framer` (default `Framer<526>`, room for two maximum frames) is {} bytes;",
            size_of::<Framer>()
        ),
        format!("(`Framer<263>` is {} bytes)", size_of::<Framer<263>>()),
        format!("`FrameBuf` is {} bytes", size_of::<FrameBuf>()),
        format!(
            "`DeviceEndpoint` (default capacity) is {} bytes",
            size_of::<DeviceEndpoint>()
        ),
        format!("`Transaction` is {} bytes.", size_of::<Transaction>()),
    ];
    // The README wraps lines: compare with its whitespace collapsed.
    let text = readme.split_whitespace().collect::<Vec<_>>().join(" ");
    for figure in expected {
        assert!(text.contains(&figure), "README.md should say: {figure}");
    }
}
