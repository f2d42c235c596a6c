"""A CCTV keyboard for tests/pelco.rs: the PyPI `pyptzcontroller` package
(Pelco-D over a serial port) driving gimbal-pelco through a pseudo-terminal.

    client.py STEP SERIAL ARGS...

Steps (each prints one JSON line):
    hold DIR SPEED SECONDS   move DIR (up/down/left/right) at SPEED (0..63),
                             repeated every 100 ms for SECONDS as a keyboard
                             repeats while the stick is held; no stop
    once DIR SPEED           move DIR once, never repeated, no stop
    stop                     the stop command
    set_preset N / go_to_preset N / clear_preset N
    move_to PAN TILT         absolute pan and tilt (pyptzcontroller's
                             move_to_pan_tilt: 0..359.99, -85..20 degrees)
    position                 the position queries (51, 53), as
                             {"pan": ..., "tilt": ...}
    joystick SECONDS         a 20 Hz stream of drives at changing speeds,
                             then the stop
"""

import contextlib
import io
import json
import sys
import time

from ptz_control_lib import PtzControl


def main():
    step, port, args = sys.argv[1], sys.argv[2], sys.argv[3:]
    # pyptzcontroller talks (in Chinese) on stdout; only our JSON goes there.
    with contextlib.redirect_stdout(io.StringIO()):
        ptz = PtzControl(port, address=1, baudrate=9600)
        if not ptz.connect():
            raise SystemExit(f"cannot open {port}")
        out = run(ptz, step, args)
        ptz.disconnect()
    print(json.dumps(out))


def run(ptz, step, args):
    if step == "hold":
        direction, speed, seconds = args[0], int(args[1]), float(args[2])
        end = time.monotonic() + seconds
        sent = 0
        while time.monotonic() < end:
            ptz.move(direction, speed)
            sent += 1
            time.sleep(0.1)
        return {"sent": sent}
    if step == "once":
        ptz.move(args[0], int(args[1]))
        return {"sent": 1}
    if step == "stop":
        ptz.stop()
        return {"sent": 1}
    if step == "set_preset":
        ptz.set_preset(int(args[0]))
        return {"sent": 1}
    if step == "go_to_preset":
        ptz.go_to_preset(int(args[0]))
        return {"sent": 1}
    if step == "clear_preset":
        # pyptzcontroller's protocol table has it; its class has no method.
        ptz._send_command(ptz._create_command("clear_preset", preset_id=int(args[0])))
        return {"sent": 1}
    if step == "move_to":
        ptz.move_to_pan_tilt(float(args[0]), float(args[1]))
        return {"sent": 2}
    if step == "position":
        pan, tilt = ptz.get_position()
        return {"pan": pan, "tilt": tilt}
    if step == "joystick":
        end = time.monotonic() + float(args[0])
        sent = 0
        while time.monotonic() < end:
            ptz.move("right", 20 + (sent * 7) % 40)
            sent += 1
            time.sleep(0.05)
        ptz.stop()
        return {"sent": sent}
    raise SystemExit(f"unknown step {step}")


if __name__ == "__main__":
    main()
