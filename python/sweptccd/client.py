"""A live client of the daemon over its WebSocket door (docs/WEBSOCKET.md,
protocol v1), with the shape of the C++ and JavaScript clients: join with a
skeleton, publish poses, hear contact events, shared-world contacts,
rejections and status (callbacks or an async iterator), leave; when the
connection drops it reconnects with backoff and joins again (same client id
and nonce, a new greater session, seq restarting at 0).

Uses Debian's python3-websockets (asyncio). Messages are the protocol's JSON
objects as dicts (their fields are WEBSOCKET.md's, section 5)::

    async with LiveClient("ws://127.0.0.1:7701/ws", "alice", "walk.json",
                          key="room.key") as client:
        client.on("contact", lambda e: print(e["result_name"], e["t_lo"]))
        await client.publish(position, orientation)   # (links, 3), (links, 4)
        async for event in client.events():            # or callbacks only
            ...
"""

from __future__ import annotations

import asyncio
import hashlib
import hmac
import json
import os
import random
import re
import time
from pathlib import Path
from typing import (Any, AsyncIterator, Callable, Dict, List, Mapping, Optional, Sequence,
                    Union)

import websockets.client
import websockets.exceptions

__all__ = ["LiveClient", "JoinRefused", "ProtocolError", "proof", "parse_key", "skeleton_arrays"]

Message = Dict[str, Any]
Callback = Callable[[Message], Any]

SUBPROTOCOL = "sweptccd.v1"
PROOF_LABEL = {"join": "sweptccd-ws-v1 join", "subscribe": "sweptccd-ws-v1 subscribe",
               "object": "sweptccd-ws-v1 object"}
CLIENT_ID = re.compile(r"^[A-Za-z0-9_.-]{1,64}$")
REASON_ACCEPTED = 0
# Refusals worth trying again after a backoff (busy, too_many_clients,
# stale_request), as the JavaScript client.
RETRY_REASONS = {8, 3, 9}
EVENTS = ("joined", "refused", "contact_event", "shared_contact", "rejection", "status",
          "error", "disconnected")
_ALIASES = {"contact": "contact_event", "shared": "shared_contact"}


class ProtocolError(Exception):
    """A fatal error from the server (its `error` message), or a broken
    exchange."""


class JoinRefused(ProtocolError):
    """The daemon refused the join: `reply` is its join_reply."""

    def __init__(self, reply: Message) -> None:
        super().__init__(f"join refused: {reply.get('reason_name', reply.get('reason'))}: "
                         f"{_display(str(reply.get('message', '')))}")
        self.reply = reply


def _display(text: str) -> str:
    """A server string made safe to print on one line (controls escaped)."""
    return "".join(c if c.isprintable() else f"\\x{ord(c):02x}" for c in text)[:4096]


def parse_key(key: Union[str, bytes, "os.PathLike[str]"]) -> bytes:
    """A room key: 32 bytes, 64 hex digits, or a key file (`sweptccd keygen`)."""
    if isinstance(key, bytes):
        if len(key) != 32:
            raise ValueError(f"a key has 32 bytes, not {len(key)}")
        return key
    text = os.fspath(key)
    if not re.fullmatch(r"\s*[0-9a-fA-F]{64}\s*", text):
        text = Path(text).read_text(encoding="ascii")
    text = text.strip()
    if not re.fullmatch(r"[0-9a-fA-F]{64}", text):
        raise ValueError("a key is 64 hex digits (sweptccd keygen)")
    return bytes.fromhex(text)


def proof(key: bytes, kind: str, challenge: str, ident: Optional[str] = None) -> str:
    """WEBSOCKET.md section 4: hex(HMAC-SHA256(key, LABEL\\nchallenge[\\nid]))."""
    message = PROOF_LABEL[kind] + "\n" + challenge + ("" if ident is None else "\n" + ident)
    return hmac.new(key, message.encode("ascii"), hashlib.sha256).hexdigest()


