"""A ground station made of pymavlink (the MAVLink library QGroundControl's
and ArduPilot's tooling is built on), driving gimbal-mavlink for
tests/mavlink/main.rs and tests/mavlink_attack.rs.

Usage: python3 gcs.py STEP PORT SYSID COMPID [ARGS_JSON]
(PORT may also be a pymavlink connection string, tcp:127.0.0.1:PORT.)

With "autopilot" in ARGS_JSON, a simulated autopilot of system 1
(component 1) sends ATTITUDE and GLOBAL_POSITION_INT on a connection of
its own around the step (class Autopilot).

Each STEP opens a UDP socket to gimbal-mavlink's udp_listen endpoint on
127.0.0.1:PORT as system SYSID, component COMPID, sends a HEARTBEAT (so
that gimbal-mavlink hears of it), does its part and prints one JSON
object on stdout: what it saw, for the Rust test to assert on. Attitude
quaternions are turned into Euler angles by pymavlink's own quaternion
module. Every wait is bounded.
"""

import json
import math
import os
import sys
import threading
import time

# MAVLink 2 and its message ids above 255 (the gimbal messages).
os.environ["MAVLINK20"] = "1"

from pymavlink import mavutil  # noqa: E402
from pymavlink.quaternion import QuaternionBase  # noqa: E402

mavutil.set_dialect("common")
mavlink = mavutil.mavlink

GIMBAL = 154
WAIT_S = 15.0


def connect(port, sysid, compid):
    """UDP to 127.0.0.1:PORT, or the connection PORT names (tcp:HOST:PORT,
    or a serial device /dev/...: pymavlink's serial link, 115200 baud)."""
    if port.startswith("/"):
        m = mavutil.mavlink_connection(port, baud=115200, source_system=sysid, source_component=compid,
                                       dialect="common")
    else:
        url = port if ":" in port else f"udpout:127.0.0.1:{port}"
        m = mavutil.mavlink_connection(url, source_system=sysid, source_component=compid, dialect="common")
    assert m.mavlink20(), "pymavlink speaks MAVLink 2"
    m.mav.heartbeat_send(mavlink.MAV_TYPE_GCS, mavlink.MAV_AUTOPILOT_INVALID, 0, 0, 0)
    return m


def wait(m, types, until=None, timeout=WAIT_S, component=GIMBAL):
    """The first message of `types` from `component` for which `until` holds."""
    end = time.monotonic() + timeout
    beat = 0.0
    while time.monotonic() < end:
        if time.monotonic() - beat > 0.5:
            # Keep gimbal-mavlink's peer entry for us fresh.
            m.mav.heartbeat_send(mavlink.MAV_TYPE_GCS, mavlink.MAV_AUTOPILOT_INVALID, 0, 0, 0)
            beat = time.monotonic()
        msg = m.recv_match(type=types, blocking=True, timeout=0.2)
        if msg is None or msg.get_srcComponent() != component:
            continue
        if until is None or until(msg):
            return msg
    return None


def ack(m, command, component=GIMBAL):
    a = wait(m, "COMMAND_ACK", lambda a: a.command == command, component=component)
    return None if a is None else a.result


def attitude_of(msg):
    """The status's angles (None for an unknown attitude: a NaN quaternion)
    and flags, COMMS_ERROR read with pymavlink's own constant."""
    comms_error = bool(msg.failure_flags & mavlink.GIMBAL_DEVICE_ERROR_FLAGS_COMMS_ERROR)
    seen = {"flags": msg.flags, "failure_flags": msg.failure_flags, "comms_error": comms_error,
            "time_boot_ms": msg.time_boot_ms}
    seen["delta_yaw"] = None if math.isnan(msg.delta_yaw) else math.degrees(msg.delta_yaw)
    if any(math.isnan(c) for c in msg.q):
        return {**seen, "roll": None, "pitch": None, "yaw": None}
    roll, pitch, yaw = QuaternionBase(list(msg.q)).euler
    return {**seen, "roll": math.degrees(roll), "pitch": math.degrees(pitch), "yaw": math.degrees(yaw)}


