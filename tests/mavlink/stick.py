"""A ground station's stick through pymavlink, for tests/door_motion.rs.

Usage: python3 stick.py stick PORT GIMBALCTL GCUD ADDRESS

Sends GIMBAL_MANAGER_SET_PITCHYAW at 50 Hz to gimbal-mavlink's
udp_listen endpoint on 127.0.0.1:PORT for 3 s with a yaw rate that changes
every message (10 to 60 deg/s, as a held stick does), then yaw rate 0 at
50 Hz for 1.5 s (the stick released). Reads the gimbal's pan on the bus
side with `GIMBALCTL --tcp GCUD --to ADDRESS position` before, 0.5 s
after the first zero and 1.5 s after it. Prints one JSON object.
"""

import json
import math
import os
import subprocess
import sys
import time

os.environ["MAVLINK20"] = "1"

from pymavlink import mavutil  # noqa: E402

mavutil.set_dialect("common")
mavlink = mavutil.mavlink

GIMBAL = 154
HZ = 50


def pan(ctl, gcud, address):
    out = subprocess.run([ctl, "--json", "--tcp", gcud, "--to", address, "position"],
                         capture_output=True, text=True, timeout=10)
    return json.loads(out.stdout.strip().splitlines()[-1])["result"]["pan_deg"]


def main():
    _, port, ctl, gcud, address = sys.argv[1:6]
    m = mavutil.mavlink_connection(f"udpout:127.0.0.1:{port}", source_system=255, source_component=190,
                                   dialect="common")
    m.mav.heartbeat_send(mavlink.MAV_TYPE_GCS, mavlink.MAV_AUTOPILOT_INVALID, 0, 0, 0)
    nan = float("nan")
    start = pan(ctl, gcud, address)

    def send(rate_dps):
        m.mav.gimbal_manager_set_pitchyaw_send(1, GIMBAL, 0, 0, nan, nan, nan, math.radians(rate_dps))

    t0 = time.monotonic()
    i = 0
    while time.monotonic() - t0 < 3.0:
        send(10.0 + 50.0 * ((i % 11) / 10.0))
        i += 1
        if i % HZ == 0:
            m.mav.heartbeat_send(mavlink.MAV_TYPE_GCS, mavlink.MAV_AUTOPILOT_INVALID, 0, 0, 0)
        time.sleep(1.0 / HZ)
    first_zero = time.monotonic()
    readings = {}
    while time.monotonic() - first_zero < 1.5:
        send(0.0)
        elapsed = time.monotonic() - first_zero
        if elapsed >= 0.5 and "half" not in readings:
            readings["half"] = pan(ctl, gcud, address)
        time.sleep(1.0 / HZ)
    readings["late"] = pan(ctl, gcud, address)
    print(json.dumps({
        "sent": i,
        "moved_deg": abs(readings["half"] - start),
        "pan_at_0_5_s": readings["half"],
        "pan_at_1_5_s": readings["late"],
    }))


if __name__ == "__main__":
    main()
