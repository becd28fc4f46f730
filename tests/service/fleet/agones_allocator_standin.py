#!/usr/bin/env python3
"""A stand-in for the Agones allocator service's REST gateway (POST
/gameserverallocation, agones allocation.proto: AllocationRequest ->
AllocationResponse), for tests: it allocates among the GameServers that the
SDK sidecar stand-ins (tests/service/ops/agones_sdk_standin.py, one per
"pod") describe in DIR/*.json, as Agones' controller would from the
GameServer objects, and appends every call, one JSON line each ({"t",
"wall", "method", "path", "body", "code", "answer"}), to LOG.

  agones_allocator_standin.py HOST PORT DIR LOG [--unhealthy-after S] [--stale NAME COUNT]

- A GameServer is Ready or Allocated per its SDK calls; one whose last
  Health (or Ready) is older than --unhealthy-after seconds (default 1) is
  Unhealthy (Agones: failureThreshold x periodSeconds) and never allocated.
- gameServerSelectors are tried in order: matchLabels (every label equal)
  and gameServerState ("READY", the default, or "ALLOCATED"); the first
  GameServer found is answered; a Ready one becomes Allocated and gets
  metadata.labels. None: HTTP 429 (grpc ResourceExhausted), as the allocator.
- A body that is not an AllocationRequest: 400 with a one-line error.
- Fault injection (--stale NAME COUNT): once a GameServer carrying the
  labels a request's metadata asks for (the room's) is Unhealthy, the next
  COUNT such requests are answered with GameServer NAME whatever they ask (an allocator answering from a stale cache), so a test
  can check that clients fence a server of an older instance.
"""
import argparse
import glob
import json
import os
import threading
import time
from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer

ap = argparse.ArgumentParser()
ap.add_argument("host")
ap.add_argument("port", type=int)
ap.add_argument("dir")
ap.add_argument("log")
ap.add_argument("--unhealthy-after", type=float, default=1.0)
ap.add_argument("--stale", nargs=2, metavar=("NAME", "COUNT"))
args = ap.parse_args()

START = time.monotonic()
LOCK = threading.Lock()
ALLOCATED = {}  # name -> labels added at allocation (the allocator's own state)
STALE = {"name": args.stale[0], "left": int(args.stale[1])} if args.stale else None


def record(entry):
    entry["t"] = round(time.monotonic() - START, 4)
    entry["wall"] = time.time()
    with open(args.log, "a") as f:
        f.write(json.dumps(entry) + "\n")


def gameservers():
    out = []
    for path in sorted(glob.glob(os.path.join(args.dir, "*.json"))):
        try:
            with open(path) as f:
                gs = json.load(f)
        except (OSError, ValueError):
            continue
        alive = time.time() - gs.get("last_health_wall", 0) <= args.unhealthy_after
        state = gs.get("state")
        if state in ("Ready", "Allocated") and not alive:
            state = "Unhealthy"
        if gs["name"] in ALLOCATED and state == "Ready":
            state = "Allocated"
        labels = dict(gs.get("labels", {}))
        labels.update(ALLOCATED.get(gs["name"], {}))
        out.append({**gs, "state": state, "labels": labels, "file": path})
    return out


def check_request(body):
    if not isinstance(body, dict):
        return "body is not a JSON object"
    if not isinstance(body.get("namespace", ""), str):
        return "namespace is not a string"
    sels = body.get("gameServerSelectors")
    if not isinstance(sels, list) or not sels or len(sels) > 16:
        return "gameServerSelectors: 1 to 16 selectors"
    for s in sels:
        if not isinstance(s, dict) or not set(s) <= {"matchLabels", "gameServerState", "players",
                                                      "counters", "lists", "matchExpressions"}:
            return "gameServerSelectors[]: unknown field"
        ml = s.get("matchLabels", {})
        if not isinstance(ml, dict) or not all(isinstance(k, str) and isinstance(v, str)
                                               for k, v in ml.items()):
            return "matchLabels: strings only"
        if s.get("gameServerState", "READY") not in ("READY", "ALLOCATED"):
            return "gameServerState: READY or ALLOCATED"
    meta = body.get("metadata", {})
    if not isinstance(meta, dict) or not isinstance(meta.get("labels", {}), dict):
        return "metadata.labels: an object"
    return None


def answer_for(gs):
    return {"gameServerName": gs["name"], "address": gs["address"], "nodeName": gs["name"] + "-node",
            "ports": gs["ports"], "source": "local",
            "metadata": {"labels": gs["labels"], "annotations": {}}}


def allocate(body):
    servers = gameservers()
    by_name = {g["name"]: g for g in servers}
    wanted = body.get("metadata", {}).get("labels", {})
    room_dead = bool(wanted) and any(
        gs["state"] == "Unhealthy" and all(gs["labels"].get(k) == v for k, v in wanted.items())
        for gs in servers)
    if STALE and room_dead and STALE["left"] > 0 and STALE["name"] in by_name:
        STALE["left"] -= 1
        return 200, answer_for(by_name[STALE["name"]])
    for sel in body["gameServerSelectors"]:
        want = {"READY": "Ready", "ALLOCATED": "Allocated"}[sel.get("gameServerState", "READY")]
        for gs in servers:
            if gs["state"] != want:
                continue
            if any(gs["labels"].get(k) != v for k, v in sel.get("matchLabels", {}).items()):
                continue
            if want == "Ready":
                ALLOCATED[gs["name"]] = dict(body.get("metadata", {}).get("labels", {}))
                gs["labels"].update(ALLOCATED[gs["name"]])
                # The labels reach the GameServer object, so its sidecar's
                # watch reports them (agones_sdk_standin.py reads FILE.allocated).
                tmp = gs["file"] + ".allocated.tmp"
                with open(tmp, "w") as f:
                    json.dump(ALLOCATED[gs["name"]], f)
                os.replace(tmp, gs["file"] + ".allocated")
            return 200, answer_for(gs)
    return 429, {"error": "there is no available GameServer to allocate", "code": 8}


class Handler(BaseHTTPRequestHandler):
    protocol_version = "HTTP/1.1"

    def log_message(self, *a):
        pass

    def reply(self, code, obj):
        data = json.dumps(obj).encode()
        self.send_response(code)
        self.send_header("Content-Type", "application/json")
        self.send_header("Content-Length", str(len(data)))
        self.end_headers()
        self.wfile.write(data)

    def do_POST(self):
        n = int(self.headers.get("Content-Length", "0"))
        raw = self.rfile.read(min(n, 65536))
        try:
            body = json.loads(raw)
        except ValueError:
            body = None
        with LOCK:
            bad = check_request(body)
            if self.path != "/gameserverallocation":
                code, obj = 404, {"error": "not found"}
            elif n > 65536 or bad:
                code, obj = 400, {"error": bad or "too long"}
            else:
                code, obj = allocate(body)
            record({"method": "POST", "path": self.path, "body": body, "code": code,
                    "answer": obj})
        self.reply(code, obj)

    def do_GET(self):
        with LOCK:
            record({"method": "GET", "path": self.path, "body": None, "code": 404, "answer": None})
        self.reply(404, {"error": "not found"})


ThreadingHTTPServer((args.host, args.port), Handler).serve_forever()
