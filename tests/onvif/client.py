"""Third-party ONVIF clients driving gimbal-onvif, for tests/onvif.rs.

Usage: python3 client.py STEP HOST PORT USER PASSWORD [ARGS_JSON]

HOST may be https://IP: onvif-zeep-async then speaks HTTPS to the device
(it verifies no certificate), and follows the XAddrs the device gives.

Each STEP talks to one gimbal's ONVIF device through onvif-zeep-async
(the library Home Assistant's ONVIF integration uses) or, for discovery,
through WSDiscovery's message layer (the package Home Assistant uses for
WS-Discovery) over a unicast UDP socket on loopback. It prints one JSON
object on stdout: what the client saw, for the Rust test to assert on.
Every SOAP response it receives, through zeep or posted raw, is first
validated against the ONVIF XSDs (schema.py): an invalid one ends the step
with the first invalid element and its path, and fails the test.
Faults are results too: {"fault": {"subcodes": [...], "message": ...}}.
Every wait is bounded.
"""

import asyncio
import datetime as dt
import json
import socket
import sys
import time

from onvif import ONVIFCamera
from zeep.exceptions import Fault

import schema

schema.install()

PROFILE = None


def fault_of(err):
    """The zeep Fault behind an error (onvif-zeep-async may wrap it)."""
    seen = err
    for _ in range(4):
        if isinstance(seen, Fault):
            return seen
        seen = seen.__cause__ or seen.__context__
        if seen is None:
            break
    return None


def describe(err):
    f = fault_of(err)
    if f is None:
        return {"error": f"{type(err).__name__}: {err}"}
    subcodes = [q.localname if hasattr(q, "localname") else str(q) for q in (f.subcodes or [])]
    return {"fault": {"code": str(f.code), "subcodes": subcodes, "message": f.message}}


async def attempt(coro):
    try:
        return {"ok": await coro}
    except schema.Invalid:
        raise  # an invalid response is no result: the step fails
    except Exception as err:  # a fault is a result here
        return describe(err)


async def camera(host, port, user, password):
    cam = ONVIFCamera(host, port, user, password, no_cache=True)
    await cam.update_xaddrs()
    return cam


def status_of(s):
    pos = s.Position.PanTilt if s.Position is not None else None
    zoom = s.Position.Zoom if s.Position is not None else None
    return {
        "zoom": None if zoom is None else zoom.x,
        "x": None if pos is None else pos.x,
        "y": None if pos is None else pos.y,
        "moving": None if s.MoveStatus is None else str(s.MoveStatus.PanTilt),
        "error": s.Error,
        "utc": str(s.UtcTime),
    }


async def wait_idle(ptz, token, seconds=30.0):
    """GetStatus until the move ends (IDLE twice in a row), at most `seconds`."""
    deadline = time.monotonic() + seconds
    idle = 0
    last = None
    while time.monotonic() < deadline:
        last = status_of(await ptz.GetStatus({"ProfileToken": token}))
        idle = idle + 1 if last["moving"] == "IDLE" else 0
        if idle >= 2:
            return last
        await asyncio.sleep(0.2)
    return {"timed_out": True, **(last or {})}


