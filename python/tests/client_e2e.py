"""sweptccd.client.LiveClient against the real daemon's WebSocket door (run
by client_e2e.sh inside a private network namespace):
  - a wrong key is refused (bad_proof, a ProtocolError);
  - the client streams the bundled walk lock-step (each pose after the
    previous pair's answer) and every contact_event equals `sweptccd query`
    on the same samples (result, brackets, initially_colliding, undecided,
    the first witness's link, object and triangle); callbacks and the async
    iterator see the same events;
  - a pose out of order gets a rejection (non_increasing_seq);
  - rejoin: a greater session, seq restarting at 0, the walk answered
    exactly again;
  - the connection drops under it: it reconnects and joins by itself;
  - leave ends the iterator;
  - a client of another room is refused by the door (409 to ?room=) before
    any frame; the room's own clients name it (client_e2e.sh: --room
    py-room) and pass the hello's room check;
  - a client of the daemon's configuration (pywalker, its own key) joins
    through the door and the walk is answered as for a live client;
  - a hand joins with sweptccd.JointSkeleton("webxr-hand")'s skeleton and
    publishes joint frames (publish_joints): each pair answered, at the
    link poses JointSkeleton.convert gives; a frame with an untracked joint
    is refused with its one line and nothing is sent; a joint skeleton of
    another size is refused.
    python3 client_e2e.py URL KEY_FILE SKELETON POSES EXPECTED WALKER_KEY_FILE
"""

from __future__ import annotations

import asyncio
import json
import sys
from pathlib import Path
from typing import Any, Dict, List

import numpy as np

import sweptccd
from sweptccd.client import LiveClient, ProtocolError


def log(*a: Any) -> None:
    print("client_e2e:", *a, flush=True)


async def stream(client: LiveClient, poses: List[Dict[str, Any]], expected: List[Dict[str, Any]],
                 got: List[Dict[str, Any]]) -> None:
    """Lock-step: pose k + 1 after pair k - 1's answer; checks each answer."""
    start = len(got)
    for k, p in enumerate(poses):
        links = p["links"]
        assert await client.publish([r[:3] for r in links], [r[3:] for r in links],
                                    utime=p["utime"])
        if k == 0:
            continue
        for _ in range(2000):
            if len(got) >= start + k:
                break
            await asyncio.sleep(0.005)
        assert len(got) == start + k, f"no answer for pair {k - 1}"
        e, x = got[start + k - 1], expected[k - 1]
        assert e["result_name"] == x["result"], (k, e, x)
        assert e["pair"] == x["pair"] and e["utime0"] == x["utime0"], (e, x)
        if x["result"] == "contact":
            for f in ("s_lo", "s_hi", "t_lo", "t_hi", "initially_colliding", "undecided"):
                assert e[f] == x[f], (f, e[f], x[f])
            c, y = e["contacts"][0], x["contacts"][0]
            assert (c["link"], c["object"], c["triangle"]) == (y["link"], y["object"],
                                                               y["triangle"]), (c, y)


