#!/usr/bin/env bash
# Installs cargo-semver-checks for crates/protocol/ci.sh (issue 36); .ci/run
# starts it early, in the background at the lowest CPU priority, so that it
# builds in the time the tests spend waiting.
#
# 0.51.0 reads the rustdoc JSON of Rust 1.95. A debug build with
# unoptimised dependencies: about 5 min on 2 busy cores, where its own debug
# profile (dependencies at opt-level 3) took 22 min and its release one adds
# LTO; the check takes as long either way (building rustdoc JSON dominates).
set -euo pipefail
cargo install --quiet --locked --debug cargo-semver-checks --version 0.51.0 \
    --config 'profile.dev.debug=0' --config 'profile.dev.package."*".opt-level=0'
