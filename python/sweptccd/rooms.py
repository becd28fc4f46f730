"""Room discovery (docs/DEPLOY.md, "Finding a room"), the same shape as the
C++ client's room_resolver.h and the JavaScript client's rooms.ts: a room
name resolved to its WebSocket door through a static map (one host) or the
Agones allocator's REST API (get-or-allocate by the sweptccd.dev/room
label). Everything read is checked before use; failures are RoomError with
one line::

    resolver = AgonesAllocatorResolver("https://allocator:443",
                                       {"sweptccd.dev/scene": "dragon"},
                                       ca_file="ca.pem", cert_file="c.pem", key_file="c.key")
    door = resolver.resolve("arcade-7")           # DoorAddress
    client = LiveClient(door.url, "alice", "skeleton.json", key="room.key")
"""

from __future__ import annotations

import json
import re
import ssl
import urllib.error
import urllib.request
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Dict, Mapping, Optional, Union

__all__ = ["DoorAddress", "RoomError", "StaticRoomMap", "AgonesAllocatorResolver",
           "with_room", "hello_room_problem",
           "parse_door_url"]

ROOM_NAME = re.compile(r"^[A-Za-z0-9_.-]{1,64}$")
HOST_NAME = re.compile(r"^[A-Za-z0-9.-]{1,253}$")
IPV6 = re.compile(r"^[0-9A-Fa-f:.]{2,45}$")
DOOR_URL = re.compile(r"^(wss?)://(.*?)(/ws)?$", re.S)
MAX_MAP_BYTES = 1 << 20
MAX_ROOMS = 4096
MAX_RESPONSE_BYTES = 64 << 10


def _show(text: Any) -> str:
    s = str(text)
    out = "".join(c if 0x20 <= ord(c) < 0x7f else "\\x%02x" % (ord(c) & 0xff) for c in s[:80])
    return "'" + out + ("..." if len(s) > 80 else "") + "'"


class RoomError(Exception):
    """A resolution that failed (one line). `retryable`: the room may exist
    in a moment (no Ready server yet, the allocator unreachable)."""

    def __init__(self, message: str, retryable: bool) -> None:
        super().__init__(message)
        self.retryable = retryable


@dataclass(frozen=True)
class DoorAddress:
    host: str
    port: int
    tls: bool
    source: str = "static"  # or "agones:GAMESERVER"

    @property
    def url(self) -> str:
        host = "[" + self.host + "]" if ":" in self.host else self.host
        return ("wss" if self.tls else "ws") + "://" + host + ":" + str(self.port) + "/ws"


def with_room(url: str, room: str) -> str:
    """`url` naming the room its client is for (docs/WEBSOCKET.md section 1):
    ``?room=ROOM`` added, so a door of another room refuses the upgrade with
    409 before any frame. room "" (no room): `url` as it is. RoomError for a
    room breaking the id rule."""
    if room == "":
        return url
    _check_room(room)
    return url + ("&" if "?" in url else "?") + "room=" + room


def hello_room_problem(room: str, hello: Mapping[str, Any], door: str) -> str:
    """The one check of a hello against the room the client is for
    (docs/WEBSOCKET.md section 5, hello.room): "" when room is "" or the
    hello names it; else one line, safe to print: a door of another room (a
    room mix-up after a failover) whose events must never be delivered. A
    hello without a string room is refused too."""
    held = hello.get("room")
    if room == "" or held == room:
        return ""
    what = ("holds room " + _show(held) if isinstance(held, str)
            else "does not say which room it holds")
    return "door %s %s, not room %s: refused (a room mix-up; resolving again)" % (
        _show(door), what, _show(room))


def _check_room(room: str) -> None:
    if not isinstance(room, str) or not ROOM_NAME.match(room):
        raise RoomError("room name %s breaks the id rule (1-64 of A-Z a-z 0-9 _ . -)"
                        % _show(room), False)


def _is_host(host: str) -> bool:
    return bool(HOST_NAME.match(host)) or (bool(IPV6.match(host)) and ":" in host)


def parse_door_url(url: str) -> DoorAddress:
    """ws://HOST:PORT[/ws] or wss://...; HOST an IPv4 literal, [IPv6] or a DNS name."""
    m = DOOR_URL.match(url) if isinstance(url, str) else None
    if not m:
        raise RoomError("door address %s is not ws://HOST:PORT or wss://HOST:PORT" % _show(url),
                        False)
    rest = m.group(2)
    if rest.startswith("["):
        close = rest.find("]")
        if close < 0 or rest[close + 1:close + 2] != ":":
            raise RoomError("door address %s: expected [IPv6]:PORT" % _show(url), False)
        host, port = rest[1:close], rest[close + 2:]
        if not (IPV6.match(host) and ":" in host):
            raise RoomError("door address %s: bad IPv6" % _show(url), False)
    else:
        host, sep, port = rest.rpartition(":")
        if not sep:
            raise RoomError("door address %s has no :PORT" % _show(url), False)
        if not HOST_NAME.match(host):
            raise RoomError("door address %s: host is not a name or an address" % _show(url),
                            False)
    if not re.fullmatch(r"[0-9]{1,5}", port) or not 1 <= int(port) <= 65535:
        raise RoomError("door address %s: port is not 1-65535" % _show(url), False)
    return DoorAddress(host, int(port), m.group(1) == "wss")


