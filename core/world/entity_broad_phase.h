#pragma once
// Internal to the entity engine (docs/DESIGN.md, section 5a): the broad
// phase over entities. A box holds the certified swept capsule of every
// link (or every mesh point) over one motion, padded far above the rounding
// of the box itself (BoxPad, rounding_slack.h); boxes apart mean the
// entities do not touch over that motion, and then the answer is `free`
// with no link work. (The descent could instead accept a near miss within
// delta, which G3 allows too: `sweptccd world` and the daemon both apply
// these boxes through EntryNear, so they agree.) Each box depends on its own
// motion's samples only, so a live service holding those samples computes
// the same bits as `sweptccd world`.

#include <vector>

#include "core/avatar/motion.h"
#include "core/avatar/skeleton.h"
#include "core/geometry/bvh.h"
#include "core/world/window_split.h"
#include "core/world/world.h"

namespace sweptccd::world {

/// Every link of an avatar over `motion` (one pair or one sample interval).
Aabb AvatarMotionBox(const Skeleton& skeleton, const PairMotion& motion);
/// The largest distance from an object's frame origin to a point of its mesh
/// (of its BVH's bounds), rounded up.
double ObjectRadius(const TriangleBvh& bvh);
/// A tracked object moving from x0 to x1 (x1 == x0 for an object with one
/// sample): its frame origin moves on the segment, every mesh point within
/// `radius` (ObjectRadius) of it; `mesh_scale` is the BVH's largest absolute
/// coordinate.
Aabb ObjectMotionBox(const RigidSample& x0, const RigidSample& x1, double radius,
                     double mesh_scale);

/// The entry's broad phase: whether A's box over the pair meets E's box of
/// some interval the window's pieces use; `box_of(k)` is E's box over its
/// samples k -> k + 1 (k -> k for an entity with one sample). False: the
/// entry is `free` with culled_by_box, and no link work.
template <class BoxOf>
bool EntryNear(const Aabb& box_a, const std::vector<Piece>& pieces, const BoxOf& box_of) {
  for (const Piece& p : pieces) {
    if (box_a.Overlaps(box_of(static_cast<size_t>(p.k)))) return true;
  }
  return false;
}

}  // namespace sweptccd::world
