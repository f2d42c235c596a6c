#!/usr/bin/env bash
# ./demo.sh: everything running at once on this machine (README.md, "Quick
# start"): gcud on config/demo.toml with its three simulated gimbals, and
# every front door in DOORS below on all three, each over its own link of
# gcud (so gcud governs each as its own controller), all on loopback
# (127.0.0.1; VISCA over IP on 127.0.0.2, VISCA_HOST below).
# Prints what to open; Ctrl-C (SIGINT) or SIGTERM stops every program it
# started, and it exits once they are all gone.
#
#   ./demo.sh                   build (cargo build --release), then run
#   ./demo.sh --port-base 14000 every port moved by 14000 - 4000
#   ./demo.sh --no-build        run what target/release holds
#   ./demo.sh --bin-dir DIR     run the programs in DIR (implies --no-build)
#   ./demo.sh --run-dir DIR     keep the configurations and logs in DIR
#                               (default: a temporary folder, removed at exit)
#
# Ports: config/demo.toml's (clients 4001, operators 4002, a link per door
# 4003..4008, metrics 9187; a door it has no link for gets 4010 + its place
# in DOORS) and the doors' below (web 8080, ONVIF 8081..8083, WS-Discovery
# 3702, MAVLink 14560, VISCA over IP udp 5381..5383 (52381 is VISCA's
# own) and raw tcp 5678..5680, Pelco-D tcp 4100), all moved together by
# --port-base (4000 is as written): one number, no file to edit.
#
# Exit status: 0 stopped by a signal; 1 a program would not start or died
# (its log's end is printed); 2 bad arguments or the build failed.
#
# Why a script: it is glue (build, write small configurations, start,
# print, stop), and the programs it runs are the build's, which a binary
# of the workspace could not build before itself.
set -uo pipefail
cd "$(dirname "$0")"

base=4000 build=1 bin_dir="" run_dir="" keep_run_dir=0
usage() { sed -n '2,/^set -uo/p' "$0" | sed '$d;s/^# \{0,1\}//'; }
while [ $# -gt 0 ]; do
  case "$1" in
    --port-base) base=${2:-}; shift ;;
    --no-build) build=0 ;;
    --bin-dir) bin_dir=${2:-}; build=0; shift ;;
    --run-dir) run_dir=${2:-}; keep_run_dir=1; shift ;;
    -h | --help) usage; exit 0 ;;
    *) echo "demo.sh: unknown argument $1 (--help)" >&2; exit 2 ;;
  esac
  shift
done
case "$base" in
  '' | *[!0-9]*) echo "demo.sh: --port-base takes a number, not '$base'" >&2; exit 2 ;;
esac
shift_by=$((base - 4000))
# The highest port the demo uses is MAVLink's (14560).
if [ $((3702 + shift_by)) -lt 1024 ] || [ $((14560 + shift_by)) -gt 65535 ]; then
  echo "demo.sh: --port-base $base puts ports outside 1024..65535 (try 4000..54000)" >&2
  exit 2
fi

# A port of the demo, moved by --port-base.
port() { echo $(($1 + shift_by)); }

# --- the front doors ----------------------------------------------------------
# The doors, in the order started: each its binary, and the name of its
# [[link]] in config/demo.toml (a door whose link that file lacks gets one:
# 4010 + its place here). Each has a function settings_NAME that prints
# its configuration's own keys (its gcud link is $link; its ports through
# `port`), a case in gimbal_keys for its [[gimbal]] tables, and a function
# open_NAME that prints what a user opens; door_config writes the whole.
DOORS=(gimbal-onvif gimbal-mavlink gimbal-web gimbal-visca gimbal-pelco)

# The demo's gimbals: name, address.
GIMBALS=("mast-1 5.1.1" "mast-2 5.1.2" "roof 5.2.1")
# Their MAVLink gimbal managers' component ids, in the same order.
MAVLINK_COMPONENTS=(154 171 172)
# VISCA over IP's cameras listen on a loopback address of their own: a
# client on this host that binds the camera's port on every address (the
# Python visca-over-ip package does) then fits beside them
# (config/gimbal-visca.toml, reuse_address).
VISCA_HOST=127.0.0.2

