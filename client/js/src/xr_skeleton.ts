// The WebXR pose source's skeleton (client/js/README.md, "WebXR"): a
// headset's tracked parts become capsule links of one SweptCCD skeleton,
// built once from the first complete frame, then every frame becomes one
// pose. No DOM here: the page (xr/xr_page.ts) reads the XRFrame and hands
// over an XrSnapshot in the room's frame; tests feed snapshots directly.
//
// Links (all of them frames of tracked things, so motion is INDEPENDENT):
//   head                 root; the viewer pose; a capsule from 4 cm behind
//                        the eyes down to the chin (radius 0.11)
//   controller_left/right  grip space; a capsule along its -z, 15 cm (r 0.04)
//   left_<joint>, right_<joint>  the 25 joints of WebXR hand input, each a
//                        capsule from the joint to the next joint of its finger
//                        (as measured in the first frame, in the joint's frame),
//                        a sphere for the tips; the wrist's reaches the middle
//                        finger's knuckle (the palm); radius: the runtime's
//                        joint radius of that first frame
//   body_<joint>         body tracking where offered (XRBody): a capsule to
//                        the next joint of its chain (radius 0.05-0.10)
// Parents: head is the root; controllers, wrists and the body's hips hang
// from it; finger joints from the joint before them.
// A part that is not tracked in a later frame keeps its last pose.

import type { Quat, Vec3 } from "./protocol.js";
import type { SkeletonFile } from "./skeleton.js";
import { rotate } from "./pose_math.js";

export interface RigidPose {
  position: Vec3;
  orientation: Quat;
}
export interface JointPose extends RigidPose {
  radius: number;
}

/** One frame of what the headset tracks, in the room's frame. */
export interface XrSnapshot {
  head: RigidPose | null;
  controllers: { left?: RigidPose; right?: RigidPose };
  hands: { left?: Map<string, JointPose>; right?: Map<string, JointPose> };
  body?: Map<string, RigidPose>;
}

const FINGERS: [string, string[]][] = [
  ["thumb", ["metacarpal", "phalanx-proximal", "phalanx-distal", "tip"]],
  ["index-finger", ["metacarpal", "phalanx-proximal", "phalanx-intermediate", "phalanx-distal", "tip"]],
  ["middle-finger", ["metacarpal", "phalanx-proximal", "phalanx-intermediate", "phalanx-distal", "tip"]],
  ["ring-finger", ["metacarpal", "phalanx-proximal", "phalanx-intermediate", "phalanx-distal", "tip"]],
  ["pinky-finger", ["metacarpal", "phalanx-proximal", "phalanx-intermediate", "phalanx-distal", "tip"]],
];
/** The 25 joints of WebXR hand input, in the spec's order. */
export const HAND_JOINTS: string[] = ["wrist", ...FINGERS.flatMap(([f, js]) => js.map((j) => `${f}-${j}`))];

/** Body chains (XRBody joint names, Meta's body tracking) with their radii. */
const BODY_CHAINS: [string[], number][] = [
  [["hips", "spine-lower", "spine-middle", "spine-upper", "chest", "neck", "head"], 0.1],
  [["left-shoulder", "left-arm-upper", "left-arm-lower", "left-hand-wrist"], 0.05],
  [["right-shoulder", "right-arm-upper", "right-arm-lower", "right-hand-wrist"], 0.05],
];

/** Where a link's pose comes from. */
export type LinkSource =
  | { kind: "head" }
  | { kind: "controller"; side: "left" | "right" }
  | { kind: "hand"; side: "left" | "right"; joint: string }
  | { kind: "body"; joint: string };

export interface XrSkeleton {
  skeleton: SkeletonFile;
  sources: LinkSource[];
}

function sub(a: Vec3, b: Vec3): Vec3 {
  return [a[0] - b[0], a[1] - b[1], a[2] - b[2]];
}
function conj(q: Quat): Quat {
  return [q[0], -q[1], -q[2], -q[3]];
}
/** The vector from `from` to `to` in the frame of `from`. */
function inFrame(from: RigidPose, to: Vec3): Vec3 {
  return rotate(conj(from.orientation), sub(to, from.position));
}

