#!/usr/bin/env bash
# CI for sagebrush-protocol as a crate of its own (issue 36), called by
# .ci/run; runs from any directory, on a fresh clone.
#   - builds for thumbv6m-none-eabi (Cortex-M0/M0+, no atomic CAS) and
#     thumbv7em-none-eabihf: no features, each feature alone, all features;
#   - clippy on the crate with all features (the workspace lint builds none);
#   - docs for thumbv7m-none-eabi with all features, RUSTDOCFLAGS=-D warnings
#     (broken intra-doc links fail);
#   - cargo package --list holds only src/, README, CHANGELOG, licences;
#   - cargo publish --dry-run (package, verify build), no warning but the
#     include list's "ignoring test/example" ones;
#   - examples/embassy-rp2040 (a gimbal on an RP2040 UART with embassy):
#     release build, not run;
#   - build and tests at the MSRV (root Cargo.toml's rust-version);
#   - cargo semver-checks, all features, against SEMVER_BASELINE below.
# Installs the targets and the MSRV toolchain with rustup, and
# cargo-semver-checks with cargo install, when missing.
# Prints each step's seconds and the total.
set -euo pipefail
cd "$(dirname "$0")/../.."
export CARGO_TERM_COLOR=never CARGO_INCREMENTAL=0
start=$SECONDS
last=$SECONDS
done_step() { printf 'protocol/ci.sh: %-60s %4ss\n' "$1" "$((SECONDS - last))"; last=$SECONDS; }

PKG=sagebrush-protocol
TARGETS=(thumbv6m-none-eabi thumbv7em-none-eabihf)
DOC_TARGET=thumbv7m-none-eabi
FEATURES=(defmt embedded-io embedded-io-async)
# The API that semver-checks compares with until the first release (issue
# 36): main at bba7388. An incompatible change fails until the version says
# so; after the first release, use --baseline-version instead.
SEMVER_BASELINE=bba738870ff085319f293b543795d23757c10280
MSRV=$(sed -n 's/^rust-version = "\(.*\)"$/\1/p' Cargo.toml | head -n 1)
[ -n "$MSRV" ] || { echo "protocol/ci.sh: no rust-version in Cargo.toml" >&2; exit 1; }
# Checked first, so that a shallow clone fails before the builds.
if ! git cat-file -e "$SEMVER_BASELINE^{commit}" 2>/dev/null; then
    echo "protocol/ci.sh: semver-checks baseline $SEMVER_BASELINE is not in this clone (shallow? git fetch --unshallow)" >&2
    exit 1
fi

installed=$(rustup target list --installed)
for target in "${TARGETS[@]}" "$DOC_TARGET"; do
    grep -qx "$target" <<<"$installed" || rustup target add "$target"
done
rustup toolchain list | grep -q "^$MSRV-" || rustup toolchain install "$MSRV" --profile minimal
rustup "+$MSRV" target list --installed | grep -qx "${TARGETS[0]}" || rustup "+$MSRV" target add "${TARGETS[0]}"
done_step "rustup: targets ${TARGETS[*]} $DOC_TARGET, toolchain $MSRV"

for target in "${TARGETS[@]}"; do
    cargo build --quiet -p "$PKG" --target "$target"
    for feature in "${FEATURES[@]}"; do
        cargo build --quiet -p "$PKG" --target "$target" --no-default-features --features "$feature"
    done
    cargo build --quiet -p "$PKG" --target "$target" --all-features
    done_step "build $target: none, ${FEATURES[*]} (alone), all"
done

cargo clippy --quiet -p "$PKG" --all-targets --all-features -- -D warnings
done_step "clippy, all features"

RUSTDOCFLAGS="-D warnings" cargo doc --quiet -p "$PKG" --no-deps --all-features --target "$DOC_TARGET"
done_step "docs for $DOC_TARGET, all features, -D warnings"

list=$(cargo package --quiet --list -p "$PKG" --allow-dirty 2>/dev/null)
unexpected=$(grep -vE '^(src/.*\.rs|README\.md|CHANGELOG\.md|LICENSE-(MIT|APACHE)|Cargo\.(toml|toml\.orig|lock)|\.cargo_vcs_info\.json)$' <<<"$list" || true)
if [ -n "$unexpected" ]; then
    echo "protocol/ci.sh: the package holds files that do not belong in it:" >&2
    echo "$unexpected" >&2
    exit 1
fi
# A dirty tree is allowed so that the check also runs on a work in progress;
# on CI's fresh clone the tree is clean.
log=$(cargo publish --dry-run -p "$PKG" --allow-dirty 2>&1) || { echo "$log" >&2; exit 1; }
warnings=$(grep '^warning' <<<"$log" | grep -vE 'is not included in the published package|aborting upload due to dry run' || true)
if [ -n "$warnings" ]; then
    echo "protocol/ci.sh: cargo publish --dry-run warns:" >&2
    echo "$warnings" >&2
    exit 1
fi
done_step "cargo package --list, cargo publish --dry-run"

# The embassy example (its own workspace, Cargo.lock committed): built, not run.
(cd examples/embassy-rp2040 && cargo build --quiet --release --locked)
done_step "examples/embassy-rp2040: release build (thumbv6m-none-eabi)"

msrv_start=$SECONDS
cargo "+$MSRV" build --quiet -p "$PKG" --all-features --target "${TARGETS[0]}"
cargo "+$MSRV" test --quiet -p "$PKG" --all-features
done_step "Rust $MSRV: build (${TARGETS[0]}) and tests, all features"
echo "protocol/ci.sh: MSRV $MSRV build and tests took $((SECONDS - msrv_start)) s"

cargo semver-checks --version >/dev/null 2>&1 || bash crates/protocol/install-semver-checks.sh
done_step "cargo-semver-checks $(cargo semver-checks --version | cut -d' ' -f2) installed"
cargo semver-checks --color never -p "$PKG" --all-features --baseline-rev "$SEMVER_BASELINE"
done_step "cargo semver-checks, all features, baseline ${SEMVER_BASELINE:0:7}"

echo "protocol/ci.sh: done in $((SECONDS - start)) s"