# each_gimbal FUNCTION [ARG...]: runs FUNCTION ARG... NAME ADDRESS PLACE
# for each of the demo's gimbals, PLACE its place in GIMBALS (0 first).
each_gimbal() {
  local place=0 gimbal
  for gimbal in "${GIMBALS[@]}"; do
    "$@" $gimbal "$place"
    place=$((place + 1))
  done
}

# door_config DOOR: DOOR's configuration: its own keys, then a [[gimbal]]
# table for each of the demo's gimbals.
door_config() {
  "settings_${1//-/_}"
  each_gimbal gimbal_table "$1"
}

# gimbal_table DOOR NAME ADDRESS PLACE: DOOR's [[gimbal]] table for a gimbal.
gimbal_table() {
  printf '[[gimbal]]\nname = "%s"\naddress = "%s"\n' "$2" "$3"
  gimbal_keys "$1" "$4"
}

# gimbal_keys DOOR PLACE: the keys of DOOR's [[gimbal]] table for the
# gimbal at PLACE in GIMBALS, after its name and address.
gimbal_keys() {
  case $1 in
    gimbal-onvif) echo "listen = \"$(onvif_listen "$2")\"" ;;
    gimbal-mavlink) echo "component_id = ${MAVLINK_COMPONENTS[$2]}" ;;
    gimbal-visca) printf 'visca_udp = "%s"\nvisca_tcp = "%s"\nreuse_address = true\n' "$(visca_udp "$2")" "$(visca_tcp "$2")" ;;
    gimbal-pelco) echo "pelco_address = $(($2 + 1))" ;;
  esac
}
onvif_listen() { echo "127.0.0.1:$(port $((8081 + $1)))"; }
visca_udp() { echo "$VISCA_HOST:$(port $((5381 + $1)))"; }
visca_tcp() { echo "127.0.0.1:$(port $((5678 + $1)))"; }

settings_gimbal_onvif() {
  cat <<EOF
gcud = "$link"
state_file = "$run_dir/gimbal-onvif-presets.toml"
[discovery]
enabled = true
listen = "127.0.0.1:$(port 3702)"
[[user]]
name = "admin"
password = "change-me-admin"
role = "administrator"
[[user]]
name = "vms"
password = "change-me"
role = "operator"
EOF
}
settings_gimbal_mavlink() {
  cat <<EOF
gcud = "$link"
system_id = 1
[[endpoint]]
udp_listen = "127.0.0.1:$(port 14560)"
EOF
}
settings_gimbal_web() {
  cat <<EOF
gcud = "$link"
listen = "127.0.0.1:$(port 8080)"
[[user]]
name = "admin"
password = "change-me"
role = "administrator"
[[user]]
name = "viewer"
password = "change-me-too"
role = "user"
EOF
}
settings_gimbal_visca() { echo "gcud = \"$link\""; }
settings_gimbal_pelco() {
  cat <<EOF
gcud = "$link"
[[input]]
tcp_listen = "127.0.0.1:$(port 4100)"
protocol = "pelco-d"
EOF
}

# What each door's open_NAME prints for one gimbal (NAME ADDRESS PLACE).
onvif_line() { echo "  $1 ($2): http://$(onvif_listen "$3")/onvif/device_service"; }
mavlink_component() { echo "${MAVLINK_COMPONENTS[$3]} $1"; }
visca_line() { echo "  $1 ($2): VISCA over IP udp $(visca_udp "$3"), raw VISCA tcp $(visca_tcp "$3")"; }
pelco_camera() { echo "$(($3 + 1)) $1"; }
# joined FUNCTION: what each_gimbal FUNCTION prints, joined by ", ".
joined() { each_gimbal "$1" | awk 'NR > 1 { printf ", " } { printf "%s", $0 }'; }

