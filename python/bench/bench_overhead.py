"""Overhead per pair of the Python engine against `sweptccd query`, on the
same pairs (a bundled CMU walk in the MORSE apartment).

    PYTHONPATH=build/python /usr/bin/python3 python/bench/bench_overhead.py \
        --sweptccd build/bin/sweptccd --data data

Overhead of a pair = the wall time the caller waits for its record minus the
core's own query time (the record's elapsed_us), in microseconds:
- python, one call per pair: Engine.query on a 2-row array, records as
  dataclasses;
- python, one call for all pairs: Engine.query on the whole clip, the call's
  wall time minus the sum of elapsed_us, divided by the pairs (one sample per
  repeat);
- sweptccd query, one process per pair: what a script that shells out per
  pair waits (a 2-line pose file, process start, loading, JSON parsed);
- sweptccd query, one process for the clip: as the batch row above.
Prints a table: median, p99, max (microseconds). Both answer on the CPU."""

from __future__ import annotations

import argparse
import json
import subprocess
import tempfile
import time
from pathlib import Path
from typing import Dict, List, Tuple

import numpy as np
import numpy.typing as npt

import sweptccd


def read_pose_file(path: Path) -> Tuple[npt.NDArray[np.int64], npt.NDArray[np.float64]]:
    rows = [json.loads(line) for line in path.read_text().splitlines() if line.strip()]
    return (np.array([r["utime"] for r in rows], dtype=np.int64),
            np.array([r["links"] for r in rows], dtype=np.float64))


def write_pose_file(path: Path, utimes: npt.NDArray[np.int64],
                    poses: npt.NDArray[np.float64]) -> None:
    with path.open("w") as f:
        for u, p in zip(utimes, poses):
            f.write(json.dumps({"utime": int(u), "links": p.tolist()}) + "\n")


def row(name: str, values: List[float]) -> str:
    v = np.sort(np.asarray(values))
    p99 = v[int(0.99 * (len(v) - 1))]
    return f"| {name} | {len(v)} | {np.median(v):.1f} | {p99:.1f} | {v[-1]:.1f} |"


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--sweptccd", default="build/bin/sweptccd")
    ap.add_argument("--data", default="data")
    ap.add_argument("--cli-pairs", type=int, default=40,
                    help="pairs answered by one process each")
    ap.add_argument("--repeats", type=int, default=20, help="batch runs of the whole clip")
    args = ap.parse_args()
    data = Path(args.data)
    env = str(data / "env" / "morse_apartment.ply.gz")
    tmp = Path(tempfile.mkdtemp())
    skel, poses_file = tmp / "walk.json", tmp / "walk.jsonl"
    subprocess.run([args.sweptccd, "import-bvh", "--bvh",
                    str(data / "mocap" / "cmu_02_01_walk.bvh.gz"), "--up", "z", "--rate", "30",
                    "--offset", "0", "-1", "0.02", "--utime-start", "1000000", "--skeleton-out",
                    str(skel), "--poses-out", str(poses_file)], check=True, capture_output=True)
    utimes, poses = read_pose_file(poses_file)
    engine = sweptccd.Engine(skel, [env])
    n = len(utimes) - 1
    out: Dict[str, List[float]] = {}

    samples = []
    for _ in range(3):
        for k in range(n):
            start = time.perf_counter()
            (rec,) = engine.query(utimes[k:k + 2], poses[k:k + 2])
            wall = (time.perf_counter() - start) * 1e6
            samples.append(wall - float(rec.extra["elapsed_us"]))
    out["python Engine.query, one call per pair"] = samples

    samples = []
    for _ in range(args.repeats):
        start = time.perf_counter()
        recs = engine.query(utimes, poses)
        wall = (time.perf_counter() - start) * 1e6
        samples.append((wall - sum(float(r.extra["elapsed_us"]) for r in recs)) / n)
    out[f"python Engine.query, one call for {n} pairs (per pair)"] = samples

    samples = []
    for k in range(min(args.cli_pairs, n)):
        pair_file = tmp / "pair.jsonl"
        write_pose_file(pair_file, utimes[k:k + 2], poses[k:k + 2])
        start = time.perf_counter()
        r = subprocess.run([args.sweptccd, "query", "--backend", "cpu", "--skeleton", str(skel),
                            "--poses", str(pair_file), "--env", env],
                           check=True, capture_output=True, text=True)
        (record,) = [json.loads(line) for line in r.stdout.splitlines()]
        wall = (time.perf_counter() - start) * 1e6
        samples.append(wall - float(record["elapsed_us"]))
    out["sweptccd query, one process per pair"] = samples

    samples = []
    for _ in range(max(3, args.repeats // 4)):
        start = time.perf_counter()
        r = subprocess.run([args.sweptccd, "query", "--backend", "cpu", "--skeleton", str(skel),
                            "--poses", str(poses_file), "--env", env],
                           check=True, capture_output=True, text=True)
        records = [json.loads(line) for line in r.stdout.splitlines()]
        wall = (time.perf_counter() - start) * 1e6
        samples.append((wall - sum(float(x["elapsed_us"]) for x in records)) / n)
    out[f"sweptccd query, one process for {n} pairs (per pair)"] = samples

    print(f"overhead per pair, microseconds (wall time minus the core's elapsed_us); "
          f"{n} pairs of cmu_02_01_walk at 30 Hz, {engine.num_links} links, "
          f"morse_apartment ({engine.num_triangles} triangles)")
    print("| caller | samples | median | p99 | max |")
    print("|---|---|---|---|---|")
    for name, values in out.items():
        print(row(name, values))


if __name__ == "__main__":
    main()
