"""A ground station of pymavlink with MAVLink 2 message signing (pymavlink's
own, `setup_signing`), and the frames an attacker without the key sends,
for tests/mavlink/signing.rs.

Usage: python3 signed.py STEP PORT SYSID COMPID ARGS_JSON
(PORT may also be a pymavlink connection string, tcp:127.0.0.1:PORT.)

ARGS_JSON says how the ground station signs: "key_file" (the door's key
file, read as config/gimbal-mavlink.toml says pymavlink reads it) or "key"
(64 hexadecimal digits), neither for an unsigned one; "link_id" (default 1)
and "age_s" (its first timestamp that many seconds in the past, default 0).
Each STEP prints one JSON object on stdout. Every wait is bounded.
"""

import json
import math
import sys
import time

import gcs  # noqa: F401 (MAVLink 2 and the common dialect, as gcs.py sets them)
from gcs import GIMBAL, mavlink, mavutil

# MAVLink signing timestamps: 10 microsecond units since 2015-01-01.
EPOCH_2015 = 1420070400


def connect(port, sysid, compid, a):
    url = port if ":" in port else f"udpout:127.0.0.1:{port}"
    m = mavutil.mavlink_connection(url, source_system=sysid, source_component=compid, dialect="common")
    key = None
    if "key_file" in a:
        with open(a["key_file"]) as f:
            key = bytes.fromhex(f.read().strip())
    elif "key" in a:
        key = bytes.fromhex(a["key"])
    if key is not None:
        stamp = int((time.time() - EPOCH_2015 - a.get("age_s", 0.0)) * 100_000)
        m.setup_signing(key, sign_outgoing=True, link_id=a.get("link_id", 1), initial_timestamp=stamp)
    m.mav.heartbeat_send(mavlink.MAV_TYPE_GCS, mavlink.MAV_AUTOPILOT_INVALID, 0, 0, 0)
    return m


def wait_ack(m, command, wait_s):
    """The gimbal's COMMAND_ACK of `command` within `wait_s`, or None;
    heartbeats every half second meanwhile."""
    end = time.monotonic() + wait_s
    beat = time.monotonic()
    while time.monotonic() < end:
        if time.monotonic() - beat > 0.5:
            m.mav.heartbeat_send(mavlink.MAV_TYPE_GCS, mavlink.MAV_AUTOPILOT_INVALID, 0, 0, 0)
            beat = time.monotonic()
        msg = m.recv_match(type="COMMAND_ACK", blocking=True, timeout=0.2)
        if msg is not None and msg.get_srcComponent() == GIMBAL and msg.command == command:
            return msg
    return None


def answer(m, ack, sent):
    """What the step saw: the ACK's result and whether it came signed, and
    the bytes of the command as they went out (to replay)."""
    return {"result": None if ack is None else ack.result,
            "ack_signed": None if ack is None else ack.get_signed(),
            "sent": sent.hex()}


def step_pitchyaw(m, a):
    """MAV_CMD_DO_GIMBAL_MANAGER_PITCHYAW (degrees) as COMMAND_LONG."""
    nan = float("nan")
    cmd = mavlink.MAV_CMD_DO_GIMBAL_MANAGER_PITCHYAW
    msg = m.mav.command_long_encode(1, GIMBAL, cmd, 0, a["pitch"], a["yaw"], nan, nan, 0, 0, 0)
    m.mav.send(msg)
    return answer(m, wait_ack(m, cmd, a.get("wait_s", gcs.WAIT_S)), msg.get_msgbuf())


def step_set_pitchyaw(m, a):
    """GIMBAL_MANAGER_SET_PITCHYAW (radians; no answer exists for it) `count` times."""
    nan = float("nan")
    for _ in range(a.get("count", 5)):
        m.mav.gimbal_manager_set_pitchyaw_send(1, GIMBAL, 0, 0, math.radians(a["pitch"]), math.radians(a["yaw"]),
                                               nan, nan)
        time.sleep(0.1)
    return {"sent": a.get("count", 5)}


def step_replay(m, a):
    """The bytes of a command captured earlier (`bytes`, hex), written again
    as they were, `count` times: the ACK of `command`, if any comes."""
    frame = bytes.fromhex(a["bytes"])
    for _ in range(a.get("count", 3)):
        m.write(frame)
        time.sleep(0.1)
    ack = wait_ack(m, mavlink.MAV_CMD_DO_GIMBAL_MANAGER_PITCHYAW, a.get("wait_s", 2.0))
    return answer(m, ack, frame)


STEPS = {name[5:]: f for name, f in globals().items() if name.startswith("step_")}


def main():
    step, port, sysid, compid = sys.argv[1], sys.argv[2], int(sys.argv[3]), int(sys.argv[4])
    args = json.loads(sys.argv[5]) if len(sys.argv) > 5 else {}
    m = connect(port, sysid, compid, args)
    print(json.dumps(STEPS[step](m, args), default=str))


if __name__ == "__main__":
    main()