async def step(name, host, port, user, password, args):
    if name == "discover":
        return discover(host, port, args)
    if name == "malformed":
        return await malformed(host, port, args)
    if name == "http_digest":
        return await http_digest(host, port, user, password, args)
    if name == "login":
        return await attempt(login(host, port, user, password))
    if name == "signed_raw":
        return await signed_raw(host, port, user, password, args)
    cam = await camera(host, port, user, password)
    try:
        media = await cam.create_media_service()
        ptz = await cam.create_ptz_service()
        profiles = await media.GetProfiles()
        token = profiles[0].token
        if name == "info":
            dev = await cam.create_devicemgmt_service()
            info = await attempt(dev.GetDeviceInformation())
            if "ok" in info:
                i = info["ok"]
                info = {"ok": {k: getattr(i, k) for k in
                               ["Manufacturer", "Model", "FirmwareVersion", "SerialNumber", "HardwareId"]}}
            uri = await attempt(media.GetStreamUri({
                "ProfileToken": token,
                "StreamSetup": {"Stream": "RTP-Unicast", "Transport": {"Protocol": "RTSP"}},
            }))
            if "ok" in uri:
                uri = {"ok": uri["ok"].Uri}
            clock = (await dev.GetSystemDateAndTime()).UTCDateTime
            media_caps = await media.GetServiceCapabilities()
            ptz_caps = await ptz.GetServiceCapabilities()
            hostname = await dev.GetHostname()
            scopes = await dev.GetScopes()
            nics = await dev.GetNetworkInterfaces()
            nodes = await ptz.GetNodes()
            options = await ptz.GetConfigurationOptions({"ConfigurationToken": profiles[0].PTZConfiguration.token})
            return {
                "device": info,
                "profiles": [{
                    "token": p.token,
                    "name": p.Name,
                    "ptz": p.PTZConfiguration is not None,
                    "encoding": None if p.VideoEncoderConfiguration is None else str(p.VideoEncoderConfiguration.Encoding),
                } for p in profiles],
                "stream_uri": uri,
                "hostname": hostname.Name,
                "utc": {"year": clock.Date.Year, "hour": None if clock.Time is None else clock.Time.Hour},
                "snapshot": media_caps.SnapshotUri,
                "eflip": ptz_caps.EFlip,
                "scopes": [str(s.ScopeItem) for s in scopes],
                "mac": nics[0].Info.HwAddress,
                "nodes": [n.token for n in nodes],
                "presets_max": nodes[0].MaximumNumberOfPresets,
                "velocity_space": options.Spaces.ContinuousPanTiltVelocitySpace[0].URI,
            }
        if name == "status":
            return status_of(await ptz.GetStatus({"ProfileToken": token}))
        if name == "xaddrs":
            return await xaddrs(cam, host, port, args)
        if name == "relative_spaces":
            # What Frigate's autotracker checks before it can be switched on:
            # the FOV space among the node's and the options' relative spaces,
            # and the profile's default relative space.
            nodes = await ptz.GetNodes()
            options = await ptz.GetConfigurationOptions({"ConfigurationToken": profiles[0].PTZConfiguration.token})

            def ranges(spaces):
                return [{"uri": sp.URI, "x": [sp.XRange.Min, sp.XRange.Max], "y": [sp.YRange.Min, sp.YRange.Max]}
                        for sp in spaces.RelativePanTiltTranslationSpace]
            return {
                "node": ranges(nodes[0].SupportedPTZSpaces),
                "options": ranges(options.Spaces),
                "default": profiles[0].PTZConfiguration.DefaultRelativePanTiltTranslationSpace,
            }
        if name == "relative":
            translation = {"PanTilt": {"x": args["x"], "y": args["y"]}}
            if args.get("space"):
                translation["PanTilt"]["space"] = args["space"]
            if args.get("zoom") is not None:
                translation["Zoom"] = {"x": args["zoom"]}
            moved = await attempt(ptz.RelativeMove({"ProfileToken": token, "Translation": translation}))
            if "ok" not in moved:
                return moved
            return {"ok": True, "status": await wait_idle(ptz, token)}
        if name == "continuous":
            req = {"ProfileToken": token, "Velocity": pan_tilt_of(args)}
            if args.get("zoom") is not None:
                req["Velocity"]["Zoom"] = {"x": args["zoom"]}
            if args.get("timeout_s") is not None:
                req["Timeout"] = dt.timedelta(seconds=args["timeout_s"])
            result = await attempt(ptz.ContinuousMove(req))
            if "ok" in result:
                result = {"ok": True, "status": status_of(await ptz.GetStatus({"ProfileToken": token}))}
            elif args.get("status_after"):
                # What GetStatus says right after a refused move.
                result["status"] = status_of(await ptz.GetStatus({"ProfileToken": token}))
            return result
        if name == "absolute_truth":
            return await absolute_truth(ptz, token, args)
        if name == "takeover":
            return await takeover(ptz, token, args)
        if name == "stop":
            return await attempt(ptz.Stop({"ProfileToken": token,
                                           "PanTilt": args.get("pan_tilt", True),
                                           "Zoom": args.get("zoom", True)}))
        if name == "absolute":
            position = pan_tilt_of(args)
            if args.get("zoom") is not None:
                position["Zoom"] = {"x": args["zoom"]}
            moved = await attempt(ptz.AbsoluteMove({"ProfileToken": token, "Position": position}))
            if "ok" not in moved:
                return moved
            return {"ok": True, "status": await wait_idle(ptz, token)}
        if name == "set_preset":
            r = await attempt(ptz.SetPreset({"ProfileToken": token, "PresetName": args["name"]}))
            return {"ok": r["ok"]} if "ok" in r else r
        if name == "goto_preset":
            moved = await attempt(ptz.GotoPreset({"ProfileToken": token, "PresetToken": args["token"]}))
            if "ok" not in moved:
                return moved
            return {"ok": True, "status": await wait_idle(ptz, token)}
        if name == "presets":
            presets = await ptz.GetPresets({"ProfileToken": token})
            return {"presets": [{"token": p.token, "name": p.Name} for p in presets]}
        if name == "out_of_range":
            return await attempt(ptz.AbsoluteMove({
                "ProfileToken": token, "Position": {"PanTilt": {"x": 2.5, "y": 0.0}}}))
        if name == "wrong_profile":
            return await attempt(ptz.GetStatus({"ProfileToken": "nope"}))
        if name == "tokens":
            return await tokens(media, ptz, profiles)
        if name == "set_timeout":
            config = await ptz.GetConfiguration({"PTZConfigurationToken": profiles[0].PTZConfiguration.token})
            config.DefaultPTZTimeout = dt.timedelta(seconds=args["timeout_s"])
            r = await attempt(ptz.SetConfiguration({"PTZConfiguration": config, "ForcePersistence": True}))
            if "ok" not in r:
                return r
            again = await ptz.GetConfiguration({"PTZConfigurationToken": config.token})
            return {"ok": True, "timeout_s": again.DefaultPTZTimeout.total_seconds()}
        raise SystemExit(f"unknown step {name}")
    finally:
        await cam.close()


