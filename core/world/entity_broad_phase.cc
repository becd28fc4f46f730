#include "core/world/entity_broad_phase.h"

#include <algorithm>
#include <cmath>

#include "core/geometry/rounding_slack.h"

namespace sweptccd::world {

Aabb AvatarMotionBox(const Skeleton& skeleton, const PairMotion& motion) {
  const double pad = BoxPad(motion.coordinate_scale());
  Aabb box = Aabb::Empty();
  for (LinkIndex l(0); l < skeleton.num_links(); ++l) {
    Eigen::Vector3d a, b;
    double g;
    motion.SweptCapsule(l, 0, 1, &a, &b, &g);
    box.Grow(Aabb::OfCapsule(a, b, (skeleton.link(l).radius + g) * (1 + 1e-9) + pad));
  }
  return box;
}

double ObjectRadius(const TriangleBvh& bvh) {
  double rho = 0;
  const Aabb bounds = bvh.bounds();
  for (int c = 0; c < 8; ++c) {
    const Eigen::Vector3d corner((c & 1) ? bounds.hi.x() : bounds.lo.x(),
                                 (c & 2) ? bounds.hi.y() : bounds.lo.y(),
                                 (c & 4) ? bounds.hi.z() : bounds.lo.z());
    rho = std::max(rho, corner.norm());
  }
  return rho;
}

Aabb ObjectMotionBox(const RigidSample& x0, const RigidSample& x1, double radius,
                     double mesh_scale) {
  const double scale =
      std::max({mesh_scale, x0.p.cwiseAbs().maxCoeff(), x1.p.cwiseAbs().maxCoeff()});
  return Aabb::OfCapsule(x0.p, x1.p, radius * (1 + 1e-9) + BoxPad(scale));
}

}  // namespace sweptccd::world
