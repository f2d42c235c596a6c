#!/usr/bin/env bash
# Builds the gimbal firmware (QEMU lm3s6965evb, thumbv7m-none-eabi) at
# opt-level "z" and "s" and reports, per build: flash and RAM per section,
# the largest symbols, the panic machinery still linked with its call sites;
# then runs the bench image under QEMU -icount for the instructions per
# received byte and the stack high-water mark.
#
# Installs nothing. Needs (Debian bookworm, as root):
#   apt-get update && apt-get install -y --no-install-recommends \
#     rustc-web cargo-web rust-web-src binutils-arm-none-eabi qemu-system-arm
# Uses /usr/bin/rustc and /usr/bin/cargo (never rustup's): core is built
# from /usr/lib/rustlib/src/rust with -Zbuild-std (RUSTC_BOOTSTRAP=1).
#
# Exit status: non-zero if a build fails, a panic call site is linked into
# either image (the protocol path is panic-free; this keeps it so), or the
# bench image misbehaves.
#
# Then builds the feature images (src/feature_images/: the gimbal with the
# protocol crate's `defmt`, `embedded-io`, `embedded-io-async` in use) for
# the flash cost per feature (issue 36).
#
# The measured figures in README.md and in ../crates/protocol/README.md
# (between the `measured by build.sh` markers) must be what this run
# measured: a stale figure fails the build; `./build.sh --update-readme`
# rewrites them.
set -euo pipefail
cd "$(dirname "$0")"
update_readme=false
[ "${1:-}" = --update-readme ] && update_readme=true

missing=()
for tool in /usr/bin/cargo /usr/bin/rustc arm-none-eabi-ld arm-none-eabi-size arm-none-eabi-nm \
    arm-none-eabi-objdump arm-none-eabi-addr2line qemu-system-arm python3 timeout; do
    command -v "$tool" >/dev/null 2>&1 || missing+=("$tool")
