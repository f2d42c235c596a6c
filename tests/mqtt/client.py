"""paho-mqtt as gimbal-mqtt's client in tests/mqtt: one step per run,
printing one JSON line (tests/support/door.rs `python_step`).

    client.py STEP PORT ARGS...   (the broker on 127.0.0.1:PORT)

Steps:
  command TOPIC_BASE JSON              publish JSON on TOPIC_BASE/cmd, print its
                                       result from TOPIC_BASE/result (matched by id)
  retained TOPIC                       the retained message on TOPIC, or null
  publish TOPIC PAYLOAD [retain]       publish once (QoS 1)
  flood BASE COUNT PAYLOAD LAST        publish PAYLOAD COUNT times at once on BASE/cmd,
                                       then LAST (QoS 0, one connection: in order),
                                       print LAST's result and how many results came
  huge TOPIC BYTES                     publish a payload of BYTES spaces
  collect FILTER SECONDS               every message on FILTER for SECONDS
  wait_for TOPIC PAYLOAD SECONDS       seconds until PAYLOAD arrives on TOPIC
  results TOPIC_BASE SECONDS JSON...   publish each JSON, collect results for SECONDS
"""

import json
import sys
import threading
import time
import uuid

import paho.mqtt.client as mqtt

PORT = 0


def client(version=mqtt.MQTTv5):
    c = mqtt.Client(mqtt.CallbackAPIVersion.VERSION2, client_id="t-" + uuid.uuid4().hex[:12], protocol=version)
    c.connect("127.0.0.1", PORT, keepalive=30)
    c.loop_start()
    return c


def subscribed(topic, on_message):
    """A client subscribed to TOPIC (returns once the broker acknowledged)."""
    c = mqtt.Client(mqtt.CallbackAPIVersion.VERSION2, client_id="t-" + uuid.uuid4().hex[:12], protocol=mqtt.MQTTv5)
    done = threading.Event()
    c.on_subscribe = lambda *a: done.set()
    c.on_message = on_message
    c.on_connect = lambda cl, u, f, rc, p=None: cl.subscribe(topic, qos=1)
    c.connect("127.0.0.1", PORT, keepalive=30)
    c.loop_start()
    if not done.wait(30):
        raise SystemExit("no SUBACK for " + topic)
    return c


def command(base, payload, timeout=30.0):
    body = json.loads(payload)
    body.setdefault("id", uuid.uuid4().hex)
    got = threading.Event()
    out = {}

    def on_message(_c, _u, msg):
        r = json.loads(msg.payload)
        if r.get("id") == body["id"]:
            out.update(r)
            out["received"] = time.time()
            got.set()

    s = subscribed(base + "/result", on_message)
    p = client()
    out["published"] = time.time()
    p.publish(base + "/cmd", json.dumps(body), qos=1).wait_for_publish(30)
    if not got.wait(timeout):
        out["timeout"] = True
    s.disconnect()
    p.disconnect()
    return out


def retained(topic):
    got = threading.Event()
    out = {"message": None}

    def on_message(_c, _u, msg):
        if msg.retain:
            out["message"] = json.loads(msg.payload) if msg.payload[:1] == b"{" else msg.payload.decode()
        got.set()

    s = subscribed(topic, on_message)
    got.wait(1.0)  # a retained message comes right after the SUBACK
    s.disconnect()
    return out


def collect(filter_, seconds):
    msgs = []
    lock = threading.Lock()

    def on_message(_c, _u, msg):
        try:
            payload = json.loads(msg.payload)
        except ValueError:
            payload = msg.payload.decode(errors="replace")
        with lock:
            msgs.append({"topic": msg.topic, "payload": payload, "retain": bool(msg.retain), "at": time.time()})

    s = subscribed(filter_, on_message)
    time.sleep(seconds)
    s.disconnect()
    return {"messages": msgs}


def wait_for(topic, payload, seconds):
    got = threading.Event()

    def on_message(_c, _u, msg):
        if msg.payload.decode(errors="replace") == payload:
            got.set()

    start = time.time()
    s = subscribed(topic, on_message)
    ok = got.wait(seconds)
    s.disconnect()
    return {"arrived": ok, "after_s": time.time() - start}


def flood(base, count, payload, last):
    last_id = json.loads(last)["id"]
    got = threading.Event()
    out = {"results": 0}

    def on_message(_c, _u, msg):
        r = json.loads(msg.payload)
        out["results"] += 1
        if r.get("id") == last_id:
            out["last"] = r
            got.set()

    s = subscribed(base + "/result", on_message)
    p = client()
    infos = [p.publish(base + "/cmd", payload, qos=0) for _ in range(count)]
    infos.append(p.publish(base + "/cmd", last, qos=0))
    for i in infos:
        i.wait_for_publish(120)
    got.wait(120)
    time.sleep(1)
    s.disconnect()
    p.disconnect()
    return out


def results(base, seconds, payloads):
    msgs = []

    def on_message(_c, _u, msg):
        msgs.append(json.loads(msg.payload))

    s = subscribed(base + "/result", on_message)
    p = client()
    for body in payloads:
        p.publish(base + "/cmd", body, qos=1).wait_for_publish(30)
    time.sleep(seconds)
    s.disconnect()
    p.disconnect()
    return {"results": msgs}


def main():
    global PORT
    step, PORT, args = sys.argv[1], int(sys.argv[2]), sys.argv[3:]
    if step == "command":
        out = command(args[0], args[1])
    elif step == "retained":
        out = retained(args[0])
    elif step == "publish":
        p = client()
        p.publish(args[0], args[1], qos=1, retain=len(args) > 2 and args[2] == "retain").wait_for_publish(30)
        p.disconnect()
        out = {"published": True}
    elif step == "flood":
        out = flood(args[0], int(args[1]), args[2], args[3])
    elif step == "huge":
        p = client()
        p.publish(args[0], b" " * int(args[1]), qos=1).wait_for_publish(60)
        p.disconnect()
        out = {"published": int(args[1])}
    elif step == "collect":
        out = collect(args[0], float(args[1]))
    elif step == "wait_for":
        out = wait_for(args[0], args[1], float(args[2]))
    elif step == "results":
        out = results(args[0], float(args[1]), args[2:])
    else:
        raise SystemExit("unknown step " + step)
    print(json.dumps(out))


if __name__ == "__main__":
    main()
