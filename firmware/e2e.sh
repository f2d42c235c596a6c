#!/usr/bin/env bash
# End-to-end test of the gimbal firmware: QEMU runs the image with UART0 on
# a host pseudo-terminal; a damaged frame written straight to that pty must
# get NAK (NAK is hop by hop, so only the direct line shows the device's);
# then gcud takes the pty as port 1 and gimbalctl, a client of gcud, reads
# the ID, moves the gimbal, reads the position back, uses a preset and gets
# NIC for an unknown command.
#
# Needs the firmware image (./build.sh) and gcud + gimbalctl from the root
# workspace (cargo build --release --bin gcud --bin gimbalctl). Override
# with FIRMWARE_ELF, GCUD, GIMBALCTL.
# Last line: "firmware e2e: N passed, M failed"; exit status 1 if M > 0.
set -uo pipefail
cd "$(dirname "$0")"
FW_DIR=$(pwd)
ROOT=$(cd .. && pwd)
ELF=${FIRMWARE_ELF:-$FW_DIR/target/thumbv7m-none-eabi/release/gimbal}
GCUD=${GCUD:-$ROOT/target/release/gcud}
GIMBALCTL=${GIMBALCTL:-$ROOT/target/release/gimbalctl}

for f in "$ELF" "$GCUD" "$GIMBALCTL"; do
    if [ ! -x "$f" ] && [ ! -f "$f" ]; then
        echo "e2e.sh: missing $f (build with firmware/build.sh and cargo build --release --bin gcud --bin gimbalctl)" >&2
        exit 2
    fi
done
command -v qemu-system-arm >/dev/null || { echo "e2e.sh: qemu-system-arm missing (apt-get install qemu-system-arm)" >&2; exit 2; }

WORK=$(mktemp -d)
PIDS=()
cleanup() {
    for pid in "${PIDS[@]}"; do
        kill "$pid" 2>/dev/null
    done
    for pid in "${PIDS[@]}"; do
        for _ in $(seq 50); do kill -0 "$pid" 2>/dev/null || break; sleep 0.1; done
        kill -9 "$pid" 2>/dev/null
    done
    rm -rf "$WORK"
}
trap cleanup EXIT
trap 'exit 130' INT TERM

passed=0
failed=0
pass() { passed=$((passed + 1)); echo "ok   - $1"; }
fail() { failed=$((failed + 1)); echo "FAIL - $1"; [ -n "${2:-}" ] && echo "$2" | sed 's/^/       /'; }

# Starts QEMU with UART0 on a new pty; sets QEMU_PID and PTY.
start_qemu() {
    local log=$WORK/qemu-$1.log
    qemu-system-arm -M lm3s6965evb -nographic -monitor none -serial pty -kernel "$ELF" >"$log" 2>&1 &
    QEMU_PID=$!
    PIDS+=("$QEMU_PID")
    PTY=""
    for _ in $(seq 100); do
        PTY=$(grep -o '/dev/pts/[0-9]*' "$log" | head -1)
        [ -n "$PTY" ] && break
        kill -0 "$QEMU_PID" 2>/dev/null || break
        sleep 0.1
    done
    if [ -z "$PTY" ]; then
        echo "e2e.sh: QEMU did not report its pty:" >&2
        cat "$log" >&2
        return 1
    fi
}

# Talks to the firmware over the raw pty: each argument is a frame spec
# "G.P.D:PAYLOAD[:bad]" (source group 0); prints what came back for each,
# as hex, one line per frame.
cat >"$WORK/pty_exchange.py" <<'EOF'
import os, select, sys, termios, time, tty

fd = os.open(sys.argv[1], os.O_RDWR | os.O_NOCTTY)
tty.setraw(fd)  # no echo: QEMU must not read back what the firmware wrote

