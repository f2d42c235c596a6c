#!/usr/bin/env bash
# ./test.sh: the whole test suite in one command (README.md, "Quick start").
#
#   ./test.sh                      install what is missing, then every test
#   ./test.sh --no-install         the tests only
#   ./test.sh --test mavlink ...   other `cargo test` selection arguments
#                                  instead of --workspace
#
# 1. Installs what the tests need when it is missing (nothing when all is
#    there): Debian packages with apt-get (as root, or through sudo),
#    tshark's debconf question answered; the Python clients of
#    tests/requirements.txt in .venv; Home Assistant core in its own
#    tests/ha/.venv (tests/ha/install.sh); the npm packages of every
#    tests/**/package.json (npm ci); cargo-deb.
# 2. Builds the tests once and runs them all (`cargo test --workspace
#    --release --no-fail-fast`, CI=true: a missing tool fails its test):
#    one failing test binary does not stop the others.
# 3. Ends with one summary line (passed, failed, ignored, time) and, for
#    each failure, a command that runs that test again without compiling:
#    the test binary under target/release/deps, the test's name, --exact.
#
# Exit status: 0 every test passed; 1 a test failed; 2 the build failed or
# a tool could not be installed.
#
# Why a script and not `cargo xtask test`: half its work happens before
# anything compiles (apt, .venv, npm, cargo-deb) on a machine that may only
# have rustup; .ci/run, which calls it, is a script too.
set -uo pipefail
cd "$(dirname "$0")"
root=$PWD

install=1
selection=()
for arg in "$@"; do
  case "$arg" in
    --no-install) install=0 ;;
    -h | --help) sed -n '2,/^set -uo/p' "$0" | sed '$d;s/^# \{0,1\}//'; exit 0 ;;
    *) selection+=("$arg") ;;
  esac
