#!/usr/bin/env python3
"""Independent zenoh peers (the `eclipse-zenoh` package from PyPI) against an `aeris agent`:
strangers who try to get in, and the flight's own host asking for what it must be refused.

Usage: zenoh_stranger.py REPORT.json --endpoint tls/ADDR:PORT --host HOST --flight FLIGHT
         --schema VERSION:LAYOUT_HASH --ca CA.pem --flight-host DIR --this-host DIR
         --intruder DIR --foreign DIR --plain tcp/ADDR:PORT --escape PATH

DIRs are identity directories (ca.pem, cert.pem, key.pem): the flight's host, the agent's
own host, a host of the flight's CA that the agent does not obey (`intruder`), and a
certificate of another CA named like the flight's host (`foreign`). Writes one JSON object:

  {"no_certificate" | "foreign_ca" | "plain_tcp": {"opened": bool, "error": str|null,
                                                   "info": bool},
   "intruder": {"opened", "info": bool, "spawn": bool, "delivered": int},
   "flight_host": {"info": dict|null, "spawns": {case: reply}, "delivered": int},
   "sent": int}

`info`/`spawn` are true when any answer came back; `delivered` counts the data messages a
subscriber holding this host's own identity received from that peer (each peer publishes
`sent` of them, interleaved). The protocol is written here from its description (key
expressions, JSON requests), not with AERIS-rs's code.
"""

import argparse
import json
import os
import sys
import time

import zenoh

TIMEOUT_S = 3.0


def config(endpoint, ca=None, identity=None):
    c = zenoh.Config()
    c.insert_json5("mode", '"client"')
    c.insert_json5("scouting/multicast/enabled", "false")
    c.insert_json5("connect/endpoints", json.dumps([endpoint]))
    c.insert_json5("connect/timeout_ms", "3000")
    c.insert_json5("connect/exit_on_failure", "true")
    tls = "transport/link/tls/"
    if ca:
        c.insert_json5(tls + "root_ca_certificate", json.dumps(ca))
    if identity:
        c.insert_json5(tls + "root_ca_certificate", json.dumps(os.path.join(identity, "ca.pem")))
        c.insert_json5(tls + "connect_certificate", json.dumps(os.path.join(identity, "cert.pem")))
        c.insert_json5(tls + "connect_private_key", json.dumps(os.path.join(identity, "key.pem")))
        c.insert_json5(tls + "enable_mtls", "true")
    return c


def open_session(conf):
    try:
        return zenoh.open(conf), None
    except Exception as e:  # zenoh.ZError: the link was refused
        return None, str(e)


def ask(session, key, payload=None):
    """The first answer to a query on `key` (its payload as JSON, or text), or None."""
    kwargs = {"timeout": TIMEOUT_S}
    if payload is not None:
        kwargs["payload"] = json.dumps(payload)
    for reply in session.get(key, **kwargs):
        if reply.ok is not None:
            text = reply.ok.payload.to_string()
            try:
                return json.loads(text)
            except ValueError:
                return text
        return {"error": reply.err.payload.to_string()}
    return None


def spawn_request(schema, flight, name, kind="reasoning", variant="planner", params=None):
    version, layout = schema
    return {
        "schema": {"version": version, "layout_hash": layout},
        "spec": {
            "flight": flight,
            "name": name,
            "kind": kind,
            "variant": variant,
            "params": params or {},
            "mission": {
                "instruction": "take off, then land",
                "subgoals": [
                    {"text": "take off", "action": "takeoff"},
                    {"text": "land", "action": "land"},
                ],
            },
        },
        "handle_pid": os.getpid(),
    }


def stranger(endpoint, host, conf):
    session, error = open_session(conf)
    out = {"opened": session is not None, "error": error, "info": False}
    if session is not None:
        out["info"] = ask(session, f"aeris/host/{host}/info") is not None
        session.close()
    return out