async def main() -> None:
    url, key, skeleton, poses_file, expected_file, walker_key = sys.argv[1:7]
    poses = [json.loads(line) for line in Path(poses_file).read_text().splitlines() if line]
    expected = [json.loads(line) for line in Path(expected_file).read_text().splitlines()
                if line]
    assert any(x["result"] == "contact" for x in expected)

    wrong = LiveClient(url, "pyalice", skeleton, key="00" * 32, reconnect=False)
    try:
        await wrong.join()
        raise AssertionError("a wrong key was accepted")
    except ProtocolError as e:
        assert "bad_proof" in str(e), e
        log("wrong key refused:", e)

    lost = LiveClient(url, "pylost", skeleton, key=key, room="other-room", reconnect=False)
    lost.on("contact", lambda e: log("FAILED: an event of another room"))
    try:
        await lost.join()
        raise AssertionError("a client of another room joined")
    except ProtocolError as e:
        assert "refused room 'other-room' (409)" in str(e), e
        assert lost.wrong_rooms == 1 and not lost.hello
        log("another room's client refused:", e)

    client = LiveClient(url, "pyalice", skeleton, key=key, room="py-room")
    got: List[Dict[str, Any]] = []
    rejections: List[Dict[str, Any]] = []
    joined: List[Dict[str, Any]] = []
    client.on("contact", got.append)
    client.on("rejection", rejections.append)
    client.on("joined", joined.append)
    iterated: List[Dict[str, Any]] = []

    async def iterate() -> None:
        async for ev in client.events():
            if ev["type"] == "contact_event":
                iterated.append(ev)

    reply = await client.join()
    it = asyncio.ensure_future(iterate())
    first_session = client.session
    assert reply["reason_name"] == "accepted" and first_session > 0
    await stream(client, poses, expected, got)
    log(f"walk streamed: {len(got)} events equal to sweptccd query")

    # Out of order: seq not increasing.
    last = poses[-1]
    links = last["links"]
    assert await client.publish([r[:3] for r in links], [r[3:] for r in links],
                                utime=last["utime"] + 1000, seq=client.seq - 1)
    for _ in range(1000):
        if rejections:
            break
        await asyncio.sleep(0.005)
    assert rejections and rejections[0]["reason"] == "non_increasing_seq", rejections
    log("out-of-order pose rejected:", rejections[0]["reason"])

    # Rejoin: a new, greater session; the same answers again.
    await client.rejoin()
    it2 = asyncio.ensure_future(iterate())
    assert client.session > first_session and client.seq == 0 and client.rejoins == 1
    assert joined[-1]["rejoin"] is True
    n = len(got)
    await stream(client, poses, expected, got)
    log(f"rejoined (session {first_session} -> {client.session}): {len(got) - n} events equal")

    # The connection drops under the client: it reconnects and joins again.
    session = client.session
    assert client._ws is not None
    await client._ws.close(1001, "test drop")
    for _ in range(2000):
        if client.joined and client.session > session:
            break
        await asyncio.sleep(0.005)
    assert client.joined and client.session > session, "no reconnect"
    log(f"dropped and rejoined by itself: session {session} -> {client.session}")

    await client.leave()
    await asyncio.wait_for(it2, 5)
    await asyncio.wait_for(it, 5)
    assert len(iterated) >= len(expected), (len(iterated), len(expected))
    log("left; callbacks and the iterator saw", len(got), "and", len(iterated), "events")

    # A configured client (docs/WEBSOCKET.md "Configured clients"): its own
    # key proves the join; answered as over LCM.
    walker = LiveClient(url, "pywalker", skeleton, key=walker_key, room="py-room")
    wgot: List[Dict[str, Any]] = []
    walker.on("contact", wgot.append)
    reply = await walker.join()
    assert reply["reason_name"] == "accepted" and walker.session > 0, reply
    await stream(walker, poses, expected, wgot)
    await walker.leave()
    log(f"configured client pywalker: {len(wgot)} events equal to sweptccd query")

    await joint_frames(url, key)


def hand_frame(k: int) -> np.ndarray:
    """webxr-hand's 25 joints: the default hand (a frame at the default
    skeleton's bone lengths) moved 5 mm a frame along x, 1 m above the
    apartment's floor near its origin. Each joint's +Y along its bone: the
    skeleton's own link frames, composed from the default skeleton."""
    js = sweptccd.JointSkeleton("webxr-hand")
    names = js.joint_names
    frame = np.zeros((len(names), 7))
    frame[:, 3] = 1.0
    # Joints along +Y: each link "A>B" of the default skeleton puts B at
    # A + (0, length, 0) when every joint has the identity orientation.
    for link in js.skeleton["links"]:
        parts = link["name"].rstrip("~").split(">")
        if len(parts) == 2 and parts[1] != "end":
            a, b = names.index(parts[0]), names.index(parts[1])
            frame[b, :3] = frame[a, :3] + np.array([0.0, link["b"][1], 0.0])
    frame[:, :3] += np.array([0.005 * k, 0.0, 1.0])
    return frame


async def joint_frames(url: str, key: str) -> None:
    js = sweptccd.JointSkeleton("webxr-hand")
    hand = LiveClient(url, "pyhand", js.skeleton, key=key, room="py-room")
    got: List[Dict[str, Any]] = []
    hand.on("contact", got.append)
    await hand.join()
    for k in range(4):  # Lock-step, as stream(): frame k + 1 after pair k - 1's answer.
        assert await hand.publish_joints(js, hand_frame(k), utime=1_000_000 + 11_111 * k) is None
        for _ in range(2000):
            if len(got) >= k:
                break
            await asyncio.sleep(0.005)
    assert [(e["pair"], e["seq0"], e["seq1"]) for e in got] == [(0, 0, 1), (1, 1, 2),
                                                                 (2, 2, 3)], got
    assert hand.sent_poses == 4
    untracked = [True] * js.num_joints
    untracked[js.joint_names.index("index-finger-tip")] = False
    why = await hand.publish_joints(js, hand_frame(4), valid=untracked, utime=1_100_000)
    assert why is not None and why.startswith("joint ") and "index-finger-tip" in why, why
    other = sweptccd.JointSkeleton("ext-hand")
    why2 = await hand.publish_joints(other, np.zeros((other.num_joints, 7)), utime=1_200_000)
    assert why2 is not None and "links" in why2, why2
    assert hand.sent_poses == 4
    await hand.leave()
    log(f"joint frames: 3 pairs answered; refused: {why!r}; {why2!r}")


asyncio.run(main())
print("client_e2e: passed")
