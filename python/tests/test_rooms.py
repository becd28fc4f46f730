"""Room discovery (python/sweptccd/rooms.py, docs/DEPLOY.md): the static
map, door URLs, and the Agones allocator resolver against a loopback
stand-in that records its request (the same shape as the C++ and JavaScript
clients' tests)."""

from __future__ import annotations

import json
import threading
from http.server import BaseHTTPRequestHandler, HTTPServer
from typing import Any, Dict, List

import pytest

from sweptccd.rooms import (AgonesAllocatorResolver, RoomError, StaticRoomMap,
                            hello_room_problem, parse_door_url, with_room)


def test_static_map() -> None:
    m = StaticRoomMap.from_text(
        '{"rooms": {"arcade-1": "wss://10.0.0.5:8765", "lab": "ws://[::1]:8765/ws"}}')
    assert len(m) == 2
    assert m.resolve("arcade-1").url == "wss://10.0.0.5:8765/ws"
    assert m.resolve("lab").url == "ws://[::1]:8765/ws"
    with pytest.raises(RoomError) as e:
        m.resolve("nowhere")
    assert not e.value.retryable
    with pytest.raises(RoomError):
        m.resolve("bad room")
    for bad in ["[]", "{}", '{"rooms": []}', '{"rooms": {"a b": "ws://h:1"}}',
                '{"rooms": {"a": 5}}', '{"rooms": {"a": "ws://h"}}', '{"rooms": {"a": "ws://h:0"}}',
                '{"rooms": {"a": "ws://u@h:1"}}', "{"]:
        with pytest.raises(RoomError):
            StaticRoomMap.from_text(bad)
    with pytest.raises(RoomError):
        StaticRoomMap.from_file("/nonexistent/rooms.json")
    assert parse_door_url("ws://room-3.example:1").host == "room-3.example"


class _Allocator(BaseHTTPRequestHandler):
    calls: List[Dict[str, Any]] = []
    answer = (200, b"")

    def log_message(self, *args: Any) -> None:
        pass

    def do_POST(self) -> None:
        n = int(self.headers.get("Content-Length", "0"))
        _Allocator.calls.append({"path": self.path, "body": json.loads(self.rfile.read(n))})
        code, body = _Allocator.answer
        self.send_response(code)
        self.send_header("Content-Length", str(len(body)))
        self.end_headers()
        self.wfile.write(body)


def test_allocator_get_or_allocate() -> None:
    server = HTTPServer(("127.0.0.1", 0), _Allocator)
    threading.Thread(target=server.serve_forever, daemon=True).start()
    try:
        r = AgonesAllocatorResolver("http://127.0.0.1:%d" % server.server_port,
                                    {"sweptccd.dev/scene": "dragon"})
        _Allocator.answer = (200, json.dumps({
            "gameServerName": "dragon-x7k2p", "address": "10.0.3.2",
            "ports": [{"name": "metrics", "port": 9464},
                      {"name": "websocket", "port": 7011}]}).encode())
        d = r.resolve("arcade-7")
        assert d.url == "wss://10.0.3.2:7011/ws" and d.source == "agones:dragon-x7k2p"
        assert _Allocator.calls[-1] == {"path": "/gameserverallocation", "body": {
            "namespace": "default",
            "gameServerSelectors": [
                {"matchLabels": {"sweptccd.dev/room": "arcade-7"}, "gameServerState": "ALLOCATED"},
                {"matchLabels": {"sweptccd.dev/scene": "dragon"}, "gameServerState": "READY"}],
            "metadata": {"labels": {"sweptccd.dev/room": "arcade-7"}}}}
        _Allocator.answer = (429, b"{}")
        with pytest.raises(RoomError) as e:
            r.resolve("arcade-7")
        assert e.value.retryable and "429" in str(e.value)
        for body in [b"", b"[]", b'{"address": "10.0.3.2"}',
                     b'{"address": "a/b", "ports": [{"name": "websocket", "port": 1}]}',
                     b'{"address": "10.0.3.2", "ports": [{"name": "websocket", "port": 70000}]}',
                     b'{"address": "10.0.3.2", "ports": [{"name": "websocket", "port": true}]}']:
            _Allocator.answer = (200, body)
            with pytest.raises(RoomError):
                r.resolve("arcade-7")
        with pytest.raises(RoomError):
            r.resolve("../x")
    finally:
        server.shutdown()
    with pytest.raises(RoomError):
        AgonesAllocatorResolver("https://a", {})
    with pytest.raises(RoomError) as e:
        AgonesAllocatorResolver("http://127.0.0.1:1", {"a": "b"}, timeout_s=1).resolve("x")
    assert e.value.retryable


