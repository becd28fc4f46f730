// World-frame capsule ends of a posed link (SPEC sections 1-3): a link frame
// at position p with orientation q ([w, x, y, z], normalised here) carries
// the segment ends a and b of its link frame to p + R(q) a and p + R(q) b.

import type { Quat, Vec3 } from "./protocol.js";

/** R(q) v with q normalised; a quaternion of norm < 1e-6 leaves v as it is. */
export function rotate(q: Quat, v: Vec3): Vec3 {
  let [w, x, y, z] = q;
  const n = Math.hypot(w, x, y, z);
  if (!(n >= 1e-6)) return [v[0], v[1], v[2]];
  w /= n;
  x /= n;
  y /= n;
  z /= n;
  // v + 2 w (u x v) + 2 u x (u x v), u = (x, y, z)
  const cx = y * v[2] - z * v[1];
  const cy = z * v[0] - x * v[2];
  const cz = x * v[1] - y * v[0];
  return [
    v[0] + 2 * (w * cx + (y * cz - z * cy)),
    v[1] + 2 * (w * cy + (z * cx - x * cz)),
    v[2] + 2 * (w * cz + (x * cy - y * cx)),
  ];
}

/** p + R(q) v */
export function transformPoint(p: Vec3, q: Quat, v: Vec3): Vec3 {
  const r = rotate(q, v);
  return [p[0] + r[0], p[1] + r[1], p[2] + r[2]];
}