done
[ ${#selection[@]} -gt 0 ] || selection=(--workspace)

say() { printf '==> %s\n' "$*"; }
die() { printf 'test.sh: %s\n' "$*" >&2; exit 2; }

command -v cargo >/dev/null || die "cargo not found: install Rust first (README.md, \"Quick start\": rustup)"

# --- 1. what the tests need -------------------------------------------------

# The Debian packages the tests use, by the command that shows each is there.
apt_wanted() {
  command -v cc >/dev/null || echo build-essential
  command -v curl >/dev/null || echo curl                        # tests/demo/ runs the quick start's curl line
  command -v tshark >/dev/null || echo tshark                    # tests/capture.rs, tests/dissector.rs
  command -v systemd-analyze >/dev/null || echo systemd          # tests/deployment.rs
  command -v chromium >/dev/null || echo chromium                # tests/web/ (Selenium)
  command -v chromedriver >/dev/null || echo chromium-driver
  command -v socat >/dev/null || echo socat                      # serial doors' null-modem pairs
  command -v mosquitto >/dev/null || echo mosquitto              # an MQTT broker
  { python3 -m venv --help && python3 -c 'import ensurepip'; } >/dev/null 2>&1 || echo python3-venv
  if [ -n "$(package_jsons)" ]; then
    command -v node >/dev/null || echo nodejs
    command -v npm >/dev/null || echo npm
  fi
}

# Every tests/**/package.json (its folder gets `npm ci`).
package_jsons() {
  find tests -name package.json -not -path '*/node_modules/*' 2>/dev/null | sort
}

install_apt() {
  local packages
  packages=$(apt_wanted | sort -u | tr '\n' ' ')
  [ -n "${packages// /}" ] || return 0
  local sudo=()
  if [ "$(id -u)" -ne 0 ]; then
    command -v sudo >/dev/null || die "missing: $packages; run as root or install sudo"
    sudo=(sudo)
  fi
  command -v apt-get >/dev/null || die "missing: $packages; no apt-get here: install them by hand"
  say "apt-get install $packages"
  # tshark asks whether non-root users may capture: no (the tests only read files).
  echo "wireshark-common wireshark-common/install-setuid boolean false" | "${sudo[@]}" debconf-set-selections
  "${sudo[@]}" env DEBIAN_FRONTEND=noninteractive apt-get update -qq || die "apt-get update failed"
  # shellcheck disable=SC2086 # one word per package
  "${sudo[@]}" env DEBIAN_FRONTEND=noninteractive apt-get install -y -qq $packages \
    || die "apt-get install $packages failed"
}

install_venv() {
  # An existing .venv (a developer's, made by whichever python3) is kept: a
  # second `venv` over it by another interpreter would mix two Pythons.
  if [ ! -x .venv/bin/python3 ]; then
    say "python3 -m venv .venv"
    python3 -m venv .venv || die "python3 -m venv .venv failed"
  fi
  .venv/bin/pip install --quiet --disable-pip-version-check -r tests/requirements.txt \
    || die ".venv/bin/pip install -r tests/requirements.txt failed"
}

# Home Assistant core (tests/mqtt/home_assistant.rs) pins its own
# dependencies, at odds with .venv's clients: its own venv, made once.
install_home_assistant() {
  [ -f tests/ha/.venv/complete ] && return 0
  say "tests/ha/install.sh (Home Assistant core in tests/ha/.venv)"
  bash tests/ha/install.sh || die "tests/ha/install.sh failed"
}

install_npm() {
  local manifest dir
  for manifest in $(package_jsons); do
    dir=$(dirname "$manifest")
    [ -f "$dir/package-lock.json" ] || die "$manifest has no package-lock.json beside it (npm ci needs one)"
    # npm ci starts from scratch: only when the lock file changed since.
    if [ ! -f "$dir/node_modules/.package-lock.json" ] \
      || [ "$dir/package-lock.json" -nt "$dir/node_modules/.package-lock.json" ]; then
      say "npm ci in $dir"
      (cd "$dir" && npm ci --no-audit --no-fund --loglevel=error) || die "npm ci in $dir failed"
    fi
  done
}

if [ "$install" = 1 ]; then
  install_apt
  install_venv
  install_home_assistant
  install_npm
  if ! command -v cargo-deb >/dev/null; then
    say "cargo install cargo-deb --locked"
    cargo install cargo-deb --locked || die "cargo install cargo-deb failed"
  fi
fi

# --- 2. build once, then run everything ---------------------------------------

export CI="${CI:-true}"
target=${CARGO_TARGET_DIR:-target}
mkdir -p "$target"
artifacts="$target/test-artifacts.jsonl" log="$target/test-output.log"
started=$SECONDS

say "cargo test ${selection[*]} --release --no-run"
cargo test "${selection[@]}" --release --no-run --message-format=json-render-diagnostics >"$artifacts" \
  || die "the tests did not build (above)"

say "cargo test ${selection[*]} --release --no-fail-fast (CI=$CI)"
cargo test "${selection[@]}" --release --no-fail-fast 2>&1 | tee "$log"
cargo_status=${PIPESTATUS[0]}
elapsed=$((SECONDS - started))

# --- 3. one summary line, and a rerun command per failure ---------------------

# Each test binary's folder (cargo runs it in its package's folder), from
# the build's artifact messages: "executable<TAB>package folder".
binaries="$target/test-binaries.tsv"
: >"$binaries"
command -v python3 >/dev/null && python3 - "$artifacts" >"$binaries" <<'EOF'
import json, os, sys
for line in open(sys.argv[1]):
    try:
        m = json.loads(line)
    except ValueError:
        continue
    if m.get("reason") == "compiler-artifact" and m.get("executable") and m["profile"]["test"]:
        print(m["executable"] + "\t" + os.path.dirname(m["manifest_path"]))
EOF

awk -v root="$root" -v elapsed="$elapsed" -v binaries="$binaries" -v cargo_status="$cargo_status" '
  function rel(path) { return index(path, root "/") == 1 ? substr(path, length(root) + 2) : path }
  function quote(s) { gsub(/\x27/, "\x27\\\x27\x27", s); return "\x27" s "\x27" }
  function rerun(name,    exe, dir, cmd) {
    if (doc != "") return "cargo test --release --doc -p " doc " -- " quote(name)
    exe = bin
    if (substr(exe, 1, 1) != "/") exe = root "/" exe
    cmd = rel(exe) (name == "" ? "" : " " quote(name) " --exact")
    dir = folder[exe]
    if (dir != "" && dir != root) cmd = "(cd " rel(dir) " && " exe (name == "" ? "" : " " quote(name) " --exact") ")"
    return cmd
  }
  BEGIN {
    while ((getline row < binaries) > 0) { split(row, f, "\t"); folder[f[1]] = f[2] }
  }
  /^ *Running .* \(.*\)$/ {
    bin = $0; sub(/^.*\(/, "", bin); sub(/\)$/, "", bin)
    doc = ""; named = 0; nbin++
    next
  }
  /^ *Doc-tests / { doc = $2; gsub(/_/, "-", doc); named = 0; next }
  /^test .* \.\.\. FAILED$/ {
    name = $0; sub(/^test /, "", name); sub(/ \.\.\. FAILED$/, "", name)
    failures[++nfail] = rerun(name); named++
    next
  }
  # A binary that failed without naming a test: it crashed, or has its own
  # main (harness = false).
  /^error: test failed, to rerun pass / {
    if (!named) { failures[++nfail] = rerun(""); failed++ }
  }
  /^test result: / {
    for (i = 1; i <= NF; i++) {
      if ($(i + 1) ~ /^passed;?$/) passed += $i
      if ($(i + 1) ~ /^failed;?$/) failed += $i
      if ($(i + 1) ~ /^ignored;?$/) ignored += $i
    }
  }
  END {
    if (cargo_status != 0 && nfail == 0) failures[++nfail] = "cargo test exited " cargo_status " with no failing test named (above)"
    printf "\ntest.sh: %d passed, %d failed, %d ignored, %d test binaries, %dm%02ds%s\n", \
      passed, failed, ignored, nbin, elapsed / 60, elapsed % 60, \
      nfail ? "; rerun each failure without compiling:" : ""
    for (i = 1; i <= nfail; i++) print "  " failures[i]
    exit nfail ? 1 : 0
  }
' "$log"