def command(m, cmd, params, component=GIMBAL):
    p = list(params) + [0.0] * (7 - len(params))
    m.mav.command_long_send(1, component, cmd, 0, *p)
    return ack(m, cmd, component)


def command_int(m, cmd, params, component=GIMBAL, frame=mavlink.MAV_FRAME_GLOBAL):
    """`cmd` as COMMAND_INT (as MAVSDK and ArduPilot send it) in `frame`:
    params 1-4, x and y (integers) for params 5 and 6, z for param 7; the
    ACK's result."""
    p = list(params) + [0.0] * (7 - len(params))
    m.mav.command_int_send(1, component, frame, cmd, 0, 0, p[0], p[1], p[2], p[3], int(round(p[4])),
                           int(round(p[5])), p[6])
    return ack(m, cmd, component)


def step_command_int(m, a):
    """One COMMAND_INT with `id` and `params` (7, param 5 and 6 integers), the ACK's result."""
    nan = float("nan")
    params = [nan if v is None else v for v in a.get("params", [])]
    return {"result": command_int(m, a["id"], params, a.get("component", GIMBAL),
                                  a.get("frame", mavlink.MAV_FRAME_GLOBAL))}


def step_broadcast(m, a):
    """COMMAND_LONG `id` with `params` to component 0 (every component, as
    MAVProxy sends before it has seen the gimbal): the result each
    component answered with, by component id, within `listen_s`."""
    nan = float("nan")
    p = [nan if v is None else v for v in a.get("params", [])]
    p = p + [0.0] * (7 - len(p))
    if a.get("int"):
        m.mav.command_int_send(1, 0, mavlink.MAV_FRAME_GLOBAL, a["id"], 0, 0, p[0], p[1], p[2], p[3], int(p[4]),
                               int(p[5]), p[6])
    else:
        m.mav.command_long_send(1, 0, a["id"], 0, *p)
    end = time.monotonic() + a.get("listen_s", 4.0)
    results = {}
    while time.monotonic() < end:
        msg = m.recv_match(type="COMMAND_ACK", blocking=True, timeout=0.1)
        if msg is not None and msg.command == a["id"]:
            results.setdefault(str(msg.get_srcComponent()), []).append(msg.result)
    return {"results": results}


def step_device_set_attitude(m, a):
    """GIMBAL_DEVICE_SET_ATTITUDE (as ArduPilot, the gimbal manager, drives
    a gimbal device) of (pitch, yaw) degrees with `flags`, sent `count` times."""
    q = [float(x) for x in QuaternionBase([0.0, math.radians(a["pitch"]), math.radians(a["yaw"])]).q]
    for _ in range(a.get("count", 1)):
        m.mav.gimbal_device_set_attitude_send(1, a.get("component", GIMBAL), a.get("flags", 0), q, nan_(), nan_(),
                                              nan_())
        time.sleep(0.05)
    return {"q": q}


def step_manual(m, a):
    """GIMBAL_MANAGER_SET_MANUAL_CONTROL (unitless -1..1) sent `count` times every `every_s`."""
    nan = float("nan")
    for _ in range(a.get("count", 1)):
        m.mav.gimbal_manager_set_manual_control_send(1, a.get("component", GIMBAL), a.get("flags", 0), 0,
                                                     a.get("pitch", nan), a.get("yaw", nan),
                                                     a.get("pitch_rate", nan), a.get("yaw_rate", nan))
        time.sleep(a.get("every_s", 0.0))
    return {"sent": a.get("count", 1)}


