#include "core/query/swept_bounds.h"

#include <algorithm>
#include <cmath>

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