def skeleton_arrays(skeleton: Union[Mapping[str, Any], str, "os.PathLike[str]"]
                    ) -> Dict[str, List[Any]]:
    """A SPEC 1 skeleton (a file or its dict) as join_request's arrays
    (link_name, parent as an index or -1, a, b, radius). The daemon checks
    the skeleton (bad_skeleton names the problem)."""
    if not isinstance(skeleton, Mapping):
        skeleton = json.loads(Path(os.fspath(skeleton)).read_text(encoding="utf-8"))
    assert isinstance(skeleton, Mapping)
    links = list(skeleton["links"])
    index = {str(link["name"]): i for i, link in enumerate(links)}
    parent = []
    for link in links:
        p = link.get("parent")
        if p is not None and p not in index:
            raise ValueError(f"skeleton: link {link['name']!r}: unknown parent {p!r}")
        parent.append(-1 if p is None else index[p])
    return {"link_name": [str(link["name"]) for link in links], "parent": parent,
            "a": [list(map(float, link["a"])) for link in links],
            "b": [list(map(float, link["b"])) for link in links],
            "radius": [float(link["radius"]) for link in links]}


def _now_us() -> int:
    return time.time_ns() // 1000


class LiveClient:
    """One avatar in a live room (see the module's docstring).

    url: ws:// or wss:// ... /ws. key: the room key (bytes, hex, or a key
    file); None in an unsigned room. motion: "articulated" or "independent".
    eps, delta: 0 for the daemon's. ignore: LINK:OBJECT rules;
    ignore_entities: dicts {"link", "entity", ["other_link"]} (SPEC 8).
    reconnect: join again after a drop (backoff 0.25 s doubling to 4 s, plus
    up to 25% jitter), as WEBSOCKET.md section 9 says.
    """

    def __init__(self, url: str, client_id: str,
                 skeleton: Union[Mapping[str, Any], str, "os.PathLike[str]"], *,
                 key: Union[str, bytes, "os.PathLike[str]", None] = None,
                 motion: str = "articulated", eps: float = 0.0, delta: float = 0.0,
                 ignore: Sequence[str] = (), ignore_entities: Sequence[Mapping[str, str]] = (),
                 nonce: Optional[int] = None, reconnect: bool = True,
                 open_timeout: float = 10.0, queue_size: int = 4096) -> None:
        if not CLIENT_ID.match(client_id):
            raise ValueError("client_id: 1-64 of [A-Za-z0-9_.-]")
        if motion not in ("articulated", "independent"):
            raise ValueError("motion must be articulated or independent")
        self.url = url
        self.client_id = client_id
        self.skeleton = skeleton_arrays(skeleton)
        self.num_links = len(self.skeleton["link_name"])
        self._key = parse_key(key) if key is not None else None
        self._motion = 0 if motion == "articulated" else 1
        self._eps, self._delta = float(eps), float(delta)
        self._ignore = list(ignore)
        self._entities = [dict(e) for e in ignore_entities]
        self.nonce = nonce if nonce is not None else random.randrange(2**53 - 1)
        self.reconnect = reconnect
        self._open_timeout = open_timeout
        self._callbacks: Dict[str, List[Callback]] = {name: [] for name in EVENTS}
        self._queue: "asyncio.Queue[Optional[Message]]" = asyncio.Queue(queue_size)
        self._ws: Optional[websockets.client.WebSocketClientProtocol] = None
        self._reader: Optional["asyncio.Task[None]"] = None
        self._joined_event = asyncio.Event()
        self._join_error: Optional[BaseException] = None
        self._leaving = False
        self.session = 0
        self.instance = 0
        self.hello: Message = {}
        self.joins = 0
        self.seq = 0
        self._last_utime = 0
        self.sent_poses = 0
        self.dropped_poses = 0
        self.dropped_events = 0

    # ---- events ---------------------------------------------------------
    def on(self, event: str, callback: Callback) -> None:
        """Calls callback(message) for each event: "joined" (the join_reply,
        with "rejoin": bool), "refused", "contact" (contact_event),
        "shared_contact", "rejection", "status", "error" (a non-fatal error
        message), "disconnected" ({"code", "reason"}). A coroutine function
        is scheduled as a task."""
        name = _ALIASES.get(event, event)
        if name not in self._callbacks:
            raise ValueError(f"unknown event {event!r}; one of {', '.join(EVENTS)}")
        self._callbacks[name].append(callback)

    async def events(self) -> AsyncIterator[Message]:
        """Every event message in arrival order (the same as the callbacks
        get), until the client leaves or fails."""
        while True:
            msg = await self._queue.get()
            if msg is None:
                return
            yield msg

    def _emit(self, name: str, msg: Message) -> None:
        for cb in self._callbacks[name]:
            result = cb(msg)
            if asyncio.iscoroutine(result):
                asyncio.ensure_future(result)
        if name in ("joined", "refused", "disconnected"):
            return
        try:
            self._queue.put_nowait(msg)
        except asyncio.QueueFull:
            self.dropped_events += 1  # Nobody iterates: callbacks still saw it.

    # ---- life -----------------------------------------------------------
    @property
    def joined(self) -> bool:
        return self._joined_event.is_set()

    @property
    def rejoins(self) -> int:
        return max(0, self.joins - 1)

    async def __aenter__(self) -> "LiveClient":
        await self.join()
        return self

    async def __aexit__(self, *exc: Any) -> None:
        await self.leave()

    async def join(self) -> Message:
        """Connects and joins; returns the accepted join_reply. Raises
        JoinRefused (a refusal not worth retrying), ProtocolError, OSError."""
        self._leaving = False
        await self._connect_and_join()
        self._reader = asyncio.ensure_future(self._read_forever())
        return self._last_reply

    async def rejoin(self) -> Message:
        """Drops the connection and joins again at once (same id and nonce:
        the daemon hands the id over to the new session)."""
        await self._stop_reader()
        if self._ws is not None:
            await self._ws.close(1000, "rejoin")
        return await self.join()

    async def leave(self) -> None:
        """Ends the session (a leave message) and closes. Idempotent."""
        self._leaving = True
        ws = self._ws
        if ws is not None and self.joined:
            try:
                await ws.send(json.dumps({"type": "leave", "utime": _now_us(),
                                          "client_id": self.client_id,
                                          "session": self.session}))
            except websockets.exceptions.ConnectionClosed:
                pass
        self._joined_event.clear()
        if ws is not None:
            await ws.close(1000, "leave")
        await self._stop_reader()
        self._queue_end()

    def _queue_end(self) -> None:
        try:
            self._queue.put_nowait(None)
        except asyncio.QueueFull:
            pass

    async def _stop_reader(self) -> None:
        if self._reader is not None and self._reader is not asyncio.current_task():
            self._reader.cancel()
            try:
                await self._reader
            except (asyncio.CancelledError, Exception):
                pass
        self._reader = None

    async def _connect_and_join(self) -> None:
        self._joined_event.clear()
        ws = await websockets.client.connect(
            self.url, subprotocols=[SUBPROTOCOL],  # type: ignore[list-item]
            open_timeout=self._open_timeout, max_size=1 << 22, compression=None)
        self._ws = ws
        hello = await self._recv(ws, self._open_timeout)
        if hello.get("type") != "hello" or hello.get("protocol") != 1:
            raise ProtocolError(f"expected hello of protocol 1, got {_display(str(hello)[:200])}")
        if self.instance and hello.get("instance") != self.instance:
            self.joins = 0  # The daemon restarted: a first join again.
        self.hello, self.instance = hello, int(hello.get("instance", 0))
        challenge = str(hello.get("challenge", ""))
        request: Message = {
            "type": "join_request", "utime": _now_us(), "client_id": self.client_id,
            "nonce": self.nonce, "motion": self._motion, "eps_s": self._eps,
            "delta_m": self._delta, **self.skeleton, "ignore": self._ignore,
            "ignore_entity_link": [e["link"] for e in self._entities],
            "ignore_entity": [e["entity"] for e in self._entities],
            "ignore_entity_other_link": [e.get("other_link", "") for e in self._entities],
            "proof": proof(self._key, "join", challenge, self.client_id) if self._key else ""}
        await ws.send(json.dumps(request))
        while True:
            msg = await self._recv(ws, self._open_timeout)
            if msg.get("type") == "join_reply":
                break
            self._dispatch(msg)  # A status or an error before the reply.
        if msg.get("client_id") != self.client_id or msg.get("nonce") != self.nonce:
            raise ProtocolError("a join_reply for another join")
        if msg.get("reason") != REASON_ACCEPTED:
            self._emit("refused", msg)
            await ws.close(1000, "refused")
            raise JoinRefused(msg)
        self.session = int(msg["session"])
        self.seq = 0
        self._last_utime = 0
        self.joins += 1
        self._last_reply = msg
        self._joined_event.set()
        self._emit("joined", {**msg, "rejoin": self.joins > 1})

    async def _recv(self, ws: websockets.client.WebSocketClientProtocol,
                    timeout: float) -> Message:
        text = await asyncio.wait_for(ws.recv(), timeout)
        if not isinstance(text, str):
            raise ProtocolError("a binary frame from the server")
        msg = json.loads(text)
        if not isinstance(msg, dict):
            raise ProtocolError("a message that is not a JSON object")
        if msg.get("type") == "error" and msg.get("fatal"):
            raise ProtocolError(f"{_display(str(msg.get('code')))}: "
                                f"{_display(str(msg.get('message', '')))}")
        return msg

    def _dispatch(self, msg: Message) -> None:
        kind = msg.get("type")
        if kind == "contact_event" and msg.get("client_id") != self.client_id:
            return
        if kind in ("contact_event", "shared_contact", "rejection", "status", "error"):
            self._emit(str(kind), msg)

    async def _read_forever(self) -> None:
        backoff = 0.25
        while True:
            ws = self._ws
            assert ws is not None
            try:
                async for text in ws:
                    if not isinstance(text, str):
                        continue
                    msg = json.loads(text)
                    if isinstance(msg, dict):
                        if msg.get("type") == "error" and msg.get("fatal"):
                            self._emit("error", msg)
                        else:
                            self._dispatch(msg)
                backoff = 0.25
            except (websockets.exceptions.ConnectionClosed, OSError, ValueError):
                pass
            self._joined_event.clear()
            self._emit("disconnected", {"code": ws.close_code, "reason": ws.close_reason})
            if self._leaving or not self.reconnect:
                self._queue_end()
                return
            while not self._leaving:  # WEBSOCKET.md section 9.
                await asyncio.sleep(backoff * (1 + 0.25 * random.random()))
                backoff = min(4.0, backoff * 2)
                try:
                    await self._connect_and_join()
                    break
                except JoinRefused as e:
                    if e.reply.get("reason") not in RETRY_REASONS:
                        self._join_error = e
                        self._queue_end()
                        return
                except (OSError, ProtocolError, asyncio.TimeoutError,
                        websockets.exceptions.WebSocketException):
                    pass

    async def wait_joined(self, timeout: Optional[float] = None) -> None:
        """Waits until joined (after a drop: until joined again)."""
        await asyncio.wait_for(self._joined_event.wait(), timeout)

    # ---- poses ----------------------------------------------------------
    async def publish(self, position: Any, orientation: Any, *, utime: Optional[int] = None,
                      seq: Optional[int] = None) -> bool:
        """Sends one pose: position (links, 3) metres and orientation
        (links, 4) [w, x, y, z], world frame, link index order (lists or
        NumPy arrays); utime (default: now, strictly increasing) and seq
        (default: the next). False (the pose dropped) when not joined."""
        pos = [[float(v) for v in p] for p in position]
        ori = [[float(v) for v in q] for q in orientation]
        if len(pos) != self.num_links or len(ori) != self.num_links:
            raise ValueError(f"pose: {len(pos)} positions / {len(ori)} orientations, the "
                             f"skeleton has {self.num_links} links")
        if any(len(p) != 3 for p in pos) or any(len(q) != 4 for q in ori):
            raise ValueError("pose: positions have 3 numbers, orientations 4 [w, x, y, z]")
        ws = self._ws
        if ws is None or not self.joined:
            self.dropped_poses += 1
            return False
        t = utime if utime is not None else max(_now_us(), self._last_utime + 1)
        s = seq if seq is not None else self.seq
        try:
            await ws.send(json.dumps({"type": "tracker_pose", "utime": int(t),
                                      "client_id": self.client_id, "session": self.session,
                                      "seq": int(s), "position": pos, "orientation": ori}))
        except websockets.exceptions.ConnectionClosed:
            self.dropped_poses += 1
            return False
        self.seq, self._last_utime = s + 1, int(t)
        self.sent_poses += 1
        return True

    async def publish_pose7(self, pose: Any, *, utime: Optional[int] = None,
                            seq: Optional[int] = None) -> bool:
        """publish() of one (links, 7) row [px, py, pz, qw, qx, qy, qz], the
        layout of Engine.query's arrays and of SPEC 2 pose lines."""
        rows = [[float(v) for v in r] for r in pose]
        return await self.publish([r[:3] for r in rows], [r[3:7] for r in rows], utime=utime,
                                  seq=seq)
