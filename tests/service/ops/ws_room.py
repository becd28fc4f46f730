#!/usr/bin/env python3
"""Test helper: which room the WebSocket door says it holds (docs/WEBSOCKET.md,
unsigned mode; wss:// without checking the certificate, a test's
self-signed one). Connects, prints "hello ROOM" from the hello, joins as
CLIENT_ID, prints "status ROOM" from the first status, leaves. Exits 1 on a
refused join, 2 on a hello or status without a room.
   ws_room.py URL CLIENT_ID"""
import asyncio
import json
import random
import ssl
import sys
import time

import websockets

url, client_id = sys.argv[1], sys.argv[2]


async def main():
    tls = None
    if url.startswith("wss://"):
        tls = ssl.SSLContext(ssl.PROTOCOL_TLS_CLIENT)
        tls.check_hostname = False
        tls.verify_mode = ssl.CERT_NONE
    async with websockets.connect(url, subprotocols=["sweptccd.v1"], ssl=tls) as ws:
        hello = json.loads(await asyncio.wait_for(ws.recv(), 10))
        if hello.get("type") != "hello" or not isinstance(hello.get("room"), str):
            print("hello without a room: %s" % hello, file=sys.stderr)
            sys.exit(2)
        print("hello", hello["room"], flush=True)
        await ws.send(json.dumps({
            "type": "join_request", "utime": int(time.time() * 1e6), "client_id": client_id,
            "nonce": random.randrange(1, 2**50), "motion": 0, "eps_s": 0, "delta_m": 0,
            "link_name": ["pelvis"], "parent": [-1], "a": [[0, 0, 0]], "b": [[0, 0, 0.3]],
            "radius": [0.1], "proof": ""}))
        session = None
        while True:
            m = json.loads(await asyncio.wait_for(ws.recv(), 10))
            if m.get("type") == "join_reply":
                if m["reason"] != 0:
                    print("join refused: %s" % m, file=sys.stderr)
                    sys.exit(1)
                session = m["session"]
            elif m.get("type") == "status" and session is not None:
                if not isinstance(m.get("room"), str):
                    print("status without a room: %s" % m, file=sys.stderr)
                    sys.exit(2)
                print("status", m["room"], flush=True)
                break
        await ws.send(json.dumps({"type": "leave", "utime": int(time.time() * 1e6),
                                  "client_id": client_id, "session": session}))


asyncio.run(main())
