"""One step of a VISCA over IP controller, with the PyPI `visca-over-ip`
package's `Camera` (tests/requirements.txt), against gimbal-visca:
`client.py STEP IP PORT [ARGS...]` prints one JSON line.

The package's `pantilt` docstring describes the direction backwards: a
negative pan speed sends `01` (left in Sony's list), a negative tilt
speed `01` (up). The steps pass its numbers through unchanged; the test
asserts what the gimbal did on the bus.

Its `Camera` binds its inquiry socket to the camera's port on every
address (with SO_REUSEADDR): the door under test listens on 127.0.0.2
with `reuse_address`, so both fit on one host.
"""

import json
import socket
import sys
import time

from visca_over_ip import Camera
from visca_over_ip.exceptions import ViscaException


def day_seconds():
    """Seconds of the UTC day, as gcud's log timestamps give them."""
    return time.time() % 86400.0


def out(value):
    print(json.dumps(value))


def attempt(fn):
    """The outcome of one command: ok, or the VISCA error's code."""
    try:
        fn()
        return {"ok": True}
    except ViscaException as e:
        return {"error": e.status_code}


def main():
    step, ip, port = sys.argv[1], sys.argv[2], int(sys.argv[3])
    args = sys.argv[4:]
    cam = Camera(ip, port)
    try:
        if step == "pantilt":
            out(attempt(lambda: cam.pantilt(int(args[0]), int(args[1]))))
        elif step == "stop":
            out(attempt(lambda: cam.pantilt(0, 0)))
        elif step == "home":
            out(attempt(cam.pantilt_home))
        elif step == "absolute":
            out(attempt(lambda: cam.pantilt(24, 20, int(args[0]), int(args[1]))))
        elif step == "relative":
            out(attempt(lambda: cam.pantilt(24, 20, int(args[0]), int(args[1]), relative=True)))
        elif step == "save":
            out(attempt(lambda: cam.save_preset(int(args[0]))))
        elif step == "recall":
            out(attempt(lambda: cam.recall_preset(int(args[0]))))
        elif step == "position":
            pan, tilt = cam.get_pantilt_position()
            out({"pan": pan, "tilt": tilt})
        elif step == "zoom_position":
            started = time.monotonic()
            try:
                out({"zoom": cam.get_zoom_position()})
            except ViscaException as e:
                out({"error": e.status_code, "seconds": time.monotonic() - started})
        elif step == "inquiry":
            # An inquiry the door does not implement (args[0], hex): its
            # error and how long it took.
            started = time.monotonic()
            try:
                reply = cam._send_command(args[0], query=True)
                out({"reply": reply.hex()})
            except ViscaException as e:
                out({"error": e.status_code, "seconds": time.monotonic() - started})
        elif step == "stream":
            # A joystick: the drive (args[0], args[1]) at 20 Hz for args[2]
            # seconds, then a stop; when the stop left, in day seconds.
            pan, tilt, seconds = int(args[0]), int(args[1]), float(args[2])
            end = time.monotonic() + seconds
            sent = 0
            while time.monotonic() < end:
                cam.pantilt(pan, tilt)
                sent += 1
                time.sleep(0.05)
            stop_at = day_seconds()
            result = attempt(lambda: cam.pantilt(0, 0))
            out({"sent": sent, "stop_at": stop_at, **result})
        elif step == "stop_latency":
            # args[1] rounds of: a drive, then (args[0] s later) a stop; when
            # each drive and stop left, in day seconds.
            wait, rounds = float(args[0]), int(args[1])
            drives, stops = [], []
            for i in range(rounds):
                drives.append(day_seconds())
                cam.pantilt(12 if i % 2 else -12, 0)
                time.sleep(wait)
                stops.append(day_seconds())
                cam.pantilt(0, 0)
                time.sleep(wait)
            out({"drives": drives, "stops": stops})
        else:
            raise SystemExit(f"unknown step {step}")
    finally:
        cam.close_connection()


if __name__ == "__main__":
    main()
