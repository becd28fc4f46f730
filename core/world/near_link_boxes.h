#pragma once
// Internal to the entity engine (docs/DESIGN.md, section 5a, "Near boxes"):
// per-link boxes of an avatar over one motion that hold the link's swept
// volume itself, not the descent's bounds of it, grown by a margin. The
// descent's bounds (and LinkSweepBoxes, which must hold them) compose the
// certified speed bounds down the chain, parent's angular speed plus the
// link's own: a parent link that twists fast about its bone axis while its
// child twists back (the 81-link `meta-full-body` legs of the hands scenario
// turn up to 2.3 rad about the thigh between two samples while no point
// moves a millimetre) gives its descendants a growth of metres over a whole
// sample interval. Halving the interval where the growth is large brings
// the bound back to the size of the motion (the growth over a half is at
// most half the first-order growth, the second-order one a quarter).
//
// Two near boxes (each grown by `margin` >= delta / 2 plus the box pad)
// apart mean the links' capsules stay farther apart than delta plus the
// descent's slack over the whole motion: the descent could then neither
// close a bracket on that pair (a sample separation <= delta is needed) nor
// find it touching at the start, so leaving the pair out changes no answer
// (short of the work limit, which fewer items only keep further away).

#include <cmath>
#include <vector>

#include "core/avatar/motion_memo.h"
#include "core/avatar/skeleton.h"
#include "core/geometry/bvh.h"

namespace sweptccd::world {

/// Largest growth of a part before it is halved (metres), and how many
/// halvings at most (2^kNearMaxDepth parts of [0, 1]).
/// (2 cm and 32 parts: on the hands world's 81-link avatars, 1 cm and 64
/// parts clear 0.2 % more entries for 1.5 x the time at load.)
inline constexpr double kNearSplitAbove = 0.02;
inline constexpr int kNearMaxDepth = 5;

/// Per link l of the memo's motion: the union over a partition of [0, 1]
/// of the boxes of the capsules SweptCapsule(l, s0, s1) (radius r_l +
/// growth, times (1 + 1e-9)) grown by `margin` and by the box pad
/// (BoxPad of the motion's coordinate scale). The partition halves a part
/// while its growth exceeds kNearSplitAbove, at most kNearMaxDepth times. A
/// growth that is not finite gives an infinite box (apart from nothing).
/// Every point of the link's capsule at every s in [0, 1] lies in its box
/// at least `margin` from the box's faces. Precondition: margin >= 0 and
/// finite. Deterministic (the memo answers as the motion, bit for bit).
std::vector<Aabb> NearLinkBoxes(const Skeleton& skeleton, MotionMemo* memo, double margin);

/// The union of `boxes` (Aabb::Empty() for none).
Aabb UnionOf(const std::vector<Aabb>& boxes);

/// The margin of near boxes for distance tolerance `delta_m`: half of it,
/// rounded up (two boxes apart are then more than delta apart); infinite
/// for a delta that is not finite and >= 0 (boxes never apart).
inline double NearMargin(double delta_m) {
  return std::isfinite(delta_m) && delta_m >= 0 ? 0.5 * delta_m * (1 + 1e-9) : HUGE_VAL;
}

}  // namespace sweptccd::world
