#!/usr/bin/env bash
# Builds the Debian package: the release programs, their manual pages
# (generated from each program's clap definition: `PROGRAM
# --generate-man-page`, clap_mangen) in target/man, then `cargo deb`.
# Prints the package's path last. `--no-build` packages the release
# programs already built (as .ci/run does after `cargo test --release`);
# other arguments go to cargo deb.
set -euo pipefail
cd "$(dirname "$0")/.."
build=1
args=()
for a in "$@"; do
  if [ "$a" = --no-build ]; then build=0; else args+=("$a"); fi
done
if [ "$build" = 1 ]; then
  cargo build --release --locked --bins >&2
fi
mkdir -p target/man
for program in gcud gimbalctl gimbal-onvif gimbal-mavlink gimbal-web gimbal-mqtt gimbal-visca gimbal-pelco gimbalsim; do
  "target/release/$program" --generate-man-page > "target/man/$program.1"
  gzip -9nf "target/man/$program.1"
done
cargo deb --no-build "${args[@]}"
