"""Races against gimbal-onvif's motion ownership, for tests/door_motion.rs.

Usage: python3 race.py STEP HOST PORT USER PASSWORD [ARGS_JSON]

Driven through onvif-zeep-async, as tests/onvif/client.py: requests are
posted without awaiting the one before, as a joystick or an impatient VMS
does. Prints one JSON object on stdout. Every wait is bounded.

Steps:
- race {"kind": K, "trials": N, "seed": S}: N times, a ContinuousMove
  (pan at 24 to 48 deg/s, a new rate and direction each time, Timeout 2 s) and, 0 to 100 ms after it was
  posted, the request K: "stop", "absolute", "home", "zoom_stop" (Stop with
  PanTilt=false) or "zero_x" (a ContinuousMove whose only velocity is x=0,
  after a tilt move instead of a pan move). Reports each request's outcome.
- flood_then_stop {"moves": 40, "hz": 20}: ContinuousMoves (Timeout 1 s)
  with a changing pan velocity posted at that rate, none awaited, then a Stop: reports
  when the Stop was posted and answered (monotonic seconds).
"""

import asyncio
import datetime as dt
import json
import random
import sys
import time

from onvif import ONVIFCamera

import schema


async def outcome(coro):
    try:
        await coro
        return "ok"
    except schema.Invalid:  # a response the ONVIF XSDs refuse fails the step
        raise
    except Exception as err:  # a fault is an outcome here
        return f"{type(err).__name__}: {err}"


PTZ = "http://www.onvif.org/ver20/ptz/wsdl"
TT = "http://www.onvif.org/ver10/schema"


async def raw_post(endpoint, user, password, body):
    """`body` in a SOAP envelope signed by zeep's UsernameToken (digest), posted with httpx."""
    import httpx
    from lxml import etree
    from zeep.wsse.username import UsernameToken

    env = etree.fromstring(
        '<s:Envelope xmlns:s="http://www.w3.org/2003/05/soap-envelope"><s:Header/><s:Body>'
        + body + '</s:Body></s:Envelope>')
    env, _ = UsernameToken(user, password, use_digest=True).apply(env, {})
    async with httpx.AsyncClient(timeout=30) as http:
        r = await http.post(endpoint, content=etree.tostring(env),
                            headers={"Content-Type": "application/soap+xml"})
    if "xml" in r.headers.get("content-type", ""):  # a SOAP answer, not the listener's own refusal
        schema.check(r.content)
    if r.status_code != 200:
        raise RuntimeError(f"HTTP {r.status_code}: {r.text[:300]}")


async def race(ptz, token, args):
    rng = random.Random(args.get("seed", 1))
    kind = args["kind"]
    results = []
    for trial in range(args["trials"]):
        delay = rng.uniform(0.0, 0.1)
        # Slow enough that an escaped move is still moving 3 s later: 24 to
        # 48 deg/s pan (at least 3.75 s to the end of travel), 15 deg/s tilt
        # (6 s to its end). The direction alternates and the pan rates of
        # four trials add up to nothing, so that moves that legitimately run
        # their Timeout do not add up to the end of travel; the pan rate
        # changes at every trial, so that every move sets a speed before its
        # direction (chained, ARCHITECTURE "Delivery contract") and the
        # request K races that chain too.
        sign = 1.0 if trial % 2 == 0 else -1.0
        pan = (0.2, 0.3, 0.4, 0.3)[trial % 4]
        velocity = ({"PanTilt": {"x": 0.0, "y": 0.1 * sign}} if kind == "zero_x"
                    else {"PanTilt": {"x": pan * sign, "y": 0.0}})
        move = asyncio.ensure_future(outcome(ptz.ContinuousMove(
            {"ProfileToken": token, "Velocity": velocity, "Timeout": dt.timedelta(seconds=2)})))
        await asyncio.sleep(delay)
        if kind == "stop":
            second = ptz.Stop({"ProfileToken": token, "PanTilt": True, "Zoom": True})
        elif kind == "zoom_stop":
            second = ptz.Stop({"ProfileToken": token, "PanTilt": False, "Zoom": True})
        elif kind == "absolute":
            second = ptz.AbsoluteMove({"ProfileToken": token, "Position": {"PanTilt": {"x": 0.0, "y": 0.0}}})
        elif kind == "home":
            second = ptz.GotoHomePosition({"ProfileToken": token})
        elif kind == "zero_x":
            # zeep refuses a PanTilt without y; such clients exist, so it goes
            # out as zeep's own WS-Security would sign it, over httpx.
            second = raw_post(args["endpoint"], args["user"], args["password"],
                              f'<tptz:ContinuousMove xmlns:tptz="{PTZ}" xmlns:tt="{TT}">'
                              f'<tptz:ProfileToken>{token}</tptz:ProfileToken>'
                              '<tptz:Velocity><tt:PanTilt x="0"/></tptz:Velocity></tptz:ContinuousMove>')
        else:
            raise SystemExit(f"unknown kind {kind}")
        results.append({"delay_ms": round(delay * 1000), "move": await move, "second": await outcome(second)})
        await asyncio.sleep(0.05)
    return {"trials": results}


async def flood_then_stop(ptz, token, args):
    posted = []
    period = 1.0 / args.get("hz", 20)
    for i in range(args.get("moves", 40)):
        x = 0.3 + 0.7 * ((i % 7) / 6.0)
        # Timeout 1 s: a move that reaches the door after the Stop (HTTP
        # requests on separate connections may overtake one another) is a
        # newer move, and ends by itself.
        posted.append(asyncio.ensure_future(outcome(ptz.ContinuousMove(
            {"ProfileToken": token, "Velocity": {"PanTilt": {"x": x, "y": 0.0}},
             "Timeout": dt.timedelta(seconds=1)}))))
        await asyncio.sleep(period)
    stop_posted = time.monotonic()
    stop = await outcome(ptz.Stop({"ProfileToken": token, "PanTilt": True, "Zoom": True}))
    stop_answered = time.monotonic()
    moves = await asyncio.gather(*posted)
    return {"stop": stop, "stop_answer_s": stop_answered - stop_posted,
            "moves_ok": sum(1 for m in moves if m == "ok"), "moves": len(moves)}


async def step(name, host, port, user, password, args):
    cam = ONVIFCamera(host, port, user, password, no_cache=True)
    await cam.update_xaddrs()
    try:
        media = await cam.create_media_service()
        ptz = await cam.create_ptz_service()
        token = (await media.GetProfiles())[0].token
        if name == "race":
            args = {**args, "endpoint": f"http://{host}:{port}/onvif/ptz_service", "user": user,
                    "password": password}
            return await race(ptz, token, args)
        if name == "flood_then_stop":
            return await flood_then_stop(ptz, token, args)
        raise SystemExit(f"unknown step {name}")
    finally:
        await cam.close()


def main():
    schema.install()  # every response zeep receives is checked against the ONVIF XSDs
    name, host, port, user, password = sys.argv[1:6]
    args = json.loads(sys.argv[6]) if len(sys.argv) > 6 else {}
    result = asyncio.run(asyncio.wait_for(step(name, host, int(port), user, password, args), 120))
    print(json.dumps(result, default=str))


if __name__ == "__main__":
    main()
