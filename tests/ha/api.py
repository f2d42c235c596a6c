"""Home Assistant's HTTP API for tests/mqtt/home_assistant.rs, one step per
run, its answer as JSON on the last line of stdout. Run by tests/ha/.venv's
Python (the standard library only: urllib).

    api.py setup URL BROKER_PORT        onboarding's first user (its auth
                                        code traded for an access token at
                                        /auth/token), then the MQTT
                                        integration's config flow pointed at
                                        127.0.0.1:BROKER_PORT -> {"token",
                                        "entry"}
    api.py states URL TOKEN             GET /api/states -> the list
    api.py service URL TOKEN DOMAIN SERVICE JSON
                                        POST /api/services/DOMAIN/SERVICE

The endpoints are Home Assistant's documented REST API
(developers.home-assistant.io, "REST API"), onboarding's views
(homeassistant/components/onboarding/views.py) and the config entries'
flow views (homeassistant/components/config/config_entries.py).
"""

import json
import sys
import urllib.error
import urllib.parse
import urllib.request

TIMEOUT_S = 30


def request(url, path, token=None, body=None, form=None):
    headers = {}
    data = None
    if token:
        headers["Authorization"] = "Bearer " + token
    if body is not None:
        data = json.dumps(body).encode()
        headers["Content-Type"] = "application/json"
    if form is not None:
        data = urllib.parse.urlencode(form).encode()
        headers["Content-Type"] = "application/x-www-form-urlencoded"
    req = urllib.request.Request(url + path, data=data, headers=headers)
    try:
        with urllib.request.urlopen(req, timeout=TIMEOUT_S) as r:
            return json.loads(r.read() or b"null")
    except urllib.error.HTTPError as e:
        sys.exit(f"{req.get_method()} {path}: HTTP {e.code}: {e.read().decode(errors='replace')}")


def setup(url, broker_port):
    client_id = url + "/"
    code = request(
        url,
        "/api/onboarding/users",
        body={
            "client_id": client_id,
            "name": "Test",
            "username": "test",
            "password": "test-password",
            "language": "en",
        },
    )["auth_code"]
    token = request(
        url,
        "/auth/token",
        form={"grant_type": "authorization_code", "code": code, "client_id": client_id},
    )["access_token"]
    flow = request(url, "/api/config/config_entries/flow", token, {"handler": "mqtt"})
    if flow.get("step_id") != "broker":
        sys.exit(f"the MQTT config flow did not ask for the broker: {flow}")
    done = request(
        url,
        "/api/config/config_entries/flow/" + flow["flow_id"],
        token,
        {"broker": "127.0.0.1", "port": int(broker_port)},
    )
    if done.get("type") != "create_entry":
        sys.exit(f"the MQTT config flow did not create an entry: {done}")
    return {"token": token, "entry": done.get("result", {}).get("entry_id")}


def main(argv):
    step, url = argv[1], argv[2]
    if step == "setup":
        out = setup(url, argv[3])
    elif step == "states":
        out = request(url, "/api/states", argv[3])
    elif step == "service":
        token, domain, service, data = argv[3:7]
        out = request(url, f"/api/services/{domain}/{service}", token, json.loads(data))
    else:
        sys.exit(f"unknown step {step}")
    print(json.dumps(out))


if __name__ == "__main__":
    main(sys.argv)
