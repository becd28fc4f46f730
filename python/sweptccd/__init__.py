"""SweptCCD from Python: certified continuous collision detection of capsule
skeletons (SPEC.md), the offline engine of `sweptccd query` and `sweptccd
world` without a process per call. See docs/PYTHON.md.

    import numpy as np, sweptccd
    engine = sweptccd.Engine("skeleton.json", ["room.ply.gz"])
    records = engine.query(utimes, poses)   # int64 (N,), float64 (N, links, 7)
"""

from __future__ import annotations

import json
import os
from typing import Any, Dict, Iterable, List, Mapping, Optional, Sequence, Union

import numpy as np
import numpy.typing as npt

from . import _sweptccd
from ._records import (Contact, LinkBracket, Other, OtherContact, OtherLinkBracket, Record)

__all__ = ["Engine", "World", "JointSkeleton", "InputError", "Record", "Contact", "LinkBracket", "Other",
           "OtherContact", "OtherLinkBracket"]

#: Raised when an input cannot be used; the message is the one line
#: `sweptccd query` / `sweptccd world` prints after "error: ". A ValueError.
InputError = _sweptccd.InputError

PathLike = Union[str, "os.PathLike[str]"]


def _path(p: PathLike) -> str:
    return os.fspath(p)


def _optional_int(v: Optional[int]) -> Optional[int]:
    return None if v is None else int(v)


def _float64_poses(poses: npt.ArrayLike) -> npt.NDArray[np.float64]:
    a = np.asarray(poses)
    if a.dtype.kind not in "fiu":
        raise TypeError(f"poses must be a numeric array, got dtype {a.dtype}")
    return np.ascontiguousarray(a, dtype=np.float64)


def _int64_utimes(utimes: npt.ArrayLike) -> npt.NDArray[np.int64]:
    a = np.asarray(utimes)
    if a.dtype.kind in "iu":
        return np.ascontiguousarray(a, dtype=np.int64)
    if a.dtype.kind == "f" and bool(np.all(np.isfinite(a))) and bool(np.all(a == np.round(a))):
        return np.ascontiguousarray(a, dtype=np.int64)  # 1000000.0 is accepted, as in a file.
    raise TypeError("utimes must be integer microseconds (int64), got dtype "
                    f"{a.dtype} with non-integral values" if a.dtype.kind == "f"
                    else f"utimes must be integer microseconds (int64), got dtype {a.dtype}")


class Engine:
    """A skeleton, an environment and filters, loaded once; answers pose pairs.

    skeleton: a SPEC 1 skeleton file, or the same document as a dict.
    env: one or more mesh files (SPEC 4); object i is env[i] (one path: one object).
    filter: a filter file as `sweptccd query --filter`; ignore: LINK:OBJECT
    rules as `--ignore`. motion, eps, delta, per_link, max_intervals: as the
    command's flags (--motion, --eps, --delta, --per-link, --max-intervals;
    None: the command's default).

    Thread-safe: query() releases the GIL, and several threads may query one
    engine at once.
    """

    def __init__(self, skeleton: Union[PathLike, Mapping[str, Any]],
                 env: Union[PathLike, Sequence[PathLike]], *,
                 filter: Optional[PathLike] = None, ignore: Iterable[str] = (),
                 motion: str = "articulated", eps: float = 1e-4, delta: float = 1e-3,
                 per_link: bool = False, max_intervals: Optional[int] = None) -> None:
        envs: List[PathLike] = [env] if isinstance(env, (str, os.PathLike)) else list(env)
        if isinstance(skeleton, Mapping):
            skel_path, skel_json = None, json.dumps(skeleton, allow_nan=True)
        else:
            skel_path, skel_json = _path(skeleton), None
        self._engine = _sweptccd.Engine(
            skel_path, skel_json, [_path(e) for e in envs],
            "" if filter is None else _path(filter), list(ignore), motion, float(eps),
            float(delta), bool(per_link), _optional_int(max_intervals))
        self.per_link = bool(per_link)

    @property
    def num_links(self) -> int:
        return self._engine.num_links

    @property
    def link_names(self) -> List[str]:
        return self._engine.link_names

    @property
    def num_objects(self) -> int:
        return self._engine.num_objects

    @property
    def num_triangles(self) -> int:
        return self._engine.num_triangles

    def query_json(self, utimes: npt.ArrayLike, poses: npt.ArrayLike) -> List[str]:
        """As query(), each record as the JSON line `sweptccd query` writes."""
        return self._engine.query(_int64_utimes(utimes), _float64_poses(poses))

    def query(self, utimes: npt.ArrayLike, poses: npt.ArrayLike) -> List[Record]:
        """Answers a pose stream: poses[r] (links x 7: px py pz qw qx qy qz,
        world frame) at utimes[r] microseconds, rows as the lines of a SPEC 2
        pose file. Returns one Record per row after the first (pair r - 1 for
        row r), exactly as `sweptccd query` on that file: an invalid row (NaN,
        zero quaternion, a utime not after the last valid one) gives an
        `invalid` record naming "line r + 1", it is not an exception.
        Raises ValueError/TypeError for arrays of the wrong shape or type."""
        return [Record.from_json(line) for line in self.query_json(utimes, poses)]

    def separations(self, poses: npt.ArrayLike, search_radius: float = 1.0
                    ) -> npt.NDArray[np.float64]:
        """The separation (SPEC 5: distance to the nearest unfiltered triangle
        minus the radius, negative inside) of every link at each pose, shape
        (N, links): +inf where nothing is within search_radius metres of the
        capsule, NaN for an invalid pose."""
        return self._engine.separations(_float64_poses(poses), float(search_radius))


