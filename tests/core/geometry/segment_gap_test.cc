// SegmentGapLowerBound against brute-force twins: the segment distance by a
// dense scan of one segment (each point's exact distance to the other
// segment, in long double), which the bound must never exceed; and the use
// AvatarTarget::Cull makes of it: a gap past r (1 + 1e-9) + tol must mean
// that SegmentSegmentDistanceSquared is past r^2 (1 + 1e-9) too. Seeded
// random segments: general, nearly parallel, collinear, crossing, points,
// at human and large coordinates.

#include "core/geometry/segment_gap.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>

#include "core/geometry/distance.h"
#include "tests/common/random.h"

namespace sweptccd {
namespace {

using testing::Rng;
using Vec3L = Eigen::Matrix<long double, 3, 1>;

// Distance from point x to segment (p, q), in long double.
long double PointSegment(const Vec3L& x, const Vec3L& p, const Vec3L& q) {
  const Vec3L d = q - p;
  const long double dd = d.squaredNorm();
  long double t = dd > 0 ? (x - p).dot(d) / dd : 0;
  t = std::clamp<long double>(t, 0, 1);
  return (x - (p + t * d)).norm();
}

// An upper bound on the segment distance within (length / 2 / kSteps) of it
// (the scan's spacing): the minimum over the scanned points of segment 1.
long double ScanDistance(const Eigen::Vector3d& p1, const Eigen::Vector3d& q1,
                         const Eigen::Vector3d& p2, const Eigen::Vector3d& q2) {
  constexpr int kSteps = 4000;
  const Vec3L a = p1.cast<long double>(), b = q1.cast<long double>();
  const Vec3L c = p2.cast<long double>(), d = q2.cast<long double>();
  long double best = INFINITY;
  for (int i = 0; i <= kSteps; ++i) {
    const long double u = static_cast<long double>(i) / kSteps;
    best = std::min(best, PointSegment(a + u * (b - a), c, d));
  }
  return best;
}

void RandomPair(Rng* rng, Eigen::Vector3d* p1, Eigen::Vector3d* q1, Eigen::Vector3d* p2,
                Eigen::Vector3d* q2) {
  const double scale = rng->P(0.8) ? 1.0 : 1000.0;
  const Eigen::Vector3d centre = rng->Box(scale);
  *p1 = centre + rng->Box(0.5);
  *q1 = *p1 + rng->Dir() * rng->U(0, 0.6);
  *p2 = centre + rng->Box(0.5);
  const int kind = rng->I(5);
  if (kind == 0) {  // Nearly parallel.
    *q2 = *p2 + ((*q1 - *p1) + rng->Box(1e-6)) * rng->U(0.2, 2);
  } else if (kind == 1) {  // Collinear, apart or overlapping.
    *p2 = *q1 + (*q1 - *p1) * rng->U(-1, 1);
    *q2 = *p2 + (*q1 - *p1) * rng->U(0.1, 1);
  } else if (kind == 2) {  // A point.
    *q2 = *p2;
  } else if (kind == 3) {  // Crossing near one point.
    const Eigen::Vector3d x = *p1 + (*q1 - *p1) * rng->U(0, 1) + rng->Dir() * rng->U(0, 0.05);
    const Eigen::Vector3d dir = rng->Dir();
    *p2 = x - dir * rng->U(0, 0.3);
    *q2 = x + dir * rng->U(0, 0.3);
  } else {
    *q2 = *p2 + rng->Dir() * rng->U(0, 0.6);
  }
}

TEST(SegmentGapTest, NeverAboveTheScannedDistance) {
  Rng rng(0x5e6a9);
  int separating = 0;
  for (int trial = 0; trial < 3000; ++trial) {
    Eigen::Vector3d p1, q1, p2, q2;
    RandomPair(&rng, &p1, &q1, &p2, &q2);
    const double gap = SegmentGapLowerBound(p1, q1, p2, q2);
    const double scan = static_cast<double>(ScanDistance(p1, q1, p2, q2));
    const double slack = 1e-12 * (1 + p1.cwiseAbs().maxCoeff());
    ASSERT_GE(gap, 0.0) << "trial " << trial;
    ASSERT_LE(gap, scan + slack) << "trial " << trial;
    separating += gap > 0;
  }
  EXPECT_GT(separating, 300);  // The bound does separate (it is no constant 0).
}

TEST(SegmentGapTest, PastTheReachMeansTheExactTestDropsToo) {
  Rng rng(0x5e6aa);
  for (int trial = 0; trial < 20000; ++trial) {
    Eigen::Vector3d p1, q1, p2, q2, c1, c2;
    RandomPair(&rng, &p1, &q1, &p2, &q2);
    const double gap = SegmentGapLowerBound(p1, q1, p2, q2);
    // A reach under the gap, half the time the largest that Cull's test
    // still drops (tol as the targets' own, which scales with coordinates).
    const double tol = std::ldexp(p1.cwiseAbs().maxCoeff() + 10.0, -22) + 1e-9;
    const double reach = rng.P(0.5) ? std::nextafter((gap - tol) / (1 + 1e-9), 0.0)
                                    : gap * rng.U(0.5, 1.0);
    if (!(gap > reach * (1 + 1e-9) + tol)) continue;
    const double d2 = SegmentSegmentDistanceSquared(p1, q1, p2, q2, &c1, &c2);
    ASSERT_GT(d2, reach * reach * (1 + 1e-9)) << "trial " << trial;
  }
}

}  // namespace
}  // namespace sweptccd
