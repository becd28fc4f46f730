// Joint frames to link poses (docs/SKELETONS.md, "Joint frames"): the
// conversion of the C++ JointSkeleton::Convert (core/avatar/joint_frame.cc)
// for a skeleton that `sweptccd skeleton --from JOINT_SET` wrote, e.g. the
// WebXR sets (webxr-body, webxr-hand). No joint table is repeated here: each
// link's name says which joints bound it, as the C++ tables wrote it:
//   "A>B"    a bone from joint A to joint B;
//   "A>B~"   a fixed-length bone from A towards B;
//   "A>end"  an extension from A, along the direction from A's parent joint
//            (the first joint of the parent link, a bone "P>A") to A;
//   "A"      a sphere at A.
// Link i's frame: origin at joint A, +Y along the bone, twist A's orientation
// turned by the shortest arc taking A's +Y onto the bone (A's orientation for
// a sphere or coincident joints). A frame is refused (an error, no pose) when
// a joint some link uses is missing, not valid, non-finite, beyond 1e9 m or
// has a quaternion norm below 1e-6, or a bone's joints are farther from the
// skeleton's length than max(lengthToleranceM, lengthToleranceFraction x
// length). tests/web/joint_frames_match.mjs checks every conversion against
// `sweptccd skeleton --joints` on the same frames.

import type { Quat, Vec3 } from "./protocol.js";
import type { SkeletonFile } from "./skeleton.js";
import { rotate } from "./pose_math.js";

/** One joint of a frame, in the room's frame. */
export interface JointSample {
  position: Vec3;
  orientation: Quat; // [w, x, y, z]; normalised here.
  /** False when the runtime says the pose is not valid (default true). */
  valid?: boolean;
}

export type JointLinkKind = "bone" | "fixed" | "extension" | "sphere";

/** Which joints bound one link, read from its name. */
export interface JointLinkRule {
  name: string;
  kind: JointLinkKind;
  a: string;
  b?: string; // bone, fixed
  from?: string; // extension: A's parent joint
  length: number; // |b - a| of the link in the skeleton file
}

export interface JointFrameOptions {
  lengthToleranceM?: number; // default 0.01
  lengthToleranceFraction?: number; // default 0.05
}

/** The link rules of a skeleton written by `sweptccd skeleton`; throws on a
 * name that is not one of the four forms. */
export function jointRulesOf(skeleton: SkeletonFile): JointLinkRule[] {
  const byName = new Map(skeleton.links.map((l) => [l.name, l]));
  return skeleton.links.map((l, i) => {
    const d = [0, 1, 2].map((k) => l.b[k] - l.a[k]);
    const length = Math.hypot(d[0], d[1], d[2]);
    const parts = l.name.split(">");
    if (parts.length === 1) return { name: l.name, kind: "sphere", a: l.name, length };
    if (parts.length !== 2 || parts[0] === "") throw new Error(`link ${i} (${l.name}): not a joint-set link`);
    const [a, rest] = parts;
    if (rest === "end") {
      const parent = l.parent === null ? undefined : byName.get(l.parent);
      const pp = parent?.name.split(">");
      if (!pp || pp.length !== 2 || pp[1] !== a) {
        throw new Error(`link ${i} (${l.name}): an extension needs a parent bone ending at ${a}`);
      }
      return { name: l.name, kind: "extension", a, from: pp[0], length };
    }
    if (rest.endsWith("~")) return { name: l.name, kind: "fixed", a, b: rest.slice(0, -1), length };
    return { name: l.name, kind: "bone", a, b: rest, length };
  });
}

function jointProblem(s: JointSample | null | undefined): string {
  if (!s || s.valid === false) return "not tracked (null or valid: false)";
  if (!Array.isArray(s.position) || s.position.length !== 3) return "no position";
  for (const v of s.position) {
    if (typeof v !== "number" || !Number.isFinite(v)) return "non-finite position";
    if (Math.abs(v) > 1e9) return "position beyond 1e9 m";
  }
  if (!Array.isArray(s.orientation) || s.orientation.length !== 4) return "no quaternion";
  for (const v of s.orientation) {
    if (typeof v !== "number" || !Number.isFinite(v)) return "non-finite quaternion";
  }
  const n = Math.hypot(...s.orientation);
  if (!(n >= 1e-6)) return "quaternion norm below 1e-6";
  return "";
}