def frame(dest, source, payload, bad):
    body = bytes(dest) + bytes([source, len(payload) & 0xFF]) + payload
    check = sum(body) & 0xFF
    return b"\xf8" + body + bytes([check ^ 0x01 if bad else check])

for spec in sys.argv[2:]:
    parts = spec.split(":")
    dest = [int(x) for x in parts[0].split(".")]
    os.write(fd, frame(dest, 0, parts[1].encode(), len(parts) > 2 and parts[2] == "bad"))
    out = b""
    deadline = time.time() + 2.0
    # Collect until 300 ms of silence after the first byte, or 2 s.
    while time.time() < deadline:
        if not select.select([fd], [], [], 0.3 if out else 2.0)[0]:
            if out:
                break
            continue
        out += os.read(fd, 512)
    print(out.hex(" "))
EOF

# --- 1. The device's own NAK and ACK, straight on the pty ------------------
if start_qemu direct; then
    mapfile -t replies < <(timeout 20 python3 "$WORK/pty_exchange.py" "$PTY" '5.1.1:P?:bad' '5.1.1:AW' '5.1.1:P?')
    if [ "${replies[0]:-}" = "15" ]; then
        pass "bad checksum on the line gets exactly one NAK (0x15) from the device"
    else
        fail "bad checksum on the line gets exactly one NAK (0x15) from the device" "got: '${replies[0]:-nothing}'"
    fi
    # AW: ACK, then the result frame to group 0 (the command's source) from
    # group 5, port and device unchanged (Table 3), status 0.
    want_aw="06 f8 00 01 01 05 01 30 38"
    if [ "${replies[1]:-}" = "$want_aw" ]; then
        pass "AW on the line: ACK + result with the Table 3 header (F8 00 01 01 05 01 '0')"
    else
        fail "AW on the line: ACK + result with the Table 3 header" "want: $want_aw"$'\n'"got:  ${replies[1]:-nothing}"
    fi
    want_p="06 f8 00 01 01 05 08 30 30 30 30 30 30 30 30 8f"
    if [ "${replies[2]:-}" = "$want_p" ]; then
        pass "P? on the line after the damaged frame: position 0000 0000"
    else
        fail "P? on the line after the damaged frame" "want: $want_p"$'\n'"got:  ${replies[2]:-nothing}"
    fi
    kill "$QEMU_PID" 2>/dev/null
else
    fail "QEMU starts with UART0 on a pty"
fi

# --- 2. Through gcud ---------------------------------------------------------
if ! start_qemu gcud; then
    fail "QEMU starts with UART0 on a pty (second run)"
    echo "firmware e2e: $passed passed, $failed failed"
    exit 1
fi
# Hold the pty open for the whole run: QEMU stops serving a pty whose last
# user closed it and polls for a new one only once a second, which would eat
# gcud's first frames. Raw mode before anything is written: an echoing pty
# would hand the firmware its own replies back.
exec 7<>"$PTY"
python3 -c 'import os, sys, tty; tty.setraw(os.open(sys.argv[1], os.O_RDWR | os.O_NOCTTY))' "$PTY"
# Wait (bounded) until QEMU serves the pty: AW answered with ACK + result.
ready=0
for _ in 1 2 3 4 5; do
    reply=$(timeout 10 python3 "$WORK/pty_exchange.py" "$PTY" '5.1.1:AW')
    case "$reply" in "06 f8 00 01 01 05 01 30 38"*) ready=1; break ;; esac
done
if [ "$ready" = 1 ]; then
    pass "second QEMU run answers AW on its pty before gcud takes it"
else
    fail "second QEMU run answers AW on its pty before gcud takes it" "last reply: '${reply:-nothing}'"
fi
CLIENT_PORT=$(python3 -c 'import socket; s = socket.socket(); s.bind(("127.0.0.1", 0)); print(s.getsockname()[1])')
cat >"$WORK/gcud.toml" <<EOF
[gcu]
group = 5
name = "firmware e2e"
serial = "E2E-0005"

