#include "core/world/near_link_boxes.h"

#include <cmath>

#include "core/geometry/rounding_slack.h"

namespace sweptccd::world {
namespace {

// Grows *box by link l's swept capsules over [s0, s1], halving the part
// while its growth is over kNearSplitAbove (depth halvings left).
void GrowSwept(MotionMemo* memo, LinkIndex l, double radius, double grow, double s0, double s1,
               int depth, Aabb* box) {
  Eigen::Vector3d a, b;
  double g;
  memo->SweptCapsule(l, s0, s1, &a, &b, &g);
  const double mid = 0.5 * (s0 + s1);
  if (g > kNearSplitAbove && depth > 0 && mid > s0 && mid < s1) {
    GrowSwept(memo, l, radius, grow, s0, mid, depth - 1, box);
    GrowSwept(memo, l, radius, grow, mid, s1, depth - 1, box);
    return;
  }
  double outer = (radius + g) * (1 + 1e-9) + grow;
  if (!std::isfinite(outer)) outer = HUGE_VAL;
  box->Grow(Aabb::OfCapsule(a, b, outer));
}

}  // namespace

std::vector<Aabb> NearLinkBoxes(const Skeleton& skeleton, MotionMemo* memo, double margin) {
  const double grow = margin + BoxPad(memo->motion().coordinate_scale());
  std::vector<Aabb> boxes;
  boxes.reserve(static_cast<size_t>(skeleton.num_links()));
  for (LinkIndex l(0); l < skeleton.num_links(); ++l) {
    Aabb box = Aabb::Empty();
    GrowSwept(memo, l, skeleton.link(l).radius, grow, 0.0, 1.0, kNearMaxDepth, &box);
    boxes.push_back(box);
  }
  return boxes;
}

Aabb UnionOf(const std::vector<Aabb>& boxes) {
  Aabb box = Aabb::Empty();
  for (const Aabb& b : boxes) box.Grow(b);
  return box;
}

}  // namespace sweptccd::world
