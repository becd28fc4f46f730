#pragma once
// The link-level broad phase of the entity descent (core/world/entity_run):
// one box per link over a whole motion that holds every box the descent
// tests for that link over any part of the motion. Two links whose boxes are
// apart are apart in every item of the descent, so their pair can leave the
// candidates before any pose is composed, and an entity whose links are all
// apart from A's is `free` with no descent at all (the answer the descent
// would give: every item's Cull drops every candidate).

#include <vector>

#include "core/avatar/motion.h"
#include "core/geometry/bvh.h"

namespace sweptccd::world {

/// Per link l of `motion`: a box holding, for every [s0, s1] within [0, 1],
/// the box of the capsule around SweptCapsule(l, s0, s1)'s segment with
/// radius r_l + growth + `extra`, and, for every s in [0, 1], the box of
/// SegmentAt(l, s) with radius r_l + `extra` (r_l the link's radius). Holds
/// also every such box with its radius multiplied by (1 + 1e-9) and grown
/// by 1e-9 m (the descent's own rounding margins).
///
/// Why: every link point at any s is within the motion's certified growth
/// g(0, 1) of the segment at s = 1/2 (plus the rounding slack of the
/// segment computed at s), and a growth over [s0, s1] is at most the
/// first-order growth over [0, 1] (its formula is nondecreasing in the
/// width, rounding included). The box is padded far above its own rounding.
/// A radius that is not finite gives an infinite box (apart from nothing).
/// O(links), with no pose composed (the segments at 0, 1/2 and 1 are kept by
/// the motion). Precondition: extra >= 0 and finite.
std::vector<Aabb> LinkSweepBoxes(const Skeleton& skeleton, const PairMotion& motion, double extra);

/// True when the boxes are apart on some axis by a gap over `margin` (>= 0;
/// a box grown by `margin` on every side would still be apart). Not
/// Aabb::Overlaps's negation: a NaN coordinate makes boxes not apart here.
inline bool BoxesApart(const Aabb& x, const Aabb& y, double margin = 0.0) {
  for (int i = 0; i < 3; ++i) {
    if (x.lo[i] - margin > y.hi[i] || y.lo[i] - margin > x.hi[i]) return true;
  }
  return false;
}

}  // namespace sweptccd::world
