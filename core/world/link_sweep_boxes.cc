#include "core/world/link_sweep_boxes.h"

#include <algorithm>
#include <cmath>

#include "core/geometry/rounding_slack.h"

namespace sweptccd::world {

std::vector<Aabb> LinkSweepBoxes(const Skeleton& skeleton, const PairMotion& motion, double extra) {
  // Far above the few ulps by which the boxes below and the descent's own
  // boxes are each rounded (rounding_slack.h).
  const double pad = BoxPad(motion.coordinate_scale());
  std::vector<Aabb> boxes;
  boxes.reserve(static_cast<size_t>(skeleton.num_links()));
  for (LinkIndex l(0); l < skeleton.num_links(); ++l) {
    Eigen::Vector3d a, b;
    double g;  // Every link point at any s is within g of (a, b) (certified).
    motion.SweptCapsule(l, 0, 1, &a, &b, &g);
    // Any descent box's growth is at most either of these: the first-order
    // growth is nondecreasing in s1 - s0 <= 1; the second-order one in the
    // width and the chord, and any link point moves by at most 2 g between
    // two times (each within g of its place at 1/2), so a chord computed
    // from segments (each off by the slack) is at most 2 (g + slack),
    // rounded up here by a relative 1e-9. Its radius is at most
    // r + extra + that, times (1 + 1e-9) plus 1e-9; its segment's points
    // are within g + slack of (a, b).
    const double chord = 2 * (g + motion.rounding_slack()) * (1 + 1e-9);
    const double sub_growth =
        std::min(motion.SweepRadius(l, 0, 1), motion.SecondOrderRadius(l, chord, 0, 1));
    const double radius = (skeleton.link(l).radius + extra + sub_growth) * (1 + 1e-9) + 1e-9;
    double outer = (radius + g + motion.rounding_slack()) * (1 + 1e-9) + pad;
    if (!std::isfinite(outer)) outer = HUGE_VAL;
    boxes.push_back(Aabb::OfCapsule(a, b, outer));
  }
  return boxes;
}

}  // namespace sweptccd::world