def step_interval(m, a):
    """MAV_CMD_SET_MESSAGE_INTERVAL of message `id` to `us`, its ACK; then
    the mean interval (ms) between the next `count` messages of that id,
    by the gimbal's own time_boot_ms (what the door meant to send, not
    when this machine's scheduler let us read it), and how many came in
    `listen_s` when the stream is off."""
    name = {281: "GIMBAL_MANAGER_STATUS", 285: "GIMBAL_DEVICE_ATTITUDE_STATUS"}.get(a["id"])
    result = command(m, mavlink.MAV_CMD_SET_MESSAGE_INTERVAL, [a["id"], a["us"]])
    out = {"result": result}
    if result != mavlink.MAV_RESULT_ACCEPTED or name is None:
        return out
    # Drop what was sent before the change took effect.
    time.sleep(0.5)
    while m.recv_match(type=name, blocking=False) is not None:
        pass
    if a["us"] == -1:
        end, seen = time.monotonic() + a.get("listen_s", 2.0), 0
        while time.monotonic() < end:
            msg = m.recv_match(type=name, blocking=True, timeout=0.1)
            if msg is not None and msg.get_srcComponent() == GIMBAL:
                seen += 1
        out["seen"] = seen
        return out
    stamps = []
    end = time.monotonic() + WAIT_S
    while len(stamps) < a.get("count", 20) and time.monotonic() < end:
        msg = m.recv_match(type=name, blocking=True, timeout=0.2)
        if msg is not None and msg.get_srcComponent() == GIMBAL:
            stamps.append(msg.time_boot_ms)
    if len(stamps) >= 2:
        out["mean_ms"] = (stamps[-1] - stamps[0]) / (len(stamps) - 1)
    out["count"] = len(stamps)
    return out


def step_heartbeat(m, a):
    hb = wait(m, "HEARTBEAT", component=a.get("component", GIMBAL))
    if hb is None:
        return {"heartbeat": None}
    return {"heartbeat": {"type": hb.type, "autopilot": hb.autopilot, "system": hb.get_srcSystem(),
                          "component": hb.get_srcComponent(), "v2": m.mavlink20()}}


def step_info(m, a):
    comp = a.get("component", GIMBAL)
    out = {}
    for name, msgid in (("manager", 280), ("device", 283)):
        m.mav.command_long_send(1, comp, mavlink.MAV_CMD_REQUEST_MESSAGE, 0, msgid, 0, 0, 0, 0, 0, 0)
        out[name + "_ack"] = ack(m, mavlink.MAV_CMD_REQUEST_MESSAGE, comp)
        if out[name + "_ack"] == mavlink.MAV_RESULT_ACCEPTED:
            t = "GIMBAL_MANAGER_INFORMATION" if msgid == 280 else "GIMBAL_DEVICE_INFORMATION"
            msg = wait(m, t, component=comp)
            out[name] = None if msg is None else msg.to_dict()
    return out


def step_pitchyaw(m, a):
    """MAV_CMD_DO_GIMBAL_MANAGER_PITCHYAW (degrees), the ACK's result."""
    nan = float("nan")
    p = [a.get("pitch", nan), a.get("yaw", nan), a.get("pitch_rate", nan), a.get("yaw_rate", nan),
         a.get("flags", 0), 0, a.get("device", 0)]
    out = {"result": command(m, mavlink.MAV_CMD_DO_GIMBAL_MANAGER_PITCHYAW, p, a.get("component", GIMBAL))}
    if a.get("report"):
        # What the gimbal reports right after: the manager's flags, and
        # the heading in the attitude status's delta_yaw.
        st = wait(m, "GIMBAL_MANAGER_STATUS")
        out["manager_flags"] = None if st is None else st.flags
        at = wait(m, "GIMBAL_DEVICE_ATTITUDE_STATUS")
        out["delta_yaw"] = None if at is None else attitude_of(at)["delta_yaw"]
    return out


