"""sweptccd.JointSkeleton against `sweptccd skeleton` (the command and the
Python class call the same C++ rule, JointSkeleton::Build and ::Convert):
the same skeleton for every joint set and hands option, and on seeded joint
frames the same link poses, the same frames refused with the same one-line
reason; bad arguments raise the command's message."""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any, Dict, List, Optional, Tuple

import numpy as np
import pytest

import sweptccd
from conftest import run_cli

SETS = ["meta-full-body", "fb-body", "webxr-body", "htc-body", "bd-body", "ext-hand",
        "webxr-hand", "vrm-humanoid"]


def unit_quat(rng: np.random.Generator) -> np.ndarray:
    q = rng.normal(size=4)
    return np.asarray(q / np.linalg.norm(q))


def rotation(q: np.ndarray) -> np.ndarray:
    w, x, y, z = q
    return np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
                     [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
                     [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)]])


def frame_line(utime: int, rows: np.ndarray, valid: Optional[List[bool]] = None) -> str:
    joints: List[Any] = [[float(v) for v in r] for r in rows]
    doc: Dict[str, Any] = {"utime": utime, "joints": joints}
    if valid is not None:
        doc["valid"] = valid
    return json.dumps(doc, allow_nan=True)


def used_joints(js: sweptccd.JointSkeleton) -> List[int]:
    """Joints that bound a link, read from the link names ("A>B", "A>B~",
    "A>end", "A": docs/SKELETONS.md)."""
    names = set()
    for link in js.skeleton["links"]:
        for part in link["name"].rstrip("~").split(">"):
            names.add(part)
    return [j for j, n in enumerate(js.joint_names) if n in names]


def frames(num_joints: int, seed: int, used: Optional[List[int]] = None
           ) -> Tuple[np.ndarray, List[Tuple[np.ndarray, List[bool]]]]:
    """A calibration frame (joints scattered in a 1 m box) and 24 frames:
    rigid motions of it with new joint orientations (every bone keeps its
    length: converted), and among them frames the rule refuses: a joint
    (of `used`, in the first 12 frames) not valid, a coordinate 1e12 m away, a zero quaternion, a joint moved 0.3 m (a bone off its
    length). A refused frame is one whose joint some link uses; the same
    change to a joint no link uses is converted: both answers are checked."""
    rng = np.random.default_rng(seed)
    cal = np.zeros((num_joints, 7))
    cal[:, :3] = rng.uniform(-0.5, 0.5, size=(num_joints, 3))
    for j in range(num_joints):
        cal[j, 3:] = unit_quat(rng)
    out: List[Tuple[np.ndarray, List[bool]]] = []
    for k in range(24):
        r = rotation(unit_quat(rng))
        t = rng.uniform(-2, 2, size=3)
        f = np.zeros_like(cal)
        f[:, :3] = cal[:, :3] @ r.T + t
        for j in range(num_joints):
            f[j, 3:] = unit_quat(rng)
        valid = [True] * num_joints
        j = int(rng.integers(num_joints))
        if used and k < 12:
            j = used[int(rng.integers(len(used)))]
        kind = k % 6
        if kind == 1:
            valid[j] = False
        elif kind == 2:
            f[j, int(rng.integers(3))] = 1e12  # Out of range (JSON has no NaN: below).
        elif kind == 3:
            f[j, 3:] = 0.0
        elif kind == 4:
            f[j, :3] += 0.3 * unit_quat(rng)[:3] / np.linalg.norm(unit_quat(rng)[:3])
        out.append((f, valid))
    return cal, out


def command_poses(tmp: Path, joint_set: str, hands: str, cal_line: str,
                  lines: List[str]) -> List[Dict[str, Any]]:
    (tmp / "cal.jsonl").write_text(cal_line + "\n")
    (tmp / "frames.jsonl").write_text("\n".join(lines) + "\n")
    r = run_cli("skeleton", "--from", joint_set, "--hands", hands, "--calibrate",
                str(tmp / "cal.jsonl"), "--out", str(tmp / "skeleton.json"), "--joints",
                str(tmp / "frames.jsonl"), "--poses-out", str(tmp / "poses.jsonl"))
    assert r.returncode == 0, r.stderr
    return [json.loads(line) for line in (tmp / "poses.jsonl").read_text().splitlines()]


