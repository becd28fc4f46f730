"""Streams a pose file to a live daemon over its WebSocket door and prints
each contact as it is answered (docs/PYTHON.md, "The live client").

    PYTHONPATH=build/python /usr/bin/python3 python/examples/live_walk.py \
        --url ws://127.0.0.1:7701/ws --key room.key --id walker \
        --skeleton walk.json --poses walk.jsonl --rate 30
"""

from __future__ import annotations

import argparse
import asyncio
import json
from pathlib import Path
from typing import Any, Dict

from sweptccd.client import LiveClient


async def run(args: argparse.Namespace) -> None:
    rows = [json.loads(line) for line in Path(args.poses).read_text().splitlines() if line]
    answered = 0

    def on_contact(event: Dict[str, Any]) -> None:
        nonlocal answered
        answered += 1
        if event["result_name"] == "contact":
            c = event["contacts"][0]
            print(f"pair {event['pair']}: contact at s in [{event['s_lo']:.5f}, "
                  f"{event['s_hi']:.5f}], link {c['link']}, object {c['object']}, "
                  f"separation {c['separation']:.2e} m")

    client = LiveClient(args.url, args.id, args.skeleton, key=args.key)
    client.on("contact", on_contact)
    client.on("rejection", lambda r: print(f"rejected: {r['reason']}"))
    async with client:
        print(f"joined as {args.id}: session {client.session}")
        for row in rows[:args.count] if args.count else rows:
            await client.publish_pose7(row["links"])  # utime: now, seq: the next
            await asyncio.sleep(1.0 / args.rate)
        for _ in range(500):  # The last answers (at most 5 s).
            if answered >= client.sent_poses - 1:
                break
            await asyncio.sleep(0.01)
    print(f"left: {client.sent_poses} poses sent, {answered} events")


def main() -> None:
    ap = argparse.ArgumentParser(description="Stream a pose file to a live daemon")
    ap.add_argument("--url", required=True)
    ap.add_argument("--key", help="room key file (absent: an unsigned room)")
    ap.add_argument("--id", default="walker")
    ap.add_argument("--skeleton", required=True)
    ap.add_argument("--poses", required=True)
    ap.add_argument("--rate", type=float, default=30.0)
    ap.add_argument("--count", type=int, default=0, help="poses to send (0: all)")
    asyncio.run(run(ap.parse_args()))


if __name__ == "__main__":
    main()