def step_pitchyaw_text(m, a):
    """MAV_CMD_DO_GIMBAL_MANAGER_PITCHYAW (degrees): the ACK's result and
    the text of the gimbal's first STATUSTEXT around it (within `text_s`),
    in whichever order they come."""
    nan = float("nan")
    p = [a.get("pitch", nan), a.get("yaw", nan), nan, nan, 0, 0, 0]
    m.mav.command_long_send(1, GIMBAL, mavlink.MAV_CMD_DO_GIMBAL_MANAGER_PITCHYAW, 0, *p)
    out = {"result": None, "text": None}
    end = time.monotonic() + a.get("text_s", 5.0)
    while time.monotonic() < end and (out["result"] is None or out["text"] is None):
        msg = m.recv_match(type=["COMMAND_ACK", "STATUSTEXT"], blocking=True, timeout=0.2)
        if msg is None or msg.get_srcComponent() != GIMBAL:
            continue
        if msg.get_type() == "STATUSTEXT":
            out["text"] = out["text"] or msg.text
        elif msg.command == mavlink.MAV_CMD_DO_GIMBAL_MANAGER_PITCHYAW:
            out["result"] = msg.result
    return out


def step_set_pitchyaw(m, a):
    """GIMBAL_MANAGER_SET_PITCHYAW (radians) sent `count` times every `every_s`, with `flags`."""
    nan = float("nan")
    rad = lambda k: math.radians(a[k]) if k in a else nan
    for _ in range(a.get("count", 1)):
        m.mav.gimbal_manager_set_pitchyaw_send(1, a.get("component", GIMBAL), a.get("flags", 0), 0, rad("pitch"),
                                               rad("yaw"),
                                               rad("pitch_rate"), rad("yaw_rate"))
        time.sleep(a.get("every_s", 0.0))
    return {"sent": a.get("count", 1)}


def step_set_attitude(m, a):
    q = QuaternionBase([0.0, math.radians(a["pitch"]), math.radians(a["yaw"])]).q
    m.mav.gimbal_manager_set_attitude_send(1, a.get("component", GIMBAL), 0, 0, [float(x) for x in q], nan_(), nan_(),
                                           nan_())
    return {"q": [float(x) for x in q]}


def nan_():
    return float("nan")


def step_attitude(m, a):
    """Attitude status until within 0.5° of (pitch, yaw), or the last one seen."""
    want = (a.get("pitch"), a.get("yaw"))
    last = {}

    def near(msg):
        last.update(attitude_of(msg))
        if want[0] is None:
            return True
        return abs(last["pitch"] - want[0]) <= 0.5 and abs(last["yaw"] - want[1]) <= 0.5

    msg = wait(m, "GIMBAL_DEVICE_ATTITUDE_STATUS", near, timeout=a.get("timeout_s", WAIT_S),
               component=a.get("component", GIMBAL))
    return {"reached": msg is not None, "attitude": last}


def step_configure(m, a):
    p = a.get("params", [-2, -2, -1, -1])
    return {"result": command(m, mavlink.MAV_CMD_DO_GIMBAL_MANAGER_CONFIGURE, p + [0, 0, a.get("device", 0)],
                              a.get("component", GIMBAL))}


def step_manager_status(m, a):
    st = wait(m, "GIMBAL_MANAGER_STATUS", lambda s: (a.get("primary_sysid") is None
                                                     or s.primary_control_sysid == a["primary_sysid"])
              and (a.get("flags") is None or s.flags == a["flags"]))
    return {"status": None if st is None else st.to_dict()}


