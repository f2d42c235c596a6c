#!/usr/bin/env bash
# Fuzz smoke test: builds the cargo-fuzz targets and runs each for SECONDS.
#   bash fuzz/smoke.sh SECONDS        (from anywhere; CI runs it from the repo root)
# Uses nightly with AddressSanitizer when a nightly toolchain is installed,
# else the default toolchain with --sanitizer none. Exits non-zero on a
# crash (the reproducer is left in fuzz/artifacts/TARGET/).
set -euo pipefail
seconds="${1:-10}"
case "$seconds" in '' | *[!0-9]* | 0) echo "usage: $0 SECONDS (a whole number >= 1)" >&2; exit 2 ;; esac
cd "$(dirname "$0")"
targets=(framer command_parse reply_parse)

if ! cargo fuzz --version >/dev/null 2>&1; then
    # Another install may be running on this machine: wait for it rather than
    # racing it (up to 15 minutes).
    for _ in $(seq 180); do
        pgrep -f 'cargo install cargo-fuzz' >/dev/null 2>&1 || break
        sleep 5
    done
    cargo fuzz --version >/dev/null 2>&1 || cargo install cargo-fuzz --locked
fi
cargo fuzz --version

if cargo +nightly --version >/dev/null 2>&1; then
    toolchain=(+nightly)
    sanitizer=address
else
    toolchain=()
    sanitizer=none
fi
echo "fuzz: toolchain ${toolchain[*]:-default}, sanitizer $sanitizer, ${seconds}s per target"

# Seeds: golden frames and payloads, so short runs start from real inputs.
seed() { mkdir -p "corpus/$1" && printf "$3" >"corpus/$1/$2"; }
seed framer table3 '\x00\xf8\x05\x01\x0c\x02\x02\x50\x3f\xa5\x06'
seed framer false-start '\x01\xf8\x00\xf8\x05\x01\x0c\x02\x02\x50\x3f\xa5\x15?'
seed command_parse goto 'P0064FF9C'
seed command_parse aux-config '*x0c,9600,8,1,0'
seed command_parse gain 'GRP0F'
seed command_parse limits 'LSFFF000800123'
seed reply_parse position 'P?0064FF9C'
seed reply_parse identity '0C19PTU-D300            SN-000123           '
seed reply_parse gains 'G?0F130000'

cargo "${toolchain[@]}" fuzz build --sanitizer "$sanitizer"
for target in "${targets[@]}"; do
    echo "=== fuzz $target (${seconds}s)"
    cargo "${toolchain[@]}" fuzz run --sanitizer "$sanitizer" "$target" -- \
        -max_total_time="$seconds" -max_len=1024 -print_final_stats=1
done
echo "fuzz: all targets ran ${seconds}s without a crash"
