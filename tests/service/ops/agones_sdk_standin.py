#!/usr/bin/env python3
"""A stand-in for the Agones SDK sidecar's REST API (the grpc-gateway of
sdk.proto: agones.dev/site/docs/guides/client-sdks/rest/), for tests: it
answers what the sidecar answers and appends every call, one JSON line each
({"t": seconds since start, "wall": Unix seconds, "method", "path",
"body"}), to LOG.

  agones_sdk_standin.py HOST PORT LOG [GAMESERVER_JSON NAME ADDRESS DOOR_PORT LABELS]

With the optional arguments it also keeps the GameServer that the SDK
calls change in GAMESERVER_JSON ({"name", "address", "ports": [{"name":
"websocket", "port"}], "state", "labels", "last_health_wall"}; LABELS is
k=v,k=v), rewritten atomically on every call, as Agones' API server would
hold it: the allocator stand-in (tests/service/fleet/) reads it, and
writes the labels of an allocation to GAMESERVER_JSON.allocated, which this
stand-in follows (its watchers hear them, as through Kubernetes' API).

POST /ready /health /shutdown /allocate take a JSON object (Content-Type
application/json) and answer {}; /reserve takes {"seconds": N}; GET
/gameserver answers a GameServer; GET /watch/gameserver streams (chunked,
as the sidecar's grpc-gateway) one line {"result": GameServer} each time
the GameServer changes (state, labels); PUT /metadata/label and
/metadata/annotation take {"key", "value"}. Anything else: 404; a body that
is not JSON or a wrong content type: 400 (then the test sees the call too,
with "bad": true).

Test controls, not Agones': POST /standin/labels {"k": "v", ...} sets those
labels as the allocator (through Kubernetes' API) would, and the watchers
hear it; POST /standin/raw {"bytes": N} streams one line of N bytes of junk
to every watcher (a hostile or broken sidecar).
"""
import json
import os
import queue
import sys
import threading
import time
from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer

HOST, PORT, LOG = sys.argv[1], int(sys.argv[2]), sys.argv[3]
GS_FILE = sys.argv[4] if len(sys.argv) > 8 else None
GS = {}
if GS_FILE:
    GS = {"name": sys.argv[5], "address": sys.argv[6],
          "ports": [{"name": "websocket", "port": int(sys.argv[7])}],
          "labels": dict(kv.split("=", 1) for kv in sys.argv[8].split(",") if kv),
          "last_health_wall": 0}
START = time.monotonic()
LOCK = threading.Lock()
STATE = {"state": "Scheduled", "labels": {}, "annotations": {}}

WATCHERS = []  # One queue of encoded lines per open GET /watch/gameserver.

POSTS = {"/ready": "Ready", "/health": None, "/shutdown": "Shutdown", "/allocate": "Allocated",
         "/reserve": "Reserved"}


def record(entry):
    entry["t"] = round(time.monotonic() - START, 4)
    entry["wall"] = time.time()
    with LOCK, open(LOG, "a") as f:
        f.write(json.dumps(entry) + "\n")


def publish():
    """The GameServer object as the API server would hold it (GS_FILE)."""
    if not GS_FILE:
        return
    GS["state"] = STATE["state"]
    tmp = GS_FILE + ".tmp"
    with open(tmp, "w") as f:
        json.dump(GS, f)
    os.replace(tmp, GS_FILE)


def notify(line=None):
    """Every watcher gets `line`, by default the GameServer now (hold LOCK)."""
    data = (line if line is not None else json.dumps({"result": gameserver()}) + "\n").encode()
    for q in WATCHERS:
        q.put(data)


def gameserver():
    return {"object_meta": {"name": "sweptccd-test", "namespace": "default",
                            "labels": STATE["labels"], "annotations": STATE["annotations"]},
            "status": {"state": STATE["state"], "address": "127.0.0.1",
                       "ports": [{"name": "websocket", "port": 7000}]}}