async def absolute_truth(ptz, token, args):
    """Frigate's autotracker's loop (issue 49): an AbsoluteMove to each of
    `args["targets"]`, GetStatus at once after it returned OK, then GetStatus
    every 50 ms until IDLE: per move, the first reading and the first IDLE
    one."""
    moves = []
    for x, y in args["targets"]:
        await ptz.AbsoluteMove({"ProfileToken": token, "Position": {"PanTilt": {"x": x, "y": y}}})
        first = status_of(await ptz.GetStatus({"ProfileToken": token}))
        deadline = time.monotonic() + 30.0
        idle = None
        while time.monotonic() < deadline:
            s = status_of(await ptz.GetStatus({"ProfileToken": token}))
            if s["moving"] == "IDLE":
                idle = s
                break
            await asyncio.sleep(0.05)
        moves.append({"target": [x, y], "first": first, "idle": idle})
    return {"moves": moves}


async def takeover(ptz, token, args):
    """A ContinuousMove, GetStatus; then one line on stdout ("ready") and
    a wait for one line on stdin (the test's: another controller took the
    gimbal just now); then GetStatus every 50 ms for `args["watch_s"]`:
    each reading with the time it was asked, in seconds after that line."""
    await ptz.ContinuousMove({"ProfileToken": token, "Velocity": {"PanTilt": {"x": args["x"], "y": 0.0}}})
    before = status_of(await ptz.GetStatus({"ProfileToken": token}))
    print(json.dumps({"ready": True, "status": before}), flush=True)
    await asyncio.get_running_loop().run_in_executor(None, sys.stdin.readline)
    t0 = time.monotonic()
    readings = []
    while time.monotonic() - t0 < args["watch_s"]:
        asked = time.monotonic() - t0
        s = status_of(await ptz.GetStatus({"ProfileToken": token}))
        readings.append({"t": asked, **s})
        await asyncio.sleep(0.05)
    return {"before": before, "readings": readings}


async def xaddrs(cam, host, port, args):
    """The service addresses the device gives (GetCapabilities,
    GetServices, and those onvif-zeep-async follows), and
    GetSystemDateAndTime posted with httpx trusting only the certificate
    in `args["cert"]` (the door's self-signed one: its names must hold
    the address)."""
    import ssl
    import httpx
    dev = await cam.create_devicemgmt_service()
    caps = await dev.GetCapabilities({"Category": "All"})
    services = await dev.GetServices({"IncludeCapability": False})
    trusted = ssl.create_default_context(cafile=args["cert"])
    ip = host.split("://")[-1]
    body = ('<?xml version="1.0"?><s:Envelope xmlns:s="http://www.w3.org/2003/05/soap-envelope"><s:Body>'
            '<GetSystemDateAndTime xmlns="http://www.onvif.org/ver10/device/wsdl"/></s:Body></s:Envelope>')
    async with httpx.AsyncClient(timeout=30, verify=trusted) as http:
        r = await http.post(f"https://{ip}:{port}/onvif/device_service", content=body.encode(),
                            headers={"Content-Type": "application/soap+xml"})
    return {
        "capabilities": [caps.Device.XAddr, caps.Media.XAddr, caps.PTZ.XAddr],
        "services": [s.XAddr for s in services],
        "followed": sorted(cam.xaddrs.values()),
        "verified": answer_of(r)["status"],
    }


async def tokens(media, ptz, profiles):
    """What a client pairing tokens reads (npm onvif, Scrypted): the first
    video source, the profile using it, the profile's PTZ configuration
    and the compatible ones; and CreateProfile's answer (Synology)."""
    sources = await media.GetVideoSources()
    first = sources[0].token if sources else None
    using = [p.token for p in profiles
             if p.VideoSourceConfiguration is not None and p.VideoSourceConfiguration.SourceToken == first]
    compatible = await ptz.GetCompatibleConfigurations({"ProfileToken": profiles[0].token})
    created = await attempt(media.CreateProfile({"Name": "another"}))
    return {
        "video_source": first,
        "profiles_using_it": using,
        "ptz_configuration": profiles[0].PTZConfiguration.token,
        "compatible": [c.token for c in compatible],
        "compatible_default_space": [c.DefaultRelativePanTiltTranslationSpace for c in compatible],
        "create_profile": created if "ok" not in created else {"ok": str(created["ok"])},
    }