open_gimbal_onvif() {
  echo "ONVIF PTZ cameras (a VMS, ONVIF Device Manager; users admin / change-me-admin, vms / change-me):"
  each_gimbal onvif_line
  echo "  WS-Discovery answers unicast probes at 127.0.0.1:$(port 3702)"
}
open_gimbal_mavlink() {
  echo "MAVLink gimbal managers (system 1; components $(joined mavlink_component)):"
  echo "  UDP 127.0.0.1:$(port 14560), e.g. mavproxy.py --master=udpout:127.0.0.1:$(port 14560)"
}
open_gimbal_web() {
  echo "The web page: http://127.0.0.1:$(port 8080)/ (admin / change-me, viewer / change-me-too)"
}
open_gimbal_visca() {
  echo "VISCA cameras (OBS obs-ptz, Bitfocus Companion, vMix; camera address 1):"
  each_gimbal visca_line
}
open_gimbal_pelco() {
  echo "Pelco-D keyboards (a DVR through a serial server): tcp 127.0.0.1:$(port 4100), cameras $(joined pelco_camera)"
}

# --- build ----------------------------------------------------------------------

target=${CARGO_TARGET_DIR:-target}
[ -n "$bin_dir" ] || bin_dir="$target/release"
if [ "$build" = 1 ]; then
  bins=(--bin gcud --bin gimbalctl)
  for door in "${DOORS[@]}"; do bins+=(--bin "$door"); done
  echo "demo.sh: cargo build --release ${bins[*]}"
  cargo build --release "${bins[@]}" || { echo "demo.sh: the build failed (above)" >&2; exit 2; }
fi
bin_dir=$(cd "$bin_dir" 2>/dev/null && pwd) || { echo "demo.sh: no folder $bin_dir" >&2; exit 2; }
for program in gcud gimbalctl "${DOORS[@]}"; do
  [ -x "$bin_dir/$program" ] || { echo "demo.sh: $bin_dir/$program is missing (run without --no-build)" >&2; exit 2; }
done

# --- run ------------------------------------------------------------------------

if [ -z "$run_dir" ]; then
  run_dir=$(mktemp -d "${TMPDIR:-/tmp}/sagebrush-demo.XXXXXX") || exit 2
else
  mkdir -p "$run_dir" || exit 2
  run_dir=$(cd "$run_dir" && pwd)
fi

pids=() names=()
stop_all() {
  trap '' INT TERM
  local pid
  for pid in "${pids[@]}"; do kill -TERM "$pid" 2>/dev/null; done
  # gcud and the doors stop what they started on the bus, then exit: a
  # program still there after 10 s is killed.
  for _ in $(seq 100); do
    local alive=0
    for pid in "${pids[@]}"; do kill -0 "$pid" 2>/dev/null && alive=1; done
    [ "$alive" = 0 ] && break
    sleep 0.1
  done
  for pid in "${pids[@]}"; do kill -KILL "$pid" 2>/dev/null; done
  wait 2>/dev/null
  [ "$keep_run_dir" = 1 ] || rm -rf "$run_dir"
}
fail() {
  echo "demo.sh: $*" >&2
  stop_all
  exit 1
}

# The programs exit with the demo even when it is killed outright
# (SIGKILL): setpriv gives each a parent-death signal.
pdeathsig=()
command -v setpriv >/dev/null && setpriv --help 2>&1 | grep -q pdeathsig && pdeathsig=(setpriv --pdeathsig TERM --)
# Each program in a session of its own, so that Ctrl-C (SIGINT to the
# terminal's foreground group) reaches the launcher alone, which stops them
# in turn: had they got it too, one could exit before the launcher's trap
# ran, and the launcher report it as a program that died (seen under load).
own_session=()
command -v setsid >/dev/null && own_session=(setsid)