def step_garbage(m, a):
    """Damaged frames, bytes that are no MAVLink, a message id no dialect
    has, a message gimbal-mavlink does not handle; then a NaN and an
    out-of-travel pitch. The two results, and whether a heartbeat still
    comes."""
    good = mavlink.MAVLink_heartbeat_message(6, 8, 0, 0, 4, 3).pack(m.mav)
    garbage = []
    for i in range(len(good)):
        bad = bytearray(good)
        bad[i] ^= 0x5A
        garbage.append(bytes(bad))
    garbage.append(b"\x00" * 40 + b"GET / HTTP/1.1\r\n\r\n")
    garbage.append(bytes([0xFD, 4, 0, 0, 1, 1, 1, 0xFF, 0xFF, 0xFF, 1, 2, 3, 4, 0xAB, 0xCD]))
    for g in garbage:
        m.write(g)
    m.mav.param_request_list_send(1, GIMBAL)
    nan = float("nan")
    # Every byte written that is no intact frame (on a stream, all of it
    # reaches gimbal-mavlink; over UDP a datagram may be lost).
    out = {"garbage_bytes": sum(len(g) for g in garbage)}
    out["nan"] = command(m, mavlink.MAV_CMD_DO_GIMBAL_MANAGER_PITCHYAW, [nan, float("inf"), nan, nan, 0, 0, 0])
    out["out_of_travel"] = command(m, mavlink.MAV_CMD_DO_GIMBAL_MANAGER_PITCHYAW, [120.0, 0.0, nan, nan, 0, 0, 0])
    out["bad_configure"] = command(m, mavlink.MAV_CMD_DO_GIMBAL_MANAGER_CONFIGURE, [nan, 3.5, -1, -1, 0, 0, 0])
    out["alive"] = wait(m, "HEARTBEAT") is not None
    return out


def step_unsupported(m, a):
    return {"result": command(m, mavlink.MAV_CMD_DO_SET_SERVO, [1, 1500])}


def step_command_id(m, a):
    """A COMMAND_LONG with any command id (one the dialect may not know), the ACK's result."""
    return {"result": command(m, a["id"], a.get("params", []), a.get("component", GIMBAL))}


def step_watch(m, a):
    """Heartbeats every `beat_s` (as QGroundControl), for `duration_s`: how
    many attitude statuses of the gimbal came. Writes `ready_file` once
    connected, so the test starts its flood after the ground station was heard."""
    if "ready_file" in a:
        with open(a["ready_file"], "w") as f:
            f.write("connected")
    end = time.monotonic() + a["duration_s"]
    beat, statuses = 0.0, 0
    while time.monotonic() < end:
        if time.monotonic() - beat >= a.get("beat_s", 1.0):
            m.mav.heartbeat_send(mavlink.MAV_TYPE_GCS, mavlink.MAV_AUTOPILOT_INVALID, 0, 0, 0)
            beat = time.monotonic()
        msg = m.recv_match(type="GIMBAL_DEVICE_ATTITUDE_STATUS", blocking=True, timeout=0.1)
        if msg is not None and msg.get_srcComponent() == GIMBAL:
            statuses += 1
    return {"statuses": statuses}


def step_request_once(m, a):
    """One MAV_CMD_REQUEST_MESSAGE for GIMBAL_MANAGER_INFORMATION; then
    everything that came for `listen_s`: how many ACKs of it and how many
    information messages (one of each is the answer)."""
    m.mav.command_long_send(1, GIMBAL, mavlink.MAV_CMD_REQUEST_MESSAGE, 0, 280, 0, 0, 0, 0, 0, 0)
    end = time.monotonic() + a.get("listen_s", 2.0)
    acks, infos, result = 0, 0, None
    while time.monotonic() < end:
        msg = m.recv_match(type=["COMMAND_ACK", "GIMBAL_MANAGER_INFORMATION"], blocking=True, timeout=0.1)
        if msg is None or msg.get_srcComponent() != GIMBAL:
            continue
        if msg.get_type() == "COMMAND_ACK" and msg.command == mavlink.MAV_CMD_REQUEST_MESSAGE:
            acks += 1
            result = msg.result
        elif msg.get_type() == "GIMBAL_MANAGER_INFORMATION":
            infos += 1
    return {"acks": acks, "infos": infos, "result": result}


