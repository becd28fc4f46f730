"""Shared fixtures: a short CMU walk imported by `sweptccd import-bvh` (the
command under comparison), the MORSE apartment, and a small shared world.

ctest (python/tests/CMakeLists registration) sets SWEPTCCD_BINARY (the
sweptccd command), SWEPTCCD_DATA_DIR and PYTHONPATH (build/python)."""

from __future__ import annotations

import json
import os
import subprocess
from pathlib import Path
from typing import Any, Dict, List, Tuple

import numpy as np
import pytest

BINARY = os.environ.get("SWEPTCCD_BINARY", "build/bin/sweptccd")
DATA = Path(os.environ.get("SWEPTCCD_DATA_DIR", "data")).resolve()
APARTMENT = str(DATA / "env" / "morse_apartment.ply.gz")
BUNNY = str(DATA / "env" / "stanford_bunny.obj.gz")


def run_cli(*args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run([BINARY, *args], capture_output=True, text=True, timeout=120)


def import_clip(out: Path, name: str, bvh: str, frames: int, offset: Tuple[float, float, float],
                utime_start: int) -> Tuple[Path, Path]:
    """The clip as a skeleton and a pose file (frames: source frames, 0: all)."""
    skel, poses = out / f"{name}.json", out / f"{name}.jsonl"
    r = run_cli("import-bvh", "--bvh", str(DATA / "mocap" / bvh), "--up", "z", "--rate", "30",
                *(["--frames", str(frames)] if frames else []), "--offset", *map(str, offset), "--utime-start",
                str(utime_start), "--skeleton-out", str(skel), "--poses-out", str(poses))
    assert r.returncode == 0, r.stderr
    return skel, poses


def read_pose_file(path: Path) -> Tuple[np.ndarray, np.ndarray]:
    rows = [json.loads(line) for line in path.read_text().splitlines() if line.strip()]
    return (np.array([r["utime"] for r in rows], dtype=np.int64),
            np.array([r["links"] for r in rows], dtype=np.float64))


def write_pose_file(path: Path, utimes: np.ndarray, poses: np.ndarray) -> None:
    with path.open("w") as f:
        for u, p in zip(utimes, poses):
            f.write(json.dumps({"utime": int(u), "links": p.tolist()}) + "\n")


def cli_records(*args: str) -> List[Dict[str, Any]]:
    r = run_cli(*args, "--backend", "cpu")
    assert r.returncode == 0, r.stderr
    return [json.loads(line) for line in r.stdout.splitlines()]


@pytest.fixture(scope="session")
def walk(tmp_path_factory: pytest.TempPathFactory) -> Dict[str, Any]:
    """The CMU walk of tools/demo.sh in the apartment (86 samples at 30 Hz,
    meeting a table from pair 69), with rows made invalid in ways a
    pose file can say (a zero quaternion, a utime going back, a coordinate
    past 1e9 m), so the pairing rule is compared too."""
    out = tmp_path_factory.mktemp("walk")
    skel, poses_path = import_clip(out, "walk", "cmu_02_01_walk.bvh.gz", 0, (0, -1, 0.02),
                                   1000000)
    utimes, poses = read_pose_file(poses_path)
    poses[7, 3, 3:7] = 0.0  # Zero quaternion.
    utimes[12] = utimes[10]  # Not after the last valid pose.
    poses[20, 0, 0] = 2e9  # Past kMaxCoordinate.
    edited = out / "walk_edited.jsonl"
    write_pose_file(edited, utimes, poses)
    return {"dir": out, "skeleton": skel, "poses": edited, "utimes": utimes, "array": poses}


@pytest.fixture(scope="session")
def world_file(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """Two walkers crossing (one reversed along x) and a moving bunny."""
    out = tmp_path_factory.mktemp("world")
    import_clip(out, "a", "cmu_02_01_walk.bvh.gz", 120, (0, -1, 0.02), 1000000)
    import_clip(out, "b", "cmu_07_01_walk.bvh.gz", 120, (0.3, -0.8, 0.02), 1010000)
    with (out / "bunny.jsonl").open("w") as f:
        for k in range(12):
            f.write(json.dumps({"utime": 1000000 + 100000 * k,
                                "pose": [0.2 + 0.05 * k, -0.9, 0.8, 1, 0, 0, 0]}) + "\n")
    world = {"avatars": [{"id": "alice", "skeleton": "a.json", "poses": "a.jsonl"},
                         {"id": "bob", "skeleton": "b.json", "poses": "b.jsonl",
                          "motion": "independent"}],
             "objects": [{"id": "bunny", "mesh": BUNNY, "poses": "bunny.jsonl"}],
             "env": [APARTMENT]}
    path = out / "world.json"
    path.write_text(json.dumps(world))
    return path
