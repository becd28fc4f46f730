#!/usr/bin/env python3
"""Alternates `sweptccd bench` of two builds, four configurations, and
compares them (docs/BENCHMARKS.md).

    python3 tools/bench_ab.py OLD_BIN_DIR NEW_BIN_DIR [REPS] [--data DIR]

Each configuration (30 Hz; 15 Hz; independent motion; per-link) runs REPS
times (default 3), the two builds one after the other in each repetition,
on the three scenes of ../shared/data (or --data), up to 300 pairs per clip,
CPU only, thread CPU time, with the FCL and Bullet peers. Per configuration
it prints the targets met per run, the per-clip rows whose median is at most
Bullet's, the geometric mean over the rows of the new / old ratio of the
median (and of the p99; each row's figure is the median of its REPS runs),
the rows where the new build's first run is slower than Bullet at the
median (Bullet / ours), and a few rows in full.
"""
import argparse
import math
import os
import re
import statistics
import subprocess
import sys

CONFIGS = [("30 Hz", []), ("15 Hz", ["--rate", "15"]),
           ("independent", ["--motion", "independent"]), ("per-link", ["--per-link"])]
SCENES = ("morse_apartment", "grey_white_room", "breakfast_room")
SHOWN = ("cmu_02_01_wa", "cmu_05_06_da", "cmu_02_03_ru", "boxing_toes.")


def run_once(binary, data, extra, root):
    cmd = [binary, "bench", "--data", data, "--gpu", "off", "--clock", "thread",
           "--max-pairs", "300"]
    for s in SCENES:
        cmd += ["--scene", s]
    out = subprocess.run(cmd + extra, capture_output=True, text=True, cwd=root, check=True).stdout
    header, rows, met = None, {}, None
    for line in out.splitlines():
        f = line.split()
        if f and f[0] == "scene":
            header = f
            continue
        if header and f and f[0] in SCENES:
            if f[2] == "ALL":  # "ALL CLIPS": two words.
                f = f[:2] + ["ALL_CLIPS"] + f[4:]
            d = dict(zip(header, f))
            rows[(f[0], f[2][:12])] = (float(d["median_us"]), float(d["p99_us"]),
                                       float(d["bul_med"]), float(d["bul_p99"]))
        m = re.match(r"targets met: (\d+) of (\d+)", line)
        if m:
            met = int(m.group(1))
    if not rows or met is None:
        sys.exit(f"bench_ab: no table from {' '.join(cmd)}")
    return rows, met


def geomean_ratio(old_runs, new_runs, keys, col):
    logs = [math.log(statistics.median(r[0][k][col] for r in new_runs) /
                     statistics.median(r[0][k][col] for r in old_runs)) for k in keys]
    return math.exp(sum(logs) / len(logs))


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("old")
    ap.add_argument("new")
    ap.add_argument("reps", nargs="?", type=int, default=3)
    root = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
    ap.add_argument("--data", default=os.path.join(os.path.dirname(root), "shared", "data"))
    a = ap.parse_args()
    builds = [os.path.join(os.path.abspath(b), "sweptccd") for b in (a.old, a.new)]
    for name, extra in CONFIGS:
        runs = {b: [] for b in builds}
        for _ in range(a.reps):
            for b in builds:
                runs[b].append(run_once(b, os.path.abspath(a.data), extra, root))
        old, new = runs[builds[0]], runs[builds[1]]
        print("==", name)
        for b in builds:
            per_clip = [sum(1 for k, v in rows.items() if k[1] != "ALL_CLIPS" and v[0] <= v[2])
                        for rows, _ in runs[b]]
            print(f"  {b}: targets met {[m for _, m in runs[b]]}; "
                  f"median <= Bullet per-clip rows {per_clip} of 18")
        keys = list(old[0][0].keys())
        print("  geomean median ratio new/old over %d rows: %.3f" %
              (len(keys), geomean_ratio(old, new, keys, 0)))
        print("  geomean p99 ratio new/old over %d rows: %.3f" %
              (len(keys), geomean_ratio(old, new, keys, 1)))
        rows = new[0][0]
        slower = [f"{k[0][:5]} {k[1]} {v[2] / v[0]:.2f}" for k, v in rows.items()
                  if k[1] != "ALL_CLIPS" and v[0] > v[2]]
        print("  new run 1, median > Bullet (Bullet / ours):", "; ".join(slower))
        for k in keys:
            if k[1] not in SHOWN:
                continue
            o = [r[0][k] for r in old]
            n = [r[0][k] for r in new]
            med = lambda xs, i: statistics.median(x[i] for x in xs)
            print(f"    {k[0][:9]:9s} {k[1]:12s} med {med(o, 0):7.1f} / {med(n, 0):7.1f}"
                  f"  p99 {med(o, 1):7.1f} / {med(n, 1):7.1f}  bullet med {med(n, 2):6.1f}")


if __name__ == "__main__":
    main()
