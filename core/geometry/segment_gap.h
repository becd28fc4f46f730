#pragma once
// A cheap lower bound on the distance between two segments: the gap
// between their projections on two axes (the line between their midpoints,
// and the common normal of their directions). Any axis's gap is at most the
// distance, so a caller that only asks "farther apart than r?" can answer
// "yes" without the exact distance when the gap already says so.

#include <Eigen/Core>
#include <algorithm>
#include <cmath>

namespace sweptccd {

/// A lower bound on dist(segment (p1, q1), segment (p2, q2)), up to the
/// rounding of a few operations on the coordinates (a few ulps of their
/// magnitudes); 0 when neither axis separates the segments. Finite inputs.
/// O(1); any thread.
inline double SegmentGapLowerBound(const Eigen::Vector3d& p1, const Eigen::Vector3d& q1,
                                   const Eigen::Vector3d& p2, const Eigen::Vector3d& q2) {
  const Eigen::Vector3d d1 = q1 - p1, d2 = q2 - p2;
  const Eigen::Vector3d m = 0.5 * ((p2 + q2) - (p1 + q1));  // Midpoint to midpoint.
  // On a unit axis n each segment projects to its midpoint's projection
  // plus or minus half its extent along n. The formula holds for any unit
  // n, so an axis computed with rounding (n not quite perpendicular to d1
  // and d2 below) still gives a lower bound.
  auto gap_on = [&](const Eigen::Vector3d& n) {
    return std::fabs(m.dot(n)) - 0.5 * (std::fabs(d1.dot(n)) + std::fabs(d2.dot(n)));
  };
  double gap = 0;
  const double mm = m.squaredNorm();
  if (mm > 0) gap = std::max(gap, gap_on(m / std::sqrt(mm)));
  const Eigen::Vector3d c = d1.cross(d2);  // Both segments project to points.
  const double cc = c.squaredNorm();
  if (cc > 0) gap = std::max(gap, gap_on(c / std::sqrt(cc)));
  return gap;
}

}  // namespace sweptccd
