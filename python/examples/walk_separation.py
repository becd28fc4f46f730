"""The separations of a bundled CMU walk in the MORSE apartment, plotted.

    PYTHONPATH=build/python /usr/bin/python3 python/examples/walk_separation.py \
        --sweptccd build/bin/sweptccd --data data --out docs/python_walk_separation.png

Imports the clip with `sweptccd import-bvh` (as tools/demo.sh does: Z-up, 30 Hz,
1 m off the clip's origin, where it meets a table, 2 cm up), loads the
skeleton and the apartment once, then asks the engine for every link's
separation at every sample and for the certified first contact of every
pair, and draws both over time (docs/PYTHON.md)."""

from __future__ import annotations

import argparse
import json
import subprocess
import tempfile
from pathlib import Path
from typing import List, Tuple

import matplotlib  # type: ignore[import]

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # type: ignore[import]  # noqa: E402
import numpy as np  # noqa: E402
import numpy.typing as npt  # noqa: E402

import sweptccd  # noqa: E402


def read_pose_file(path: Path) -> Tuple[npt.NDArray[np.int64], npt.NDArray[np.float64]]:
    """A SPEC 2 pose file as arrays: utimes (N,), poses (N, links, 7)."""
    rows = [json.loads(line) for line in path.read_text().splitlines() if line.strip()]
    return (np.array([r["utime"] for r in rows], dtype=np.int64),
            np.array([r["links"] for r in rows], dtype=np.float64))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sweptccd", default="build/bin/sweptccd")
    ap.add_argument("--data", default="data")
    ap.add_argument("--out", default="python_walk_separation.png")
    args = ap.parse_args()
    data = Path(args.data)

    with tempfile.TemporaryDirectory() as tmp:
        skel, poses_file = Path(tmp) / "walk.json", Path(tmp) / "walk.jsonl"
        subprocess.run([args.sweptccd, "import-bvh", "--bvh",
                        str(data / "mocap" / "cmu_02_01_walk.bvh.gz"), "--up", "z", "--rate",
                        "30", "--offset", "0", "-1", "0.02", "--utime-start", "1000000",
                        "--skeleton-out", str(skel), "--poses-out", str(poses_file)],
                       check=True, capture_output=True)
        utimes, poses = read_pose_file(poses_file)
        engine = sweptccd.Engine(skel, [data / "env" / "morse_apartment.ply.gz"])

    sep = engine.separations(poses, search_radius=1.0)  # (N, links), +inf beyond 1 m
    records = engine.query(utimes, poses)
    t = (utimes - utimes[0]) * 1e-6
    contacts: List[sweptccd.Record] = [r for r in records if r.contact]
    print(f"{len(records)} pairs, {len(contacts)} contact, {engine.num_links} links, "
          f"{engine.num_triangles} triangles")
    for r in contacts[:3]:
        c = (r.contacts or [])[0]
        print(f"pair {r.pair}: first contact in [{r.t_lo}, {r.t_hi}] us, link "
              f"{engine.link_names[c.link]}, object {c.object}, separation {c.separation:.2e} m")

    fig, ax = plt.subplots(figsize=(9, 4.5), dpi=110)
    shown = np.where(np.isfinite(sep), sep, np.nan)
    order = np.argsort(np.nanmin(np.where(np.isfinite(sep), sep, np.inf), axis=0))
    for i in order[:5]:  # The five links that come closest.
        ax.plot(t, shown[:, i], lw=1.2, label=engine.link_names[i])
    ax.plot(t, np.nanmin(shown, axis=1), color="black", lw=2, label="closest link")
    for r in contacts:
        assert r.t_lo is not None and r.utime1 is not None
        ax.axvspan((r.t_lo - utimes[0]) * 1e-6, (r.utime1 - utimes[0]) * 1e-6, color="red",
                   alpha=0.15, lw=0)
    if contacts:
        first = contacts[0]
        assert first.t_lo is not None
        t_first = (first.t_lo - utimes[0]) * 1e-6
        ax.axvline(t_first, color="red", ls="--", lw=1)
        ax.annotate(f"first contact: pair {first.pair}\nt_lo = {t_first:.4f} s",
                    (t_first, 0.0), xytext=(t_first - 0.9, 0.75), fontsize=8,
                    arrowprops={"arrowstyle": "->", "color": "red"})
    ax.axhline(0, color="grey", lw=0.8)
    ax.set_xlabel("time (s)")
    ax.set_ylabel("separation from the apartment (m)")
    ax.set_title("CMU 02_01 walk in the MORSE apartment: separations at each sample;\n"
                 "red: from each contact pair's certified first contact (t_lo) to its end")
    ax.legend(loc="upper right", fontsize=8)
    ax.set_ylim(min(-0.05, float(np.nanmin(shown)) - 0.02), 1.0)
    fig.tight_layout()
    fig.savefig(args.out)
    print(f"wrote {args.out}")


if __name__ == "__main__":
    main()
