#!/usr/bin/env bash
# CI entry for the firmware: installs the Debian packages it needs when they
# are missing (CI runs as root), builds gcud and gimbalctl (release, the
# root workspace), then runs build.sh (sizes, panic sites, bench, flash
# cost per protocol crate feature) and e2e.sh (QEMU + gcud + gimbalctl).
# Non-zero exit on any failure.
# Takes about 2 minutes on 2 cores from a warm cargo cache and freshly
# installed packages (firmware build from scratch included).
set -euo pipefail
cd "$(dirname "$0")"
start=$(date +%s)

PACKAGES=(rustc-web cargo-web rust-web-src binutils-arm-none-eabi qemu-system-arm)
missing=()
for pkg in "${PACKAGES[@]}"; do
    dpkg-query -W -f '${Status}' "$pkg" 2>/dev/null | grep -q 'install ok installed' || missing+=("$pkg")
done
if [ ${#missing[@]} -gt 0 ]; then
    if [ "$(id -u)" != 0 ]; then
        echo "firmware/ci.sh: missing packages ${missing[*]}; as root: apt-get update && apt-get install -y --no-install-recommends ${PACKAGES[*]}" >&2
        exit 2
    fi
    echo "firmware/ci.sh: installing ${missing[*]}"
    export DEBIAN_FRONTEND=noninteractive
    apt-get update -q >/dev/null
    apt-get install -y -q --no-install-recommends "${PACKAGES[@]}" >/dev/null
fi

# gcud and gimbalctl with the workspace's usual toolchain (cached when the
# workspace's release tests ran before).
(cd .. && cargo build --release --quiet --bin gcud --bin gimbalctl)

./build.sh
./e2e.sh
echo "firmware/ci.sh: done in $(($(date +%s) - start)) s"
