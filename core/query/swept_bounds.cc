#include "core/query/swept_bounds.h"

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <limits>

#include "core/geometry/rounding_slack.h"

namespace sweptccd::internal {

double SweptBounds::Tolerance(const Environment& environment, const PairMotion& motion) {
  return std::max(environment.coordinate_tolerance(), RoundingSlack(motion.coordinate_scale()));
}

SegmentEnds SweptBounds::EndsOver(LinkIndex link, double s0, double s1) const {
  SegmentEnds ends;
  motion_.SegmentAt(link, s0, &ends.a0, &ends.b0);
  motion_.SegmentAt(link, s1, &ends.a1, &ends.b1);
  return ends;
}

LinkCapsule SweptBounds::Over(LinkIndex link, double s0, double s1) const {
  LinkCapsule c;
  double growth;
  motion_.SweptCapsule(link, s0, s1, &c.a, &c.b, &growth);
  c.radius = Radius(link, growth);
  c.link = link;
  return c;
}

LinkCapsule SweptBounds::LooseOver(LinkIndex link, const Pose& pose0, const Pose& pose1,
                                   double growth) const {
  const Link& l = skeleton_.link(link);
  const LinkPose& x0 = pose0.links[link];
  const LinkPose& x1 = pose1.links[link];
  const Eigen::Matrix3d r0 = x0.q.toRotationMatrix();
  const Eigen::Matrix3d r1 = x1.q.toRotationMatrix();
  LinkCapsule c;
  c.a = 0.5 * ((x0.p + r0 * l.a_L) + (x1.p + r1 * l.a_L));
  c.b = 0.5 * ((x0.p + r0 * l.b_L) + (x1.p + r1 * l.b_L));
  // Products by 2, 4 and 0.5 are exact (short of subnormals, which BoxPad
  // covers, as it covers the sums' rounding).
  c.radius = l.radius + 2 * growth + tolerance_m_ + 4 * motion_.rounding_slack() +
             BoxPad(motion_.coordinate_scale());
  // A bound that is not finite meets everything (a NaN would meet nothing).
  if (!(c.radius <= std::numeric_limits<double>::max())) {
    c.radius = std::numeric_limits<double>::infinity();
  }
  c.link = link;
  return c;
}

LinkCapsule SweptBounds::FromEnds(LinkIndex link, double s0, double s1,
                                  const SegmentEnds& ends) const {
  LinkCapsule c;
  double growth;
  motion_.SweptCapsuleFromEnds(link, s0, s1, ends.a0, ends.b0, ends.a1, ends.b1, &c.a, &c.b,
                               &growth);
  c.radius = Radius(link, growth);
  c.link = link;
  return c;
}

}  // namespace sweptccd::internal