[log]
level = "info"

[[port]]
id = 1
path = "$PTY"
baud = 9600

[[link]]
name = "clients"
role = "client"
listen = "127.0.0.1:$CLIENT_PORT"
allow_source_groups = [0]
EOF
"$GCUD" --config "$WORK/gcud.toml" >"$WORK/gcud.log" 2>&1 &
PIDS+=("$!")
GCUD_PID=$!
up=0
for _ in $(seq 100); do
    if (exec 3<>"/dev/tcp/127.0.0.1/$CLIENT_PORT") 2>/dev/null; then up=1; break; fi
    kill -0 "$GCUD_PID" 2>/dev/null || break
    sleep 0.1
done
if [ "$up" = 1 ]; then
    pass "gcud runs with the firmware's pty as port 1"
else
    fail "gcud runs with the firmware's pty as port 1" "$(tail -20 "$WORK/gcud.log")"
fi

# Runs gimbalctl through gcud; sets OUT and RC.
ctl() {
    OUT=$(timeout 30 "$GIMBALCTL" --tcp "127.0.0.1:$CLIENT_PORT" --to 5.1.1 "$@" 2>&1)
    RC=$?
}
# expect NAME EXIT_CODE REGEX gimbalctl-args...
expect() {
    local name=$1 code=$2 regex=$3
    shift 3
    ctl "$@"
    if [ "$RC" = "$code" ] && echo "$OUT" | grep -Eq -- "$regex"; then
        pass "$name"
    else
        fail "$name" "gimbalctl $* -> exit $RC (want $code), output:"$'\n'"$OUT"$'\n'"(want /$regex/)"
    fi
}

expect "id (D?) through gcud: device 01, revision 19, the firmware's name" 0 'device 01 +protocol revision 19 +name "SAGEBRUSH QEMU PT"' id
expect "id (D?) names the serial number" 0 'serial "LM3S6965-0001"' id
expect "status (AW): motors on, no error" 0 'hardware functioning properly' status
expect "goto 12.5 -7.25 --wait: the motion model arrives" 0 'arrived at pan +12\.50° +tilt +-7\.25°' goto 12.5 -7.25 --wait
expect "position (P?) after the move: 12.50 / -7.25" 0 '^pan +12\.50° +tilt +-7\.25°$' position
expect "preset store 3 (S03)" 0 '' preset store 3
expect "goto -30 20 --wait" 0 'arrived at pan +-30\.00° +tilt +20\.00°' goto -30 20 --wait
expect "position (P?): -30.00 / 20.00" 0 '^pan +-30\.00° +tilt +20\.00°$' position
expect "preset query 3 (P?03) gives the stored position" 0 'pan +12\.50° +tilt +-7\.25°' preset query 3
# --wait polls the position until the motion ends (an event, not a fixed
# sleep: 42.5 deg of pan at 20 deg/s takes about 2.1 s, longer on a loaded
# machine); --wait-timeout (25 s, inside ctl's 30 s) is only a hang guard.
expect "preset recall 3 (P03) --wait: back at 12.50 / -7.25" 0 'arrived at pan +12\.50° +tilt +-7\.25°' preset recall 3 --wait --wait-timeout 25000
expect "position (P?) after the recall: back at 12.50 / -7.25" 0 '^pan +12\.50° +tilt +-7\.25°$' position
expect "raw XY: the device answers NIC for an unknown command" 5 'NIC' raw XY
expect "preset query 40 (only 00..1F exist): NIC" 5 'NIC' preset query 40
expect "errors (E?): none" 0 'pan none ; tilt none' errors
expect "status-bits (I?): none" 0 'pan none ; tilt none' status-bits
expect "halt (HA)" 0 '' halt
expect "status (AW) after halt: motors off" 0 '[Mm]otors' status

echo "firmware e2e: $passed passed, $failed failed"
[ "$failed" = 0 ]