def follow_allocation():
    """The allocator (stand-in) labels the GameServer at allocation: its
    labels appear in GS_FILE.allocated and reach the watchers, as
    Kubernetes' watch would deliver them."""
    seen = None
    while True:
        try:
            with open(GS_FILE + ".allocated") as f:
                labels = json.load(f)
        except (OSError, ValueError):
            labels = None
        if isinstance(labels, dict) and labels != seen:
            seen = labels
            with LOCK:
                STATE["labels"].update({str(k): str(v) for k, v in labels.items()})
                notify()
        time.sleep(0.02)


class Handler(BaseHTTPRequestHandler):
    protocol_version = "HTTP/1.1"

    def log_message(self, *args):
        pass

    def answer(self, code, obj):
        data = json.dumps(obj).encode()
        self.send_response(code)
        self.send_header("Content-Type", "application/json")
        self.send_header("Content-Length", str(len(data)))
        self.end_headers()
        self.wfile.write(data)

    def body(self):
        n = int(self.headers.get("Content-Length", "0"))
        if n > 65536:
            return None, "too long"
        raw = self.rfile.read(n)
        if self.headers.get("Content-Type", "").split(";")[0].strip() != "application/json":
            return None, "content type"
        try:
            obj = json.loads(raw)
        except ValueError:
            return None, "not JSON"
        return (obj, None) if isinstance(obj, dict) else (None, "not an object")

    def do_POST(self):
        obj, bad = self.body()
        record({"method": "POST", "path": self.path, "body": obj, "bad": bad is not None})
        if bad:
            return self.answer(400, {"error": bad})
        if self.path == "/standin/labels":
            with LOCK:
                STATE["labels"].update({str(k): str(v) for k, v in obj.items()})
                notify()
            return self.answer(200, {})
        if self.path == "/standin/raw":
            with LOCK:
                notify("x" * int(obj.get("bytes", 0)) + "\n")
            return self.answer(200, {})
        if self.path not in POSTS:
            return self.answer(404, {"error": "not found"})
        with LOCK:
            if POSTS[self.path] and POSTS[self.path] != STATE["state"]:
                STATE["state"] = POSTS[self.path]
                notify()
            if self.path in ("/health", "/ready"):
                GS["last_health_wall"] = time.time()
            publish()
        self.answer(200, {})

    def do_PUT(self):
        obj, bad = self.body()
        record({"method": "PUT", "path": self.path, "body": obj, "bad": bad is not None})
        if bad or not {"key", "value"} <= set(obj or {}):
            return self.answer(400, {"error": bad or "key and value"})
        kind = {"/metadata/label": "labels", "/metadata/annotation": "annotations"}.get(self.path)
        if not kind:
            return self.answer(404, {"error": "not found"})
        with LOCK:
            STATE[kind]["agones.dev/sdk-" + obj["key"]] = obj["value"]
            notify()
        self.answer(200, {})

    def do_GET(self):
        record({"method": "GET", "path": self.path, "body": None, "bad": False})
        if self.path == "/gameserver":
            return self.answer(200, gameserver())
        if self.path == "/watch/gameserver":
            return self.watch()
        self.answer(404, {"error": "not found"})

    def watch(self):
        q = queue.Queue()
        with LOCK:
            WATCHERS.append(q)
        try:
            self.send_response(200)
            self.send_header("Content-Type", "application/json")
            self.send_header("Transfer-Encoding", "chunked")
            self.end_headers()
            self.wfile.flush()
            while True:
                data = q.get()
                self.wfile.write(b"%x\r\n%s\r\n" % (len(data), data))
                self.wfile.flush()
        except OSError:
            pass
        finally:
            with LOCK:
                WATCHERS.remove(q)
            self.close_connection = True


if GS_FILE:
    threading.Thread(target=follow_allocation, daemon=True).start()
ThreadingHTTPServer((HOST, PORT), Handler).serve_forever()