# start NAME ARGS...: runs $bin_dir/NAME ARGS with its log in $run_dir/NAME.log
# and waits for its "NAME ready" line.
start() {
  local name=$1
  shift
  RUST_LOG=${RUST_LOG:-info} "${pdeathsig[@]}" "${own_session[@]}" "$bin_dir/$name" "$@" >"$run_dir/$name.log" 2>&1 &
  pids+=($!) names+=("$name")
  local pid=$!
  for _ in $(seq 600); do
    grep -q "$name ready" "$run_dir/$name.log" 2>/dev/null && return 0
    kill -0 "$pid" 2>/dev/null || fail "$name exited at start; the end of its log:
$(tail -n 15 "$run_dir/$name.log")"
    sleep 0.1
  done
  fail "$name did not say it was ready within 60 s; the end of its log:
$(tail -n 15 "$run_dir/$name.log")"
}
trap 'echo; echo "demo.sh: stopping"; stop_all; exit 0' INT TERM

# gcud: config/demo.toml with its ports moved, and a link for any door it lacks.
gcud_config="$run_dir/gcud.toml"
awk -v by="$shift_by" '{
  while (match($0, /127\.0\.0\.1:[0-9]+/)) {
    out = out substr($0, 1, RSTART - 1) "127.0.0.1:" (substr($0, RSTART + 10, RLENGTH - 10) + by)
    $0 = substr($0, RSTART + RLENGTH)
  }
  print out $0; out = ""
}' config/demo.toml >"$gcud_config"
# The listen address of gcud's link NAME in the configuration.
link_of() {
  awk -v want="name = \"$1\"" '
    /^\[/ { in_link = ($0 == "[[link]]"); named = 0 }
    in_link && index($0, want) == 1 { named = 1 }
    in_link && named && /^listen = / { gsub(/^listen = "|".*$/, ""); print; exit }
  ' "$gcud_config"
}
i=0
for door in "${DOORS[@]}"; do
  if [ -z "$(link_of "$door")" ]; then
    printf '\n[[link]]\nname = "%s"\nrole = "client"\nlisten = "127.0.0.1:%s"\nmotion_lease_ms = 1500\n' \
      "$door" "$(port $((4010 + i)))" >>"$gcud_config"
  fi
  i=$((i + 1))
done
start gcud --config "$gcud_config"

for door in "${DOORS[@]}"; do
  link=$(link_of "$door")
  door_config "$door" >"$run_dir/$door.toml"
  start "$door" --config "$run_dir/$door.toml"
done

ctl="$bin_dir/gimbalctl"
[ "$bin_dir" = "$PWD/target/release" ] && ctl="target/release/gimbalctl"
cat <<EOF

The Sagebrush demo is running: gcud (GCU 5; gimbals 5.1.1 and 5.1.2 on bus 1, 5.2.1 the roof on bus 2)
and ${DOORS[*]}, all on loopback (127.0.0.1; VISCA over IP on $VISCA_HOST).
EOF
for door in "${DOORS[@]}"; do "open_${door//-/_}"; done
cat <<EOF
gcud: clients 127.0.0.1:$(port 4001), operators 127.0.0.1:$(port 4002) (priority 80), metrics http://127.0.0.1:$(port 9187)/metrics
  $ctl --tcp 127.0.0.1:$(port 4001) --to 5.1.1 goto 45 -10 --wait
  $ctl --tcp 127.0.0.1:$(port 4001) --to 5.1.1 position
  $ctl gcud-status --http 127.0.0.1:$(port 9187)
  $ctl --tcp 127.0.0.1:$(port 4002) tour start roof-round
Logs and configurations: $run_dir
Ctrl-C stops everything.
EOF

# Until a signal, or until one of the programs dies.
while :; do
  wait -n
  for j in "${!pids[@]}"; do
    if ! kill -0 "${pids[$j]}" 2>/dev/null; then
      fail "${names[$j]} exited; the end of its log:
$(tail -n 15 "$run_dir/${names[$j]}.log")"
    fi
  done
done
