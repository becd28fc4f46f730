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
                            parse_door_url)


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