class Autopilot:
    """A simulated autopilot of system 1 (component 1, MAV_COMP_ID_AUTOPILOT1)
    on a connection of its own: HEARTBEAT (a quadrotor, PX4) every second,
    ATTITUDE with yaw `heading` (degrees) and, when `position` ([lat, lon,
    alt_m] and optionally home's altitude) is given, GLOBAL_POSITION_INT,
    both at `rate_hz`, from a thread until stop()."""

    def __init__(self, port, cfg):
        self.m = connect(port, cfg.get("system", 1), 1)
        self.heading = cfg.get("heading", 0.0)
        self.position = cfg.get("position")
        self.rate_hz = cfg.get("rate_hz", 10.0)
        self.running = True
        self.thread = threading.Thread(target=self.run, daemon=True)
        self.thread.start()

    def run(self):
        t0, beat = time.monotonic(), 0.0
        while self.running:
            now = time.monotonic()
            boot_ms = int((now - t0) * 1000)
            if now - beat >= 1.0:
                self.m.mav.heartbeat_send(mavlink.MAV_TYPE_QUADROTOR, mavlink.MAV_AUTOPILOT_PX4, 0, 0, 4)
                beat = now
            self.m.mav.attitude_send(boot_ms, 0.0, 0.0, math.radians(self.heading), 0.0, 0.0, 0.0)
            if self.position is not None:
                lat, lon, alt = self.position[:3]
                home = self.position[3] if len(self.position) > 3 else alt
                hdg = int((self.heading % 360.0) * 100)
                self.m.mav.global_position_int_send(boot_ms, int(round(lat * 1e7)), int(round(lon * 1e7)),
                                                    int(alt * 1000), int((alt - home) * 1000), 0, 0, 0, hdg)
            time.sleep(1.0 / self.rate_hz)

    def stop(self):
        self.running = False
        self.thread.join(timeout=5.0)


def step_roi_turn(m, a):
    """With the autopilot (`autopilot`, started by main) at its heading: a
    MAV_CMD_DO_SET_ROI_LOCATION as COMMAND_INT at `roi` ([lat, lon, alt_m],
    MAV_FRAME_GLOBAL); the attitude status until near (`pitch`, `yaw1`);
    then the vehicle turns to heading `heading2`, and the attitude status
    until near (`pitch`, `yaw2`). The ACK's result and whether each was
    reached (from the gimbal's own reports, the bus's P? answers)."""
    lat, lon, alt = a["roi"]
    result = command_int(m, mavlink.MAV_CMD_DO_SET_ROI_LOCATION, [0, 0, 0, 0, lat * 1e7, lon * 1e7, alt])
    out = {"result": result}
    near = lambda yaw: lambda msg: abs(attitude_of(msg)["yaw"] - yaw) <= 0.5 \
        and abs(attitude_of(msg)["pitch"] - a["pitch"]) <= 0.5
    out["reached1"] = wait(m, "GIMBAL_DEVICE_ATTITUDE_STATUS", near(a["yaw1"])) is not None
    AUTOPILOT.heading = a["heading2"]
    out["reached2"] = wait(m, "GIMBAL_DEVICE_ATTITUDE_STATUS", near(a["yaw2"])) is not None
    return out


AUTOPILOT = None

STEPS = {name[5:]: f for name, f in globals().items() if name.startswith("step_")}


def main():
    step, port, sysid, compid = sys.argv[1], sys.argv[2], int(sys.argv[3]), int(sys.argv[4])
    args = json.loads(sys.argv[5]) if len(sys.argv) > 5 else {}
    global AUTOPILOT
    if "autopilot" in args:
        # Heard a few times before the step; `for_s`: only that long, then
        # silent for `delay_s` (a heading gone stale).
        cfg = args["autopilot"]
        AUTOPILOT = Autopilot(port, cfg)
        time.sleep(cfg.get("for_s", 0.5))
        if "for_s" in cfg:
            AUTOPILOT.stop()
        time.sleep(cfg.get("delay_s", 0.0))
    m = connect(port, sysid, compid)
    out = STEPS[step](m, args)
    if AUTOPILOT is not None:
        AUTOPILOT.stop()
    print(json.dumps(out, default=str))


if __name__ == "__main__":
    main()
