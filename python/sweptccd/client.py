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
from typing import (TYPE_CHECKING, Any, AsyncIterator, Callable, Dict, List, Mapping, Optional,
                    Sequence, Union)

import websockets.client
import websockets.exceptions

from .rooms import hello_room_problem, with_room

if TYPE_CHECKING:
    from . import JointSkeleton

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
    file), or a configured client's own key (security.client_keys); None in
    an unsigned room. motion: "articulated" or "independent".
    eps, delta: 0 for the daemon's. ignore: LINK:OBJECT rules;
    ignore_entities: dicts {"link", "entity", ["other_link"]} (SPEC 8).
    reconnect: join again after a drop (backoff 0.25 s doubling to
    max_backoff, 4 s, plus up to 25% jitter), as WEBSOCKET.md section 9 says.

    Failover (docs/DEPLOY.md), the C++ and JavaScript clients' rules: with
    resolver and room (sweptccd.rooms) every connection resolves the room's
    door (url is then None); no status of the joined instance for
    heartbeat_timeout seconds takes the room for dead; hellos of an older
    instance and events of another instance are fenced; seq goes on across
    re-joins and the poses whose pair is unanswered are re-sent after the
    re-join (lock-step, same seq and utime); an answer already delivered is
    dropped; a rejection unknown_client re-joins at once. room (with or
    without a resolver) is sent as ``?room=`` and checked against
    hello.room: a door of another room (409, or another hello.room) is
    refused before any join and resolved again (wrong_rooms counts them).
    """

    def __init__(self, url: Optional[str], client_id: str,
                 skeleton: Union[Mapping[str, Any], str, "os.PathLike[str]"], *,
                 key: Union[str, bytes, "os.PathLike[str]", None] = None,
                 motion: str = "articulated", eps: float = 0.0, delta: float = 0.0,
                 ignore: Sequence[str] = (), ignore_entities: Sequence[Mapping[str, str]] = (),
                 nonce: Optional[int] = None, reconnect: bool = True,
                 open_timeout: float = 10.0, queue_size: int = 4096,
                 resolver: Any = None, room: str = "", heartbeat_timeout: float = 3.0,
                 max_backoff: float = 4.0, max_pending: int = 4096) -> None:
        if not CLIENT_ID.match(client_id):
            raise ValueError("client_id: 1-64 of [A-Za-z0-9_.-]")
        if motion not in ("articulated", "independent"):
            raise ValueError("motion must be articulated or independent")
        if url is None and resolver is None:
            raise ValueError("give url, or resolver and room")
        self.url = url or ""
        with_room("", room)  # A room name breaking the id rule: RoomError now.
        self.resolver, self.room = resolver, room
        self.heartbeat_timeout, self.max_backoff = heartbeat_timeout, max_backoff
        self._max_pending = max_pending
        self._pending: List[Message] = []  # From the last answered pose on.
        self._answered: Dict[int, None] = {}
        self._awaiting = -1
        self._answer_seen = asyncio.Event()
        self._resender: Optional["asyncio.Task[None]"] = None
        self._max_instance = 0
        self._last_status = 0.0
        self.fenced_events = self.fenced_hellos = self.heartbeat_losses = 0
        self.wrong_rooms = 0  # Doors of another room (409 to ?room=, or hello.room): refused.
        self.resent_poses = self.repeated_answers = self.forgotten_poses = 0
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
        the daemon hands the id over to the new session). An explicit restart
        of the stream: seq starts again at 0, nothing is re-sent (automatic
        re-joins after a drop or a failover keep seq and re-send)."""
        await self._stop_reader()
        self.seq, self._last_utime = 0, 0
        self._pending, self._answered = [], {}
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
        if self.resolver is not None:
            door = await asyncio.get_running_loop().run_in_executor(
                None, self.resolver.resolve, self.room)
            self.url = door.url
        try:
            ws = await websockets.client.connect(
                with_room(self.url, self.room), subprotocols=[SUBPROTOCOL],  # type: ignore[list-item]
                open_timeout=self._open_timeout, max_size=1 << 22, compression=None)
        except websockets.exceptions.InvalidStatusCode as e:
            if e.status_code != 409:
                raise
            self.wrong_rooms += 1  # The door holds another room (WEBSOCKET.md section 1).
            raise ProtocolError(f"door {_display(self.url)} refused room '{self.room}' (409): "
                                "it holds another room") from None
        self._ws = ws
        hello = await self._recv(ws, self._open_timeout)
        if hello.get("type") != "hello" or hello.get("protocol") != 1:
            raise ProtocolError(f"expected hello of protocol 1, got {_display(str(hello)[:200])}")
        wrong_room = hello_room_problem(self.room, hello, self.url)
        if wrong_room:
            self.wrong_rooms += 1  # Never joined: no event of another room is delivered.
            await ws.close(1000, "wrong room")
            raise ProtocolError(wrong_room)
        if int(hello.get("instance", 0)) < self._max_instance:
            self.fenced_hellos += 1  # An older run of the room (a stale allocation).
            await ws.close(1000, "fenced")
            raise ProtocolError(f"instance {int(hello.get('instance', 0))} is older than "
                                f"{self._max_instance} joined already: fenced")
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
        self.instance = int(msg.get("instance", self.instance))
        self._max_instance = max(self._max_instance, self.instance)
        self._last_status = time.monotonic()
        self.joins += 1
        if self._pending:
            self.resent_poses += len(self._pending)
            self._resender = asyncio.ensure_future(self._resend(ws, list(self._pending)))
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

    async def _resend(self, ws: websockets.client.WebSocketClientProtocol,
                      poses: List[Message]) -> None:
        """The unanswered poses under the new session, one pair at a time
        (latest-wins would merge a burst), paced under the door's limits."""
        limits = self.hello.get("limits", {})
        period = 1.0 / max(1.0, 0.8 * min(float(limits.get("message_rate_hz", 480)),
                                          float(limits.get("max_pose_rate_hz", 240))))
        for i, pose in enumerate(poses):
            self._answer_seen.clear()
            self._awaiting = -1 if i == 0 else int(pose["seq"])  # The first anchors.
            try:
                await ws.send(json.dumps({**pose, "session": self.session}))
            except websockets.exceptions.ConnectionClosed:
                return
            if self._awaiting >= 0:
                try:
                    await asyncio.wait_for(self._answer_seen.wait(), 0.25)
                except asyncio.TimeoutError:
                    pass  # Shed or suppressed: go on.
            await asyncio.sleep(period)
        self._awaiting = -1

    def _pair_done(self, seq: int) -> None:
        if self._awaiting >= 0 and seq >= self._awaiting:
            self._answer_seen.set()

    def _dispatch(self, msg: Message) -> None:
        kind = msg.get("type")
        instance = msg.get("instance")
        if kind != "join_reply" and isinstance(instance, int) and instance != self.instance:
            self.fenced_events += 1  # Another daemon run's event (WEBSOCKET.md "The epoch").
            return
        if kind == "status":
            self._last_status = time.monotonic()
        if kind == "rejection" and msg.get("client_id") == self.client_id:
            if msg.get("reason") == "unknown_client" and self.joined and self._ws is not None:
                self._abort(self._ws)  # The daemon dropped the session: join again.
            else:
                seq = msg.get("seq")
                self._pending = [p for p in self._pending if p["seq"] != seq]
                if isinstance(seq, int):
                    self._pair_done(seq)
        if kind == "contact_event" and msg.get("client_id") == self.client_id:
            seq1 = msg.get("seq1")
            if isinstance(seq1, int):
                self._pair_done(seq1)
                while self._pending and self._pending[0]["seq"] < seq1:
                    self._pending.pop(0)
                if seq1 in self._answered:
                    self.repeated_answers += 1
                    return
                self._answered[seq1] = None
                if len(self._answered) > 8192:
                    del self._answered[next(iter(self._answered))]
        if kind == "contact_event" and msg.get("client_id") != self.client_id:
            return
        if kind in ("contact_event", "shared_contact", "rejection", "status", "error"):
            self._emit(str(kind), msg)

    @staticmethod
    def _abort(ws: websockets.client.WebSocketClientProtocol) -> None:
        """Drops a connection without a close handshake (the peer may be gone)."""
        transport = getattr(ws, "transport", None)
        if transport is not None:
            transport.abort()

    async def _messages(self, ws: websockets.client.WebSocketClientProtocol
                        ) -> AsyncIterator[Union[str, bytes]]:
        """ws's messages until it closes, or until no status of the joined
        instance came for heartbeat_timeout (the room is dead: aborted)."""
        limit = self.heartbeat_timeout
        period = self.hello.get("limits", {}).get("status_period_ms")
        if type(period) is int and 0 < period <= 3600000:
            limit = max(limit, 3 * period / 1000)  # At least 3 of the door's status periods.
        while True:
            timeout = None
            if self.heartbeat_timeout > 0 and self.joined:
                timeout = max(0.01, self._last_status + limit - time.monotonic())
            try:
                yield await asyncio.wait_for(ws.recv(), timeout)
            except asyncio.TimeoutError:
                if self.joined and time.monotonic() - self._last_status > limit:
                    self.heartbeat_losses += 1
                    self._abort(ws)
                    return

    async def _read_forever(self) -> None:
        backoff = 0.25
        while True:
            ws = self._ws
            assert ws is not None
            try:
                async for text in self._messages(ws):
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
            if self._resender is not None:
                self._resender.cancel()
                self._resender = None
            self._emit("disconnected", {"code": ws.close_code, "reason": ws.close_reason})
            if self._leaving or not self.reconnect:
                self._queue_end()
                return
            while not self._leaving:  # WEBSOCKET.md section 9.
                await asyncio.sleep(backoff * (1 + 0.25 * random.random()))
                backoff = min(self.max_backoff, backoff * 2)
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
                except Exception as e:  # noqa: BLE001 - a RoomError from the resolver
                    if getattr(e, "retryable", True) is False:
                        self._join_error = e
                        self._queue_end()
                        return

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
        rejoining = (not self.joined and (self.joins > 0 or self._max_instance > 0)
                     and not self._leaving and self.reconnect)
        if ws is None or not (self.joined or rejoining):
            self.dropped_poses += 1
            return False
        t = utime if utime is not None else max(_now_us(), self._last_utime + 1)
        s = seq if seq is not None else self.seq
        if s < self.seq:  # Numbered from anew: a new stream.
            self._pending, self._answered = [], {}
        pose = {"type": "tracker_pose", "utime": int(t), "client_id": self.client_id,
                "session": self.session, "seq": int(s), "position": pos, "orientation": ori}
        self._pending.append(pose)
        if len(self._pending) > self._max_pending:
            self._pending.pop(0)
            self.forgotten_poses += 1
        self.seq, self._last_utime = s + 1, int(t)
        if rejoining or (self._resender is not None and not self._resender.done()):
            # Sent after the re-join / behind the re-sent ones (_resend's list
            # is a copy: add it there too).
            if self._resender is not None and not self._resender.done():
                await self._resender
                if self.joined and self._ws is not None:
                    try:
                        await self._ws.send(json.dumps({**pose, "session": self.session}))
                    except websockets.exceptions.ConnectionClosed:
                        pass
            self.sent_poses += 1
            return True
        try:
            await ws.send(json.dumps(pose))
        except websockets.exceptions.ConnectionClosed:
            self.dropped_poses += 1
            return False
        self.sent_poses += 1
        return True

    async def publish_joints(self, joints: "JointSkeleton", frame: Any, *,
                             valid: Optional[Sequence[bool]] = None,
                             utime: Optional[int] = None,
                             seq: Optional[int] = None) -> Optional[str]:
        """Publishes one frame of a tracking runtime's joint poses (OpenXR,
        WebXR, VRM; docs/SKELETONS.md) as the link poses of `joints`'
        skeleton, which must be the skeleton this client joined with:
        converts it (JointSkeleton.convert, the C++ rule) and sends it as
        publish() does. frame: (num_joints, 7) rows [px, py, pz, qw, qx,
        qy, qz]; valid: one flag per joint (default all valid). Returns None
        when sent; else nothing is sent and the one-line reason: the frame's
        problem (an untracked joint a link needs, NaN, a bone off its
        length), a link count that is not the joined skeleton's, or not
        joined. The C++ client's PublishJointFrame, in Python."""
        if joints.num_links != self.num_links:
            return (f"joint frame: the joint skeleton has {joints.num_links} links, this "
                    f"client joined with {self.num_links}")
        try:
            links = joints.convert(frame, valid)
        except ValueError as e:  # InputError included: the frame's one line.
            return str(e)
        if not await self.publish_pose7(links, utime=utime, seq=seq):
            return "not joined: the pose was dropped"
        return None

    async def publish_pose7(self, pose: Any, *, utime: Optional[int] = None,
                            seq: Optional[int] = None) -> bool:
        """publish() of one (links, 7) row [px, py, pz, qw, qx, qy, qz], the
        layout of Engine.query's arrays and of SPEC 2 pose lines."""
        rows = [[float(v) for v in r] for r in pose]
        return await self.publish([r[:3] for r in rows], [r[3:7] for r in rows], utime=utime,
                                  seq=seq)