class World:
    """A shared world file (SPEC 8, as `sweptccd world --world PATH`), loaded
    once. records() answers every avatar pair."""

    def __init__(self, path: PathLike, *, eps: float = 1e-4, delta: float = 1e-3,
                 per_link: bool = False, max_intervals: Optional[int] = None) -> None:
        self._world = _sweptccd.World(_path(path), float(eps), float(delta), bool(per_link),
                                      _optional_int(max_intervals))

    @property
    def avatar_ids(self) -> List[str]:
        return self._world.avatar_ids

    def records_json(self) -> List[str]:
        """As records(), each as the JSON line `sweptccd world` writes."""
        return self._world.records()

    def records(self) -> List[Record]:
        """One Record per avatar pair, per avatar in world-file order, each in
        pair order; `avatar` and `others` set."""
        return [Record.from_json(line) for line in self.records_json()]


class JointSkeleton:
    """A tracking runtime's joint set as a SPEC 1 skeleton, and the
    conversion of its joint frames to link poses (docs/SKELETONS.md): the C++
    rule of `sweptccd skeleton --from JOINT_SET` and of the C++ client's
    PublishJointFrame, so a frame converts to the same link poses everywhere.

    joint_set: an id `sweptccd skeleton --from` takes (meta-full-body,
    fb-body, webxr-body, htc-body, bd-body, ext-hand, webxr-hand,
    vrm-humanoid). height (metres, 0.5..2.5) scales the default lengths and
    radii; hands: "none", "simple" or "full". calibration: one joint frame
    (a joint frame line of docs/SKELETONS.md, as a string or the same
    document as a dict) whose joint distances set the bone lengths and, for
    sets with runtime radii, the radii. length_tolerance: metres a frame's
    bone may differ from the skeleton's (or 5 %, whichever is larger).
    Raises InputError with the command's one line for a bad argument.
    """

    def __init__(self, joint_set: str, *, height: float = 1.75, hands: str = "full",
                 calibration: Optional[Union[str, Mapping[str, Any]]] = None,
                 length_tolerance: float = 0.01) -> None:
        line = (json.dumps(calibration, allow_nan=True) if isinstance(calibration, Mapping)
                else calibration)
        self.joint_set = joint_set
        self._joints = _sweptccd.JointSkeleton(joint_set, float(height), hands, line,
                                               float(length_tolerance))

    @property
    def num_joints(self) -> int:
        return self._joints.num_joints

    @property
    def num_links(self) -> int:
        return self._joints.num_links

    @property
    def joint_names(self) -> List[str]:
        """The specification's joint identifiers, in its order."""
        return self._joints.joint_names

    @property
    def skeleton(self) -> Dict[str, Any]:
        """The SPEC 1 skeleton (what `sweptccd skeleton --out` writes), as a
        dict: give it to Engine, or to LiveClient as its skeleton."""
        doc: Dict[str, Any] = json.loads(self._joints.skeleton_json())
        return doc

    def convert(self, joints: npt.ArrayLike, valid: Optional[Sequence[bool]] = None,
                utime: int = 0) -> npt.NDArray[np.float64]:
        """One frame of joint poses, (num_joints, 7) rows [px, py, pz, qw, qx,
        qy, qz] in the joint set's order, to link poses, (num_links, 7) in the
        same layout (a row of Engine.query's poses, of publish_pose7).
        valid: one flag per joint, False where the runtime says the joint is
        not tracked or not valid (OpenXR's location flags, WebXR's missing
        pose); joints no link uses are never looked at. Raises InputError
        with the one-line reason when the frame cannot be converted (a joint
        a link needs not valid, NaN or out of range, a zero quaternion, a
        bone off its length), ValueError for arrays of the wrong shape."""
        flags = None if valid is None else [bool(v) for v in valid]
        rows = np.ascontiguousarray(joints, dtype=np.float64)
        return self._joints.convert(rows, flags, int(utime))