done
[ -d /usr/lib/rustlib/src/rust/library/core ] || missing+=("/usr/lib/rustlib/src/rust (rust-web-src)")
if [ ${#missing[@]} -gt 0 ]; then
    echo "build.sh: missing: ${missing[*]}" >&2
    echo "install (Debian bookworm, as root): apt-get update && apt-get install -y --no-install-recommends rustc-web cargo-web rust-web-src binutils-arm-none-eabi qemu-system-arm" >&2
    exit 2
fi

# Debian's toolchain only: rustup's proxies must not be picked up.
export PATH="/usr/bin:$PATH"
export RUSTC=/usr/bin/rustc RUSTC_BOOTSTRAP=1
unset RUSTUP_TOOLCHAIN RUSTFLAGS CARGO_BUILD_TARGET CARGO_TARGET_DIR
CARGO=/usr/bin/cargo
# -Zbuild-std compiles the library source next to the compiler: versions must match.
if command -v dpkg-query >/dev/null 2>&1; then
    rustc_deb=$(dpkg-query -W -f '${Version}' rustc-web 2>/dev/null || true)
    src_deb=$(dpkg-query -W -f '${Version}' rust-web-src 2>/dev/null || true)
    if [ -n "$rustc_deb" ] && [ "$rustc_deb" != "$src_deb" ]; then
        echo "build.sh: rustc-web $rustc_deb but rust-web-src ${src_deb:-missing}: install matching versions" >&2
        exit 2
    fi
fi
echo "toolchain: $(/usr/bin/rustc --version), $($CARGO --version)"

TARGET=thumbv7m-none-eabi
status=0

section_sizes() { # ELF -> "flash ram" in bytes
    arm-none-eabi-size -A "$1" | awk '
        $1 ~ /^\.(vector_table|text|rodata|gnu\.sgstubs)$/ { flash += $2 }
        $1 == ".data" { flash += $2; ram += $2 }
        $1 ~ /^\.(bss|uninit)$/ { ram += $2 }
        END { print flash + 0, ram + 0 }'
}

declare -A FLASH RAM SITES
for profile in release release-s; do
    level=$([ "$profile" = release ] && echo z || echo s)
    echo
    echo "== opt-level \"$level\" (cargo profile $profile) =="
    $CARGO build --quiet --profile "$profile" --bin gimbal
    elf="target/$TARGET/$profile/gimbal"
    arm-none-eabi-size -A "$elf" | awk 'NR <= 2 || ($1 ~ /^\./ && $1 !~ /^\.(debug|comment|ARM)/)'
    read -r flash ram < <(section_sizes "$elf")
    FLASH[$level]=$flash
    RAM[$level]=$ram
    echo "flash (vector_table + text + rodata + data): $flash bytes; static RAM (data + bss + uninit): $ram bytes"
    echo "largest symbols (bytes, flash and RAM):"
    arm-none-eabi-nm --print-size --size-sort --radix=d -C "$elf" | tail -12 | awk '{ $1 = ""; printf "  %6d %s", $2, $3; $2 = $3 = ""; print $0 }'
    report=$(python3 panic_sites.py "$elf" arm-none-eabi-objdump arm-none-eabi-addr2line)
    echo "$report" | sed 's|'"$(cd .. && pwd)"'/||g'
    sites=$(echo "$report" | sed -n 's/^panic call sites: //p')
    SITES[$level]=$sites
    if [ "$sites" != 0 ]; then
        echo "build.sh: FAIL: $sites panic call site(s) linked at opt-level $level" >&2
        status=1
    fi
done

echo
echo "== bench: instructions per received byte (QEMU -icount shift=0) and stack high-water =="
$CARGO build --quiet --profile release --features bench --bin bench
bench_out=$(timeout 120 qemu-system-arm -M lm3s6965evb -nographic -monitor none -serial null \
    -icount shift=0 -semihosting-config enable=on,target=native \
    -kernel "target/$TARGET/release/bench" 2>&1) || {
    echo "$bench_out"
    echo "build.sh: FAIL: bench image exited with failure" >&2
    exit 1
}
echo "$bench_out" | grep '^bench:'
stack=$(echo "$bench_out" | sed -n 's/^bench: receive path stack high-water \([0-9]*\) bytes.*/\1/p')
per_byte=$(echo "$bench_out" | sed -n 's/^bench: endpoint+handler \([0-9]*\) instructions\/byte.*/\1/p')
framer_per_byte=$(echo "$bench_out" | sed -n 's/.*framer alone \([0-9]*\) instructions\/byte.*/\1/p')
if [ -z "$stack" ] || [ -z "$per_byte" ]; then
    echo "build.sh: FAIL: bench printed no figures" >&2
    exit 1
fi

echo
echo "== feature images: the gimbal with a protocol crate feature in use (opt-level z) =="
FEATURES=(defmt embedded-io embedded-io-async)
declare -A FEATURE_FLASH FEATURE_RAM FEATURE_SITES
for feature in "${FEATURES[@]}"; do
    $CARGO build --quiet --profile release --features "$feature" --bin "gimbal-$feature"
    elf="target/$TARGET/release/gimbal-$feature"
    read -r flash ram < <(section_sizes "$elf")
    sites=$(python3 panic_sites.py "$elf" arm-none-eabi-objdump arm-none-eabi-addr2line | sed -n 's/^panic call sites: //p')
    FEATURE_FLASH[$feature]=$flash
    FEATURE_RAM[$feature]=$ram
    FEATURE_SITES[$feature]=$sites
    echo "gimbal-$feature: flash $flash B ($(printf '%+d' $((flash - FLASH[z]))) B), static RAM $ram B ($(printf '%+d' $((ram - RAM[z]))) B), panic call sites $sites"
done

echo
echo "== summary =="
for level in z s; do
    echo "opt-level $level: flash ${FLASH[$level]} B ($(awk "BEGIN { printf \"%.2f\", ${FLASH[$level]} / 1024 }") KiB), static RAM ${RAM[$level]} B, panic call sites ${SITES[$level]}"
done
echo "receive-path stack high-water (bench image, painted stack, opt-level z): $stack B; static RAM + that at opt-level z: $((RAM[z] + stack)) B (main loop and exception frames add about 140 B)"
echo "receive path: $per_byte instructions per received byte (endpoint + gimbal handler), framer alone $framer_per_byte"
echo "flash by component, opt-level z (objdump -l attribution):"
components=$(python3 flash_by_component.py "target/$TARGET/release/gimbal" arm-none-eabi-objdump arm-none-eabi-size)
echo "$components"

# The README's measured block, as this run measured it.
measured=$(cat <<MEASURED
| | opt-level z | opt-level s |
|---|---|---|
| flash (vector table + text + rodata + data) | ${FLASH[z]} B | ${FLASH[s]} B |
| static RAM (.data + .bss + .uninit) | ${RAM[z]} B | ${RAM[s]} B |
| panic call sites linked | ${SITES[z]} | ${SITES[s]} |

- Receive-path stack high-water (bench image, painted stack, opt-level z):
  $stack B; static RAM + that: $((RAM[z] + stack)) B.
- Instructions per received byte (QEMU \`-icount shift=0\`): $per_byte for
  the endpoint with the gimbal handler, $framer_per_byte for the framer alone.
- Flash by component at opt-level z (bytes, \`flash_by_component.py\`):

\`\`\`text
$components
\`\`\`
MEASURED
)
# The protocol crate's README: flash cost per feature.
feature_rows=""
for feature in "${FEATURES[@]}"; do
    feature_rows+="| \`$feature\` | \`gimbal-$feature\` | ${FEATURE_FLASH[$feature]} B | $(printf '%+d' $((FEATURE_FLASH[$feature] - FLASH[z]))) B | $(printf '%+d' $((FEATURE_RAM[$feature] - RAM[z]))) B | ${FEATURE_SITES[$feature]} |"$'\n'
done
measured_features=$(cat <<MEASURED
| feature | \`firmware/\` image | flash | flash cost | static RAM cost | panic call sites |
|---|---|---|---|---|---|
| none | \`gimbal\` | ${FLASH[z]} B | | | ${SITES[z]} |
${feature_rows%$'\n'}
MEASURED
)

# check_measured FILE TEXT: the block between FILE's markers is TEXT, or
# with --update-readme becomes it.
begin='<!-- measured by build.sh: do not edit; ./build.sh --update-readme rewrites it -->'
end='<!-- end of measured -->'
check_measured() {
    if $update_readme; then
        python3 - "$1" "$begin" "$end" "$2" <<'PY'
import sys
path, begin, end, measured = sys.argv[1:5]
text = open(path).read()
head, rest = text.split(begin, 1)
_, tail = rest.split(end, 1)
open(path, "w").write(head + begin + "\n" + measured + "\n" + end + tail)
PY
        echo "$1: measured figures rewritten"
    fi
    local in_readme
    in_readme=$(awk -v b="$begin" -v e="$end" '$0 == e { inside = 0 } inside { print } $0 == b { inside = 1 }' "$1")
    if [ "$in_readme" != "$2" ]; then
        echo "build.sh: FAIL: $1's measured figures are stale (run firmware/build.sh --update-readme):" >&2
        diff <(echo "$in_readme") <(echo "$2") >&2 || true
        status=1
    fi
}
check_measured README.md "$measured"
check_measured ../crates/protocol/README.md "$measured_features"

echo "targets: flash z <= 8192 B: $([ "${FLASH[z]}" -le 8192 ] && echo met || echo NOT met); RAM <= 2048 B: $([ $((RAM[z] + stack)) -le 2048 ] && echo met || echo NOT met); panic sites 0: $([ "${SITES[z]}" = 0 ] && [ "${SITES[s]}" = 0 ] && echo met || echo NOT met)"
if [ "${FLASH[z]}" -gt 8192 ]; then
    echo "build.sh: FAIL: flash at opt-level z is ${FLASH[z]} B, more than 8192 B" >&2
    status=1
fi
exit $status