def main():
    p = argparse.ArgumentParser()
    p.add_argument("report")
    p.add_argument("--endpoint", required=True)
    p.add_argument("--plain", required=True)
    p.add_argument("--host", required=True)
    p.add_argument("--flight", required=True)
    p.add_argument("--schema", required=True)
    p.add_argument("--ca", required=True)
    p.add_argument("--flight-host", required=True)
    p.add_argument("--this-host", required=True)
    p.add_argument("--intruder", required=True)
    p.add_argument("--foreign", required=True)
    p.add_argument("--escape", required=True)
    a = p.parse_args()
    version, layout = a.schema.split(":")
    schema = (int(version), int(layout))
    host, flight = a.host, a.flight
    report = {}

    report["no_certificate"] = stranger(a.endpoint, host, config(a.endpoint, ca=a.ca))
    report["foreign_ca"] = stranger(
        a.endpoint, host, config(a.endpoint, identity=a.foreign)
    )
    report["plain_tcp"] = stranger(a.plain, host, config(a.plain))

    # the agent's own host subscribes to the flight's data, as its bridge does
    listener, error = open_session(config(a.endpoint, identity=a.this_host))
    if listener is None:
        sys.exit(f"the agent's own host could not connect: {error}")
    received = []
    sub = listener.declare_subscriber(
        f"aeris/data/{flight}/**", lambda s: received.append(s.payload.to_string())
    )

    intruder, error = open_session(config(a.endpoint, identity=a.intruder))
    report["intruder"] = {"opened": intruder is not None, "error": error}
    flight_host, error = open_session(config(a.endpoint, identity=a.flight_host))
    if flight_host is None:
        sys.exit(f"the flight's host could not connect: {error}")
    if intruder is not None:
        report["intruder"]["info"] = ask(intruder, f"aeris/host/{host}/info") is not None
        report["intruder"]["spawn"] = (
            ask(intruder, f"aeris/host/{host}/spawn", spawn_request(schema, flight, "reasoning"))
            is not None
        )

    fh = {"info": ask(flight_host, f"aeris/host/{host}/info")}
    escape = os.path.relpath(a.escape, "/")
    cases = {
        "traversal": spawn_request(schema, flight, "../" * 12 + escape),
        "traversal_flight": spawn_request(schema, "../../" + escape, "reasoning"),
        "kind": spawn_request(
            schema,
            flight,
            "camera",
            kind="camera",
            variant="gstreamer",
            params={"pipeline": f"videotestsrc ! filesink location={a.escape}"},
        ),
        "param": spawn_request(
            schema, flight, "reasoning", variant="smollm2", params={"model": a.escape}
        ),
        "bridge_connect": spawn_request(
            schema,
            flight,
            "bridge-on-x",
            kind="bridge",
            variant="zenoh",
            params={"connect": "tcp/192.0.2.1:7447"},
        ),
    }
    fh["spawns"] = {
        case: ask(flight_host, f"aeris/host/{host}/spawn", req) for case, req in cases.items()
    }

    # interleaved: the intruder's messages, then the flight host's, on the flight's data
    sent = 20
    key = f"aeris/data/{flight}/reasoning/decision"
    for i in range(sent):
        if intruder is not None:
            intruder.put(key, f"intruder {i}")
        flight_host.put(key, f"flight-host {i}")
        time.sleep(0.02)
    deadline = time.monotonic() + 10.0
    while time.monotonic() < deadline:
        if sum(1 for m in received if m.startswith("flight-host")) >= sent:
            break
        time.sleep(0.02)
    report["sent"] = sent
    fh["delivered"] = sum(1 for m in received if m.startswith("flight-host"))
    report["flight_host"] = fh
    report["intruder"]["delivered"] = sum(1 for m in received if m.startswith("intruder"))

    sub.undeclare()
    for s in (listener, intruder, flight_host):
        if s is not None:
            s.close()
    with open(a.report, "w") as f:
        json.dump(report, f, indent=1)


if __name__ == "__main__":
    main()