@pytest.mark.parametrize("joint_set", SETS)
@pytest.mark.parametrize("hands", ["full", "simple"])
def test_frames_equal_the_command(joint_set: str, hands: str, tmp_path: Path) -> None:
    if hands == "simple" and joint_set in ("ext-hand", "webxr-hand"):
        hands = "full"  # A hand-only set has no simpler hand.
    plain = sweptccd.JointSkeleton(joint_set, hands=hands)
    num_joints = plain.num_joints
    seed = 1000 + SETS.index(joint_set) * 7 + (hands == "full")
    cal, fs = frames(num_joints, seed, used_joints(plain))
    cal_line = frame_line(0, cal)
    js = sweptccd.JointSkeleton(joint_set, hands=hands, calibration=cal_line)
    assert js.num_joints == num_joints and len(js.joint_names) == num_joints
    ref = command_poses(tmp_path, joint_set, hands, cal_line,
                        [frame_line(1000 * (k + 1), f, v) for k, (f, v) in enumerate(fs)])
    assert js.skeleton == json.loads((tmp_path / "skeleton.json").read_text())
    assert js.num_links == len(js.skeleton["links"])
    converted = refused = 0
    for k, ((f, v), want) in enumerate(zip(fs, ref)):
        if "invalid" in want:
            with pytest.raises(sweptccd.InputError) as e:
                js.convert(f, v, utime=1000 * (k + 1))
            assert want["invalid"] == f"line {k + 1}: {e.value}", (k, want, str(e.value))
            refused += 1
        else:
            got = js.convert(f, v, utime=1000 * (k + 1))
            assert got.shape == (js.num_links, 7)
            np.testing.assert_allclose(got, np.array(want["links"]), rtol=0, atol=1e-12)
            converted += 1
    # Both answers happen in every set: the comparison can fail either way.
    assert converted >= 4 and refused >= 6, (converted, refused)


def test_calibration_as_a_dict_equals_the_line() -> None:
    cal, _ = frames(26, 5)
    line = frame_line(0, cal)
    a = sweptccd.JointSkeleton("ext-hand", calibration=line)
    b = sweptccd.JointSkeleton("ext-hand", calibration=json.loads(line))
    assert a.skeleton == b.skeleton
    assert a.skeleton != sweptccd.JointSkeleton("ext-hand").skeleton


def test_height_scales_the_default_skeleton(tmp_path: Path) -> None:
    js = sweptccd.JointSkeleton("htc-body", height=1.5, hands="none")
    r = run_cli("skeleton", "--from", "htc-body", "--height", "1.5", "--hands", "none", "--out",
                str(tmp_path / "s.json"))
    assert r.returncode == 0, r.stderr
    assert js.skeleton == json.loads((tmp_path / "s.json").read_text())


@pytest.mark.parametrize("args,flags", [
    ({"joint_set": "htc-body", "height": 3.0}, ["--from", "htc-body", "--height", "3.0"]),
    ({"joint_set": "webxr-hand", "hands": "none"}, ["--from", "webxr-hand", "--hands", "none"]),
])
def test_bad_arguments_raise_the_commands_message(args: Dict[str, Any], flags: List[str],
                                                  tmp_path: Path) -> None:
    with pytest.raises(sweptccd.InputError) as e:
        sweptccd.JointSkeleton(**args)
    r = run_cli("skeleton", *flags, "--out", str(tmp_path / "s.json"))
    assert r.returncode == 2 and r.stderr == f"error: {e.value}\n", (str(e.value), r.stderr)


def test_unknown_joint_set_names_the_known_ones() -> None:
    with pytest.raises(sweptccd.InputError) as e:
        sweptccd.JointSkeleton("no-such-set")
    assert "'no-such-set'" in str(e.value)
    for known in SETS:
        assert known in str(e.value)


def test_bad_calibration_and_shapes() -> None:
    with pytest.raises(sweptccd.InputError, match="calibration: "):
        sweptccd.JointSkeleton("webxr-hand", calibration='{"utime": 0, "joints": [null]}')
    with pytest.raises(sweptccd.InputError, match="calibration: longer than the cap"):
        sweptccd.JointSkeleton("webxr-hand", calibration=" " * 10_000_000)
    js = sweptccd.JointSkeleton("webxr-hand")
    with pytest.raises(ValueError, match=r"joints must have shape \(25, 7\)"):
        js.convert(np.zeros((24, 7)))
    with pytest.raises(ValueError, match="valid must have 25 flags, got 3"):
        js.convert(np.zeros((25, 7)), [True, True, False])
    # A refused frame leaves the object usable.
    cal, fs = frames(25, 9)
    js = sweptccd.JointSkeleton("webxr-hand", calibration=frame_line(0, cal))
    assert js.convert(fs[0][0]).shape == (js.num_links, 7)


def test_nan_refused_with_one_line() -> None:
    cal, fs = frames(26, 11)
    js = sweptccd.JointSkeleton("ext-hand", calibration=frame_line(0, cal))
    f = fs[0][0].copy()
    f[3, 1] = math.nan
    with pytest.raises(sweptccd.InputError, match=r"^joint 3 \(.*\): non-finite position$"):
        js.convert(f)
    f = fs[0][0].copy()
    f[3, 4] = math.nan
    with pytest.raises(sweptccd.InputError, match=r"^joint 3 \(.*\): "):
        js.convert(f)
