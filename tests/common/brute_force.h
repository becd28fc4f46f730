#pragma once
// Brute-force twins shared by the core tests: answers computed by testing
// every triangle, with no BVH, no culling and no early exit.

#include <Eigen/Core>
#include <cstdint>
#include <limits>

#include "core/geometry/distance.h"
#include "core/scene/collision_filter.h"
#include "core/scene/environment.h"

namespace sweptccd::testing {

struct BruteNearest {
  bool any = false;  // Some unfiltered triangle is at a finite distance.
  double distance = std::numeric_limits<double>::infinity();  // From the segment a-b.
  ObjectIndex object;
  uint32_t slot = 0;  // BVH slot in `object`.
};

/// The nearest unfiltered triangle of `env` to the segment a-b of `link`, by
/// testing every triangle of every object. Adds the triangles tested to
/// *tests when given.
inline BruteNearest BruteForceNearest(const Environment& env, const CollisionFilter& filter,
                                      LinkIndex link, const Eigen::Vector3d& a,
                                      const Eigen::Vector3d& b, uint32_t* tests = nullptr) {
  BruteNearest best;
  for (ObjectIndex o(0); o < env.num_objects(); ++o) {
    if (filter.Ignores(link, o)) continue;
    const TriangleBvh& bvh = env.object(o).bvh;
    Eigen::Vector3d ta, tb, tc;
    for (uint32_t slot = 0; slot < bvh.num_triangles(); ++slot) {
      bvh.Triangle(slot, &ta, &tb, &tc);
      const double d = SegmentTriangleDistance(a, b, ta, tb, tc).distance;
      if (tests != nullptr) ++*tests;
      if (d < best.distance) {
        best.any = true;
        best.distance = d;
        best.object = o;
        best.slot = slot;
      }
    }
  }
  return best;
}

}  // namespace sweptccd::testing