def test_failover_between_two_stand_in_servers() -> None:
    """The room's server goes silent (no status): the client takes it for
    dead, resolves the room again (another server, a newer instance),
    re-joins, re-sends the unanswered poses with their seq, fences a late
    event of the old instance and drops a repeated answer: each pair reaches
    the application once."""
    import asyncio

    import websockets.server

    from sweptccd.client import LiveClient
    from sweptccd.rooms import DoorAddress

    skeleton = {"links": [{"name": "pelvis", "parent": None, "a": [0, 0, 0], "b": [0, 0.2, 0],
                           "radius": 0.1}]}
    received: Dict[int, List[Dict[str, Any]]] = {7: [], 9: []}

    def server(instance: int, answer_upto: int) -> Any:
        async def handler(ws: Any) -> None:
            await ws.send(json.dumps({"type": "hello", "protocol": 1, "instance": instance,
                                      "security": "unsigned", "challenge": "b" * 64,
                                      "server_utime": 1, "room": "arcade-7", "limits": {}}))
            first = True  # A session's first pose anchors it: no pair.
            async for text in ws:
                msg = json.loads(text)
                received[instance].append(msg)
                anchor = msg["type"] == "tracker_pose" and first
                first = first and not anchor
                if msg["type"] == "join_request":
                    await ws.send(json.dumps({
                        "type": "join_reply", "utime": 1, "client_id": msg["client_id"],
                        "nonce": msg["nonce"], "reason": 0, "reason_name": "accepted",
                        "message": "", "session": instance * 10, "instance": instance,
                        "silence_timeout_ms": 5000}))
                    await ws.send(json.dumps({"type": "status", "utime": 1,
                                              "instance": instance, "client_id": []}))
                    if instance == 9:  # A late event of the dead run; a repeat of pair 2.
                        for inst, seq1 in ((7, 4), (9, 2)):
                            await ws.send(json.dumps({
                                "type": "contact_event", "client_id": "alice", "seq0": seq1 - 1,
                                "seq1": seq1, "result": 0, "contacts": [], "instance": inst}))
                if msg["type"] == "tracker_pose" and not anchor and msg["seq"] <= answer_upto:
                    await ws.send(json.dumps({
                        "type": "contact_event", "client_id": "alice", "seq0": msg["seq"] - 1,
                        "seq1": msg["seq"], "result": 0, "contacts": [], "instance": instance}))
        return handler

    class Resolver:
        port = 0

        def resolve(self, room: str) -> DoorAddress:
            return DoorAddress("127.0.0.1", self.port, False)

    async def run() -> None:
        old = await websockets.server.serve(server(7, 2), "127.0.0.1", 0,
                                            subprotocols=["sweptccd.v1"])  # type: ignore[list-item]
        new = await websockets.server.serve(server(9, 10**6), "127.0.0.1", 0,
                                            subprotocols=["sweptccd.v1"])  # type: ignore[list-item]
        resolver = Resolver()
        resolver.port = list(old.sockets)[0].getsockname()[1]
        client = LiveClient(None, "alice", skeleton, resolver=resolver, room="arcade-7",
                            heartbeat_timeout=0.3, max_backoff=0.1)
        seen: List[int] = []
        client.on("contact", lambda e: seen.append(e["seq1"]))
        await client.join()
        for k in range(5):
            assert await client.publish([[0, 1, 0]], [[1, 0, 0, 0]], utime=1000 + k)
        for _ in range(200):
            if len(seen) == 2:
                break
            await asyncio.sleep(0.01)
        resolver.port = list(new.sockets)[0].getsockname()[1]
        for _ in range(300):
            if client.joined and client.session == 90:
                break
            await asyncio.sleep(0.01)
        assert client.session == 90 and client.heartbeat_losses == 1
        for k in range(5, 8):
            assert await client.publish([[0, 1, 0]], [[1, 0, 0, 0]], utime=1000 + k)
        for _ in range(300):
            if len(seen) == 7:
                break
            await asyncio.sleep(0.01)
        await asyncio.sleep(0.1)
        assert seen == [1, 2, 3, 4, 5, 6, 7], seen
        assert client.fenced_events == 1 and client.repeated_answers == 1
        resent = [(m["seq"], m["session"], m["utime"]) for m in received[9]
                  if m["type"] == "tracker_pose"]
        assert resent[:3] == [(2, 90, 1002), (3, 90, 1003), (4, 90, 1004)], resent
        await client.leave()
        old.close()
        new.close()

    asyncio.run(run())