/** The skeleton of what `first` tracks (head required). */
export function buildXrSkeleton(first: XrSnapshot): XrSkeleton {
  if (!first.head) throw new Error("xr skeleton: no head pose yet");
  const links: SkeletonFile["links"] = [];
  const sources: LinkSource[] = [];
  const add = (name: string, parent: string | null, a: Vec3, b: Vec3, radius: number, source: LinkSource) => {
    links.push({ name, parent, a, b, radius });
    sources.push(source);
  };
  add("head", null, [0, 0.02, 0.04], [0, -0.12, 0.02], 0.11, { kind: "head" });
  for (const side of ["left", "right"] as const) {
    if (first.controllers[side]) add(`controller_${side}`, "head", [0, 0, 0.03], [0, 0, -0.12], 0.04, { kind: "controller", side });
  }
  for (const side of ["left", "right"] as const) {
    const hand = first.hands[side];
    if (!hand || !HAND_JOINTS.every((j) => hand.has(j))) continue;
    const j = (name: string) => hand.get(name)!;
    const wrist = j("wrist");
    add(`${side}_wrist`, "head", [0, 0, 0], inFrame(wrist, j("middle-finger-phalanx-proximal").position), wrist.radius, { kind: "hand", side, joint: "wrist" });
    for (const [finger, joints] of FINGERS) {
      joints.forEach((joint, i) => {
        const name = `${finger}-${joint}`;
        const pose = j(name);
        const next = joints[i + 1];
        const b: Vec3 = next ? inFrame(pose, j(`${finger}-${next}`).position) : [0, 0, 0];
        const parent = i === 0 ? `${side}_wrist` : `${side}_${finger}-${joints[i - 1]}`;
        add(`${side}_${name}`, parent, [0, 0, 0], b, pose.radius, { kind: "hand", side, joint: name });
      });
    }
  }
  if (first.body) {
    const body = first.body;
    for (const [chain, radius] of BODY_CHAINS) {
      chain.forEach((joint, i) => {
        const pose = body.get(joint);
        if (!pose) return;
        const next = chain[i + 1] ? body.get(chain[i + 1]) : undefined;
        const prev = chain.slice(0, i).reverse().find((p) => body.has(p));
        const parent = prev ? `body_${prev}` : "head";
        add(`body_${joint}`, parent, [0, 0, 0], next ? inFrame(pose, next.position) : [0, 0, 0], radius, { kind: "body", joint });
      });
    }
  }
  return { skeleton: { name: "webxr", links }, sources };
}

function lookup(s: XrSnapshot, src: LinkSource): RigidPose | undefined {
  switch (src.kind) {
    case "head":
      return s.head ?? undefined;
    case "controller":
      return s.controllers[src.side];
    case "hand":
      return s.hands[src.side]?.get(src.joint);
    case "body":
      return s.body?.get(src.joint);
  }
}

/**
 * One pose of every link from `snapshot`; a link whose part is not tracked
 * keeps its pose in `last` (null when there is none yet: the caller waits).
 */
export function xrSample(sk: XrSkeleton, snapshot: XrSnapshot, last: RigidPose[] | null): RigidPose[] | null {
  const out: RigidPose[] = [];
  for (let i = 0; i < sk.sources.length; i++) {
    const p = lookup(snapshot, sk.sources[i]) ?? last?.[i];
    if (!p) return null;
    out.push({ position: [...p.position] as Vec3, orientation: [...p.orientation] as Quat });
  }
  return out;
}

/** Hamilton product a * b of [w, x, y, z] quaternions. */
export function quatMultiply(a: Quat, b: Quat): Quat {
  return [
    a[0] * b[0] - a[1] * b[1] - a[2] * b[2] - a[3] * b[3],
    a[0] * b[1] + a[1] * b[0] + a[2] * b[3] - a[3] * b[2],
    a[0] * b[2] - a[1] * b[3] + a[2] * b[0] + a[3] * b[1],
    a[0] * b[3] + a[1] * b[2] - a[2] * b[1] + a[3] * b[0],
  ];
}

/**
 * WebXR's reference space (y up, metres) into the room's frame (z up):
 * a quarter turn about x, then `yaw` radians about the room's z, then
 * `origin` (where the reference space's floor origin stands in the room).
 */
export function xrToRoom(pose: RigidPose, origin: Vec3 = [0, 0, 0], yaw = 0): RigidPose {
  const up: Quat = [Math.SQRT1_2, Math.SQRT1_2, 0, 0];
  const turn: Quat = [Math.cos(yaw / 2), 0, 0, Math.sin(yaw / 2)];
  const q = quatMultiply(turn, up);
  const p = rotate(q, pose.position);
  return { position: [p[0] + origin[0], p[1] + origin[1], p[2] + origin[2]], orientation: quatMultiply(q, pose.orientation) };
}