async def signed_raw(host, port, user, password, args):
    """`args["body"]` in a SOAP envelope of `args["soap"]` (1.1 or 1.2)
    signed by zeep's UsernameToken (digest), posted with httpx with the
    Content-Type and SOAPAction the step names."""
    import httpx
    from lxml import etree
    from zeep.wsse.username import UsernameToken

    ns = {"1.1": schema.SOAP11, "1.2": schema.SOAP12}[args["soap"]]
    env = etree.fromstring(
        f'<s:Envelope xmlns:s="{ns}"><s:Header/><s:Body>' + args["body"] + "</s:Body></s:Envelope>")
    env, _ = UsernameToken(user, password, use_digest=True).apply(env, {})
    headers = {"Content-Type": args["content_type"]}
    if args.get("soap_action") is not None:
        headers["SOAPAction"] = args["soap_action"]
    async with httpx.AsyncClient(timeout=30) as http:
        r = await http.post(f"http://{host}:{port}/onvif/{args.get('service', 'ptz_service')}",
                            content=etree.tostring(env), headers=headers)
    return answer_of(r)


def pan_tilt_of(args):
    """A PanTilt vector when the step gives x and y; none for the zoom alone."""
    if args.get("x") is None and args.get("y") is None:
        return {}
    return {"PanTilt": {"x": args["x"], "y": args["y"]}}


async def login(host, port, user, password):
    cam = await camera(host, port, user, password)
    await cam.close()
    return True


async def malformed(host, port, args):
    """Posts a broken body with the HTTP client zeep itself uses."""
    import httpx
    async with httpx.AsyncClient(timeout=30) as http:
        r = await http.post(f"http://{host}:{port}/onvif/ptz_service", content=args["body"].encode(),
                            headers={"Content-Type": "application/soap+xml"})
    return answer_of(r)


async def http_digest(host, port, user, password, args):
    """A SOAP request with HTTP Digest authentication (httpx.DigestAuth) and no WS-Security."""
    import httpx
    body = ('<?xml version="1.0"?><s:Envelope xmlns:s="http://www.w3.org/2003/05/soap-envelope"><s:Body>'
            + args["operation"] + '</s:Body></s:Envelope>')
    async with httpx.AsyncClient(timeout=30, auth=httpx.DigestAuth(user, password)) as http:
        r = await http.post(f"http://{host}:{port}/onvif/ptz_service", content=body.encode(),
                            headers={"Content-Type": "application/soap+xml"})
    return {**answer_of(r), "challenge": r.headers.get("www-authenticate")}


def answer_of(r):
    """A raw httpx answer, its SOAP body validated against the ONVIF XSDs."""
    content_type = r.headers.get("content-type", "")
    if "soap+xml" in content_type or "text/xml" in content_type:
        schema.check(r.content)
    return {"status": r.status_code, "body": r.text, "content_type": content_type}


def discover(host, port, args):
    """A unicast Probe built and read by WSDiscovery's message layer."""
    from wsdiscovery import QName, Scope
    from wsdiscovery.actions.probe import constructProbe
    from wsdiscovery.message import createSOAPMessage, parseSOAPMessage

    types = [QName("http://www.onvif.org/ver10/network/wsdl", "NetworkVideoTransmitter", "dn")]
    env = constructProbe(types, [Scope(s) for s in args.get("scopes", [])])
    data = createSOAPMessage(env)
    sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    sock.settimeout(1.0)
    sock.bind(("127.0.0.1", 0))
    sock.sendto(data.encode() if isinstance(data, str) else data, (host, port))
    matches = []
    deadline = time.monotonic() + args.get("wait_s", 3.0)
    while time.monotonic() < deadline and len(matches) < args.get("expect", 1):
        try:
            reply, addr = sock.recvfrom(65536)
        except socket.timeout:
            continue
        parsed = parseSOAPMessage(reply, addr[0])
        if parsed is None or parsed.getRelatesTo() != env.getMessageId():
            continue
        for m in parsed.getProbeResolveMatches():
            matches.append({
                "epr": m.getEPR(),
                "xaddrs": m.getXAddrs(),
                "types": [t.getLocalname() for t in m.getTypes()],
                "scopes": [s.getValue() for s in m.getScopes()],
            })
    return {"matches": matches}


def main():
    name, host, port, user, password = sys.argv[1:6]
    args = json.loads(sys.argv[6]) if len(sys.argv) > 6 else {}
    result = asyncio.run(asyncio.wait_for(step(name, host, int(port), user, password, args), 90))
    print(json.dumps(result, default=str))


if __name__ == "__main__":
    main()