function normalise(q: Quat): Quat {
  const n = Math.hypot(q[0], q[1], q[2], q[3]);
  return [q[0] / n, q[1] / n, q[2] / n, q[3] / n];
}

function multiply(p: Quat, q: Quat): Quat {
  return [
    p[0] * q[0] - p[1] * q[1] - p[2] * q[2] - p[3] * q[3],
    p[0] * q[1] + p[1] * q[0] + p[2] * q[3] - p[3] * q[2],
    p[0] * q[2] - p[1] * q[3] + p[2] * q[0] + p[3] * q[1],
    p[0] * q[3] + p[1] * q[2] - p[2] * q[1] + p[3] * q[0],
  ];
}

// The shortest-arc rotation taking unit u onto unit v (Eigen's
// FromTwoVectors; at exactly opposite vectors, a half turn about an axis
// perpendicular to u, which Eigen may choose differently: the segment is the
// same, the twist about the bone may differ).
function fromTwoVectors(u: Vec3, v: Vec3): Quat {
  const c = u[0] * v[0] + u[1] * v[1] + u[2] * v[2];
  if (c < -1 + 1e-15) {
    const t: Vec3 = Math.abs(u[0]) < 0.9 ? [1, 0, 0] : [0, 1, 0];
    const ax: Vec3 = [u[1] * t[2] - u[2] * t[1], u[2] * t[0] - u[0] * t[2], u[0] * t[1] - u[1] * t[0]];
    const n = Math.hypot(...ax);
    return [0, ax[0] / n, ax[1] / n, ax[2] / n];
  }
  const axis: Vec3 = [u[1] * v[2] - u[2] * v[1], u[2] * v[0] - u[0] * v[2], u[0] * v[1] - u[1] * v[0]];
  const s = Math.sqrt((1 + c) * 2);
  return [0.5 * s, axis[0] / s, axis[1] / s, axis[2] / s];
}

/**
 * One frame's link poses ([position, orientation] per link, in the
 * skeleton's order: a SPEC section 2 pose line's `links`), or the reason the
 * frame is refused. `joints` maps a joint name (the joint set's, e.g. WebXR's
 * "left-hand-wrist") to its sample, or null when not tracked.
 */
export function jointFrameToLinks(
  rules: JointLinkRule[],
  joints: Map<string, JointSample | null>,
  options: JointFrameOptions = {},
): { links: [Vec3, Quat][] } | { error: string } {
  const tolM = options.lengthToleranceM ?? 0.01;
  const tolF = options.lengthToleranceFraction ?? 0.05;
  for (const r of rules) {
    for (const j of [r.a, r.b, r.from]) {
      if (j === undefined) continue;
      const p = jointProblem(joints.get(j));
      if (p) return { error: `joint ${j}: ${p}` };
    }
  }
  const links: [Vec3, Quat][] = [];
  for (let i = 0; i < rules.length; ++i) {
    const r = rules[i];
    const a = joints.get(r.a) as JointSample;
    const qa = normalise(a.orientation);
    let bone: Vec3 = [0, 0, 0];
    if (r.b !== undefined) {
      const b = (joints.get(r.b) as JointSample).position;
      bone = [b[0] - a.position[0], b[1] - a.position[1], b[2] - a.position[2]];
    } else if (r.from !== undefined) {
      const f = (joints.get(r.from) as JointSample).position;
      bone = [a.position[0] - f[0], a.position[1] - f[1], a.position[2] - f[2]];
    }
    const len = Math.hypot(bone[0], bone[1], bone[2]);
    if (r.kind === "bone") {
      const tol = Math.max(tolM, tolF * r.length);
      if (!(Math.abs(len - r.length) <= tol)) {
        return {
          error:
            `link ${i} (${r.name}): joints ${len.toFixed(4)} m apart, the skeleton's bone is ` +
            `${r.length.toFixed(4)} m (tolerance ${tol.toFixed(4)} m)`,
        };
      }
    }
    let q = qa;
    if (len > 1e-9 && r.kind !== "sphere") {
      const axis = rotate(qa, [0, 1, 0]);
      const an = Math.hypot(axis[0], axis[1], axis[2]);
      const from: Vec3 = [axis[0] / an, axis[1] / an, axis[2] / an];
      const to: Vec3 = [bone[0] / len, bone[1] / len, bone[2] / len];
      q = multiply(fromTwoVectors(from, to), qa);
    }
    links.push([[a.position[0], a.position[1], a.position[2]], normalise(q)]);
  }
  return { links };
}
