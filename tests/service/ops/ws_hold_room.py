#!/usr/bin/env python3
"""Test helper: one live client in a room through the WebSocket door
(docs/WEBSOCKET.md, unsigned mode), held for a while: joins as CLIENT_ID,
prints "joined WALL_SECONDS", keeps the connection (pings) for SECONDS,
prints "leaving WALL_SECONDS", sends leave, prints "left WALL_SECONDS" once
the server closed. Exits 1 on a
refused join or a protocol error.
   ws_hold_room.py URL CLIENT_ID SECONDS"""
import asyncio
import json
import random
import sys
import time

import websockets

url, client_id, hold = sys.argv[1], sys.argv[2], float(sys.argv[3])


async def main():
    async with websockets.connect(url, subprotocols=["sweptccd.v1"]) as ws:
        await ws.send(json.dumps({
            "type": "join_request", "utime": int(time.time() * 1e6), "client_id": client_id,
            "nonce": random.randrange(1, 2**50), "motion": 0, "eps_s": 0, "delta_m": 0,
            "link_name": ["pelvis"], "parent": [-1], "a": [[0, 0, 0]], "b": [[0, 0, 0.3]],
            "radius": [0.1], "proof": ""}))
        while True:
            m = json.loads(await asyncio.wait_for(ws.recv(), 10))
            if m.get("type") == "join_reply":
                break
        if m["reason"] != 0:
            print("join refused: %s" % m, file=sys.stderr)
            sys.exit(1)
        print("joined %.4f" % time.time(), flush=True)
        end = time.monotonic() + hold
        while time.monotonic() < end:
            await ws.send(json.dumps({"type": "ping"}))
            try:
                await asyncio.wait_for(ws.recv(), min(0.5, max(0.01, end - time.monotonic())))
            except asyncio.TimeoutError:
                pass
        print("leaving %.4f" % time.time(), flush=True)
        await ws.send(json.dumps({"type": "leave", "utime": int(time.time() * 1e6),
                                  "client_id": client_id, "session": m["session"]}))
        try:
            while True:
                await asyncio.wait_for(ws.recv(), 5)
        except websockets.ConnectionClosed:
            pass
        print("left %.4f" % time.time(), flush=True)


asyncio.run(main())
