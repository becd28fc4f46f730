// SPEC section 1 skeletons and section 2 pose lines, as the arrays of the
// protocol's join_request and tracker_pose.

import type { Quat, SkeletonArrays, Vec3 } from "./protocol.js";

/** A skeleton file (SPEC section 1). */
export interface SkeletonFile {
  name?: string;
  links: { name: string; parent: string | null; a: number[]; b: number[]; radius: number }[];
}

function vec3(v: unknown, where: string): Vec3 {
  if (!Array.isArray(v) || v.length !== 3 || !v.every((x) => typeof x === "number" && Number.isFinite(x))) {
    throw new Error(`${where}: not 3 finite numbers`);
  }
  return [v[0], v[1], v[2]];
}

/**
 * The join arrays of a SPEC skeleton; throws naming the link and the problem
 * (unknown parent, two roots, a loop, radius <= 0, non-finite, duplicates).
 */
export function skeletonToArrays(skeleton: SkeletonFile): SkeletonArrays {
  if (!skeleton || !Array.isArray(skeleton.links) || skeleton.links.length === 0) {
    throw new Error("skeleton: no links");
  }
  const index = new Map<string, number>();
  skeleton.links.forEach((l, i) => {
    if (typeof l.name !== "string" || l.name === "") throw new Error(`skeleton: link ${i} has no name`);
    if (index.has(l.name)) throw new Error(`skeleton: duplicate link name "${l.name}"`);
    index.set(l.name, i);
  });
  const out: SkeletonArrays = { link_name: [], parent: [], a: [], b: [], radius: [] };
  let roots = 0;
  for (const l of skeleton.links) {
    let p = -1;
    if (l.parent === null || l.parent === undefined) {
      roots++;
    } else {
      const q = index.get(l.parent);
      if (q === undefined) throw new Error(`skeleton: link "${l.name}" has unknown parent "${l.parent}"`);
      p = q;
    }
    if (typeof l.radius !== "number" || !Number.isFinite(l.radius) || l.radius <= 0) {
      throw new Error(`skeleton: link "${l.name}" radius must be > 0`);
    }
    out.link_name.push(l.name);
    out.parent.push(p);
    out.a.push(vec3(l.a, `skeleton: link "${l.name}" a`));
    out.b.push(vec3(l.b, `skeleton: link "${l.name}" b`));
    out.radius.push(l.radius);
  }
  if (roots !== 1) throw new Error(`skeleton: ${roots} roots, need exactly one`);
  // Loops: walking up from any link must reach the root in < n steps.
  for (let i = 0; i < out.parent.length; i++) {
    let j = i;
    for (let steps = 0; j !== -1; steps++) {
      if (steps > out.parent.length) throw new Error(`skeleton: link "${out.link_name[i]}" is in a loop`);
      j = out.parent[j];
    }
  }
  return out;
}

/** One pose line (SPEC section 2) as tracker_pose arrays. */
export interface PoseSample {
  utime: number;
  position: Vec3[];
  orientation: Quat[];
}

/** A SPEC section 2 pose object ({"utime", "links": [[px,py,pz,qw,qx,qy,qz], ...]}). */
export function poseLineToSample(line: { utime: number; links: number[][] }): PoseSample {
  if (!line || typeof line.utime !== "number" || !Array.isArray(line.links)) throw new Error("pose: needs utime and links");
  const position: Vec3[] = [];
  const orientation: Quat[] = [];
  for (const l of line.links) {
    if (!Array.isArray(l) || l.length !== 7) throw new Error("pose: each link is [px,py,pz,qw,qx,qy,qz]");
    position.push([l[0], l[1], l[2]]);
    orientation.push([l[3], l[4], l[5], l[6]]);
  }
  return { utime: line.utime, position, orientation };
}

/** Parses JSON Lines of SPEC section 2 poses (blank lines skipped). */
export function parsePoseLines(text: string): PoseSample[] {
  const out: PoseSample[] = [];
  for (const raw of text.split("\n")) {
    const line = raw.trim();
    if (line === "") continue;
    out.push(poseLineToSample(JSON.parse(line)));
  }
  return out;
}