class StaticRoomMap:
    """{"rooms": {"NAME": "wss://HOST:PORT", ...}}, at most 1 MiB and 4096 rooms."""

    def __init__(self, rooms: Mapping[str, DoorAddress]) -> None:
        self._rooms = dict(rooms)

    @classmethod
    def from_text(cls, text: str, what: str = "room map") -> "StaticRoomMap":
        if len(text) > MAX_MAP_BYTES:
            raise RoomError("%s: over %d bytes" % (what, MAX_MAP_BYTES), False)
        try:
            j = json.loads(text)
        except ValueError:
            j = None
        rooms = j.get("rooms") if isinstance(j, dict) else None
        if not isinstance(rooms, dict):
            raise RoomError('%s: not a JSON object with an object "rooms"' % what, False)
        if len(rooms) > MAX_ROOMS:
            raise RoomError("%s: more than %d rooms" % (what, MAX_ROOMS), False)
        out: Dict[str, DoorAddress] = {}
        for name, url in rooms.items():
            _check_room(name)
            if not isinstance(url, str):
                raise RoomError("%s: room %s is not a string" % (what, _show(name)), False)
            out[name] = parse_door_url(url)
        return cls(out)

    @classmethod
    def from_file(cls, path: Union[str, Path]) -> "StaticRoomMap":
        try:
            with open(path, "rb") as f:
                data = f.read(MAX_MAP_BYTES + 1)
        except OSError as e:
            raise RoomError("room map %s: cannot be read (%s)" % (_show(path), e.strerror),
                            False) from None
        return cls.from_text(data.decode("utf-8", "replace"), "room map " + _show(path))

    def __len__(self) -> int:
        return len(self._rooms)

    def resolve(self, room: str) -> DoorAddress:
        _check_room(room)
        if room not in self._rooms:
            raise RoomError("room %s is not in the room map" % _show(room), False)
        return self._rooms[room]


class AgonesAllocatorResolver:
    """The Agones allocator service's REST gateway (POST /gameserverallocation,
    allocation.proto), get-or-allocate by the room label; mTLS with
    cert_file/key_file (Agones' allocator asks for a client certificate)."""

    def __init__(self, url: str, fleet_labels: Mapping[str, str], *,
                 namespace: str = "default", room_label: str = "sweptccd.dev/room",
                 port_name: str = "websocket", door_tls: bool = True,
                 ca_file: Optional[str] = None, cert_file: Optional[str] = None,
                 key_file: Optional[str] = None, timeout_s: float = 2.0) -> None:
        if not re.match(r"^https?://", str(url)):
            raise RoomError("allocator URL %s is not https://HOST[:PORT]" % _show(url), False)
        if not fleet_labels:
            raise RoomError("allocator: no fleet label to allocate a new room from "
                            "(e.g. sweptccd.dev/scene=NAME)", False)
        self.url = url.rstrip("/")
        self.fleet_labels = dict(fleet_labels)
        self.namespace, self.room_label, self.port_name = namespace, room_label, port_name
        self.door_tls, self.timeout_s = door_tls, timeout_s
        self._context: Optional[ssl.SSLContext] = None
        if self.url.startswith("https://"):
            self._context = ssl.create_default_context(cafile=ca_file)
            if cert_file:
                self._context.load_cert_chain(cert_file, key_file)

    def request_body(self, room: str) -> Dict[str, Any]:
        room_labels = {self.room_label: room}
        return {"namespace": self.namespace,
                "gameServerSelectors": [
                    {"matchLabels": room_labels, "gameServerState": "ALLOCATED"},
                    {"matchLabels": self.fleet_labels, "gameServerState": "READY"}],
                "metadata": {"labels": room_labels}}

    def parse_response(self, body: bytes) -> DoorAddress:
        if len(body) > MAX_RESPONSE_BYTES:
            raise RoomError("allocator: answer too long", True)
        try:
            j = json.loads(body)
        except ValueError:
            j = None
        if not isinstance(j, dict):
            raise RoomError("allocator: answer is not JSON", True)
        host = j.get("address")
        if not isinstance(host, str) or not _is_host(host):
            raise RoomError("allocator: answer's address %s is not a host" % _show(host), True)
        ports = j.get("ports")
        if not isinstance(ports, list) or len(ports) > 64:
            raise RoomError("allocator: answer has no ports", True)
        port = 0
        for p in ports:
            if not isinstance(p, dict) or p.get("name") != self.port_name:
                continue
            value = p.get("port")
            if type(value) is not int or not 1 <= value <= 65535:
                raise RoomError("allocator: port %s is not 1-65535" % _show(self.port_name), True)
            port = value
        if not port:
            raise RoomError("allocator: answer has no port named %s" % _show(self.port_name),
                            True)
        name = j.get("gameServerName")
        return DoorAddress(host, port, self.door_tls,
                           "agones:" + (_show(name)[1:-1] if isinstance(name, str) else ""))

    def resolve(self, room: str) -> DoorAddress:
        _check_room(room)
        data = json.dumps(self.request_body(room)).encode()
        req = urllib.request.Request(self.url + "/gameserverallocation", data=data,
                                     headers={"Content-Type": "application/json"},
                                     method="POST")
        try:
            with urllib.request.urlopen(req, timeout=self.timeout_s,
                                        context=self._context) as r:
                body = r.read(MAX_RESPONSE_BYTES + 1)
        except urllib.error.HTTPError as e:
            text = e.read(200).decode("utf-8", "replace")
            if e.code == 429:
                raise RoomError("allocator: no room server Ready for %s (429); retry"
                                % _show(room), True) from None
            raise RoomError("allocator: HTTP %d for %s: %s" % (e.code, _show(room), _show(text)),
                            e.code >= 500) from None
        except (OSError, ValueError) as e:
            raise RoomError("allocator %s: %s" % (_show(self.url), _show(e)), True) from None
        return self.parse_response(body)