def test_room_named_and_hello_checked() -> None:
    """The room a client is for (docs/WEBSOCKET.md sections 1 and 5): sent as
    ?room=, a hello of another room refused with one clear error before any
    join (the 409 of a real door: client_e2e.py)."""
    import asyncio

    import websockets.server

    from sweptccd.client import LiveClient, ProtocolError

    assert with_room("ws://h:1/ws", "") == "ws://h:1/ws"
    assert with_room("ws://h:1/ws", "arcade-7") == "ws://h:1/ws?room=arcade-7"
    with pytest.raises(RoomError):
        with_room("ws://h:1/ws", "a&b=c")
    assert hello_room_problem("", {"room": "x"}, "d") == ""
    assert hello_room_problem("arcade-7", {"room": "arcade-7"}, "d") == ""
    assert "holds room 'arcade-8', not room 'arcade-7': refused" in hello_room_problem(
        "arcade-7", {"room": "arcade-8"}, "ws://d")
    assert "does not say which room" in hello_room_problem("arcade-7", {}, "d")
    hostile = hello_room_problem("arcade-7", {"room": "x\n\x1b[31m"}, "d")
    assert "\n" not in hostile and "\x1b" not in hostile
    skeleton = {"links": [{"name": "pelvis", "parent": None, "a": [0, 0, 0], "b": [0, 0.2, 0],
                           "radius": 0.1}]}
    with pytest.raises(RoomError):
        LiveClient("ws://h:1/ws", "alice", skeleton, room="bad room")
    paths: List[str] = []
    received: List[Dict[str, Any]] = []

    async def handler(ws: Any) -> None:
        paths.append(ws.path)
        await ws.send(json.dumps({"type": "hello", "protocol": 1, "instance": 3,
                                  "security": "unsigned", "challenge": "b" * 64,
                                  "server_utime": 1, "room": "arcade-8", "limits": {}}))
        async for text in ws:
            received.append(json.loads(text))

    async def run() -> None:
        server = await websockets.server.serve(handler, "127.0.0.1", 0,
                                               subprotocols=["sweptccd.v1"])  # type: ignore[list-item]
        port = list(server.sockets)[0].getsockname()[1]
        client = LiveClient(f"ws://127.0.0.1:{port}/ws", "alice", skeleton, room="arcade-7",
                            reconnect=False)
        client.on("contact", lambda e: pytest.fail("an event of another room"))
        with pytest.raises(ProtocolError, match="holds room 'arcade-8', not room 'arcade-7'"):
            await client.join()
        assert client.wrong_rooms == 1
        await asyncio.sleep(0.05)
        assert paths == ["/ws?room=arcade-7"] and received == []  # No join sent.
        server.close()

    asyncio.run(run())
