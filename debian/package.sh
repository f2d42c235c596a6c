#!/usr/bin/env bash
# Builds the Debian package: the release programs, then what is generated
# from them for every [[bin]] of Cargo.toml (a new program needs no entry
# here): the manual pages (`PROGRAM --generate-man-pages DIR PROGRAMS...`,
# clap_mangen: PROGRAM.1 and a page per subcommand) in target/man, the
# bash, zsh and fish completions (`PROGRAM --generate-completions SHELL`,
# clap_complete) in target/completions, the Wireshark dissector in the
# build architecture's plugin folder under target/wireshark-plugin; checks
# that Cargo.toml's Depends is what dpkg-shlibdeps finds for all the
# programs together; then `cargo deb`. Prints the package's path last.
# `--no-build` packages the release programs already built (as .ci/run
# does after `cargo test --release`); other arguments go to cargo deb.
set -euo pipefail
trap 'echo "package.sh: line $LINENO failed (exit $?)" >&2' ERR
cd "$(dirname "$0")/.."
build=1
args=()
for a in "$@"; do
  if [ "$a" = --no-build ]; then build=0; else args+=("$a"); fi
done
if [ "$build" = 1 ]; then
  cargo build --release --locked --bins >&2
fi
release="${CARGO_TARGET_DIR:-target}/release"

# The package's programs: the name of every [[bin]] table of Cargo.toml.
mapfile -t programs < <(awk '/^\[\[bin\]\]/ { in_bin = 1; next }
  /^\[/ { in_bin = 0 }
  in_bin && /^name *=/ { gsub(/^name *= *"|"$/, ""); print; in_bin = 0 }' Cargo.toml)
[ "${#programs[@]}" -gt 0 ] || { echo "package.sh: no [[bin]] in Cargo.toml" >&2; exit 1; }

rm -rf target/man target/completions target/wireshark-plugin
mkdir -p target/man target/completions/bash target/completions/zsh target/completions/fish
for program in "${programs[@]}"; do
  "$release/$program" --generate-man-pages target/man "${programs[@]}"
  "$release/$program" --generate-completions bash > "target/completions/bash/$program"
  "$release/$program" --generate-completions zsh > "target/completions/zsh/_$program"
  "$release/$program" --generate-completions fish > "target/completions/fish/$program.fish"
done
gzip -9nf target/man/*.1

# Wireshark and tshark load Lua plugins for all users from
# /usr/lib/MULTIARCH/wireshark/plugins (and its subfolders, one deep).
multiarch=$(dpkg-architecture -qDEB_HOST_MULTIARCH 2>/dev/null || gcc -print-multiarch 2>/dev/null || true)
[ -n "$multiarch" ] || { echo "package.sh: neither dpkg-architecture (dpkg-dev) nor gcc names the multiarch triplet" >&2; exit 1; }
plugin="target/wireshark-plugin/$multiarch/wireshark/plugins/sagebrush"
mkdir -p "$plugin"
cp tools/wireshark/sagebrush.lua tools/wireshark/sagebrush_tables.lua "$plugin/"

# cargo-deb's "$auto" lists each program's libc6 apart (issue 53); the
# Depends in Cargo.toml must be dpkg-shlibdeps' answer for all at once.
shlibs=$(mktemp -d)
mkdir "$shlibs/debian" && touch "$shlibs/debian/control"
binaries=()
for program in "${programs[@]}"; do binaries+=("$(realpath "$release/$program")"); done
if ! shlibdeps=$(cd "$shlibs" && dpkg-shlibdeps -O "${binaries[@]}" 2>"$shlibs/errors"); then
  echo "package.sh: dpkg-shlibdeps (dpkg-dev) failed:" >&2; cat "$shlibs/errors" >&2; exit 1
fi
rm -rf "$shlibs"
needed=$(sed -n 's/^shlibs:Depends=//p' <<<"$shlibdeps")
declared=$(awk -F'"' '/^depends *=/ { print $2; exit }' Cargo.toml)
if [ "$needed" != "$declared" ]; then
  echo "package.sh: Cargo.toml [package.metadata.deb] depends = \"$declared\", but the programs need \"$needed\" (dpkg-shlibdeps): write that" >&2
  exit 1
fi

cargo deb --no-build "${args[@]}"
