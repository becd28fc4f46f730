// Enclosure checks for PairMotion::SweptCapsule, the swept bound the queries
// rely on: every point of a link over [s0, s1] must lie within `growth` of the
// same link point at the midpoint. Brute-force twin: dense sampling of s and
// of the point along the segment.

#include <gtest/gtest.h>

#include <random>

#include "core/avatar/motion.h"

namespace sweptccd {
namespace {

Eigen::Quaterniond RandomRotation(std::mt19937_64& rng) {
  std::normal_distribution<double> g;
  Eigen::Quaterniond q(g(rng), g(rng), g(rng), g(rng));
  return q.normalized();
}

// Rotation by `angle` about a random axis.
Eigen::Quaterniond RandomTurn(std::mt19937_64& rng, double angle) {
  std::normal_distribution<double> g;
  Eigen::Vector3d axis(g(rng), g(rng), g(rng));
  return Eigen::Quaterniond(Eigen::AngleAxisd(angle, axis.normalized()));
}

struct Case {
  Skeleton skeleton;
  Pose pose0, pose1;
};

// Random trees up to depth `max_depth`, random links, random motions; a share
// of the turns is close to (or exactly) 180 degrees.
Case RandomCase(std::mt19937_64& rng, int num_links, int max_depth) {
  std::uniform_real_distribution<double> u(-1, 1), r(0.01, 0.15), unit(0, 1);
  std::vector<Link> links(num_links);
  std::vector<int> depth(num_links, 0);
  for (int i = 0; i < num_links; ++i) {
    links[i].name = "l" + std::to_string(i);
    if (i > 0) {
      int p;
      do {
        p = static_cast<int>(rng() % i);
      } while (depth[p] + 1 > max_depth);
      links[i].parent = p;
      depth[i] = depth[p] + 1;
    }
    links[i].a_L = 0.3 * Eigen::Vector3d(u(rng), u(rng), u(rng));
    links[i].b_L =
        unit(rng) < 0.1 ? links[i].a_L : Eigen::Vector3d(0.5 * u(rng), 0.5 * u(rng), 0.5 * u(rng));
    links[i].radius = r(rng);
  }
  Case c;
  c.skeleton = Skeleton::FromLinks("random", links, "test");
  c.pose0.utime = 0;
  c.pose1.utime = 33333;
  c.pose0.links.resize(num_links);
  c.pose1.links.resize(num_links);
  for (int i = 0; i < num_links; ++i) {
    c.pose0.links[i].p = Eigen::Vector3d(u(rng), u(rng), u(rng));
    c.pose0.links[i].q = RandomRotation(rng);
    const double kind = unit(rng);
    const double angle = kind < 0.2 ? M_PI : kind < 0.4 ? M_PI - 1e-3 * unit(rng) : 2 * unit(rng);
    c.pose1.links[i].p = c.pose0.links[i].p + 0.5 * Eigen::Vector3d(u(rng), u(rng), u(rng));
    c.pose1.links[i].q = (RandomTurn(rng, angle) * c.pose0.links[i].q).normalized();
    if (unit(rng) < 0.3) c.pose1.links[i].q.coeffs() *= -1;  // q versus -q
  }
  return c;
}

void CheckEnclosure(uint64_t seed, int cases, int max_links, int max_depth, MotionModel model) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> unit(0, 1);
  int64_t checks = 0, violations = 0;
  for (int n = 0; n < cases; ++n) {
    const int links = 1 + static_cast<int>(rng() % max_links);
    const Case c = RandomCase(rng, links, max_depth);
    const PairMotion motion(c.skeleton, c.pose0, c.pose1, model);
    for (int k = 0; k < 8; ++k) {
      double s0 = unit(rng), s1 = unit(rng);
      if (k == 0) s0 = 0, s1 = 1;
      if (k == 1) s1 = s0 + 1e-4 * unit(rng);
      if (s0 > s1) std::swap(s0, s1);
      s1 = std::min(s1, 1.0);
      const LinkIndex link(static_cast<int>(rng() % links));
      Eigen::Vector3d am, bm, a, b;
      double growth;
      motion.SweptCapsule(link, s0, s1, &am, &bm, &growth);
      EXPECT_LE(growth, motion.SweepRadius(link, s0, s1));
      for (int j = 0; j <= 40; ++j) {
        const double s = s0 + (s1 - s0) * j / 40.0;
        motion.SegmentAt(link, s, &a, &b);
        for (double t : {0.0, 0.25, 0.5, 0.75, 1.0}) {
          const Eigen::Vector3d p = (1 - t) * a + t * b;
          const Eigen::Vector3d pm = (1 - t) * am + t * bm;
          ++checks;
          if ((p - pm).norm() > growth) {
            ++violations;
            ADD_FAILURE() << "seed " << seed << " case " << n << " link " << link << " [" << s0
                          << ", " << s1 << "] s " << s << " t " << t << ": moved "
                          << (p - pm).norm() << " > bound " << growth;
          }
        }
      }
    }
  }
  EXPECT_EQ(violations, 0);
  EXPECT_GT(checks, 100000);
}

TEST(SweptBoundTest, ArticulatedDeepChainsEnclose) {
  CheckEnclosure(11, 1500, 16, 12, MotionModel::kArticulated);
}

TEST(SweptBoundTest, IndependentEncloses) {
  CheckEnclosure(12, 1000, 8, 4, MotionModel::kIndependent);
}

TEST(SweptBoundTest, TwentyLevelChainNear180Degrees) {
  CheckEnclosure(13, 400, 21, 20, MotionModel::kArticulated);
}

// The second-order bound must be much tighter than the first-order one on
// small intervals (that is what it is for): the growth shrinks like the
// actual displacement.
TEST(SweptBoundTest, SecondOrderIsTightOnSmallIntervals) {
  std::mt19937_64 rng(14);
  const Case c = RandomCase(rng, 8, 8);
  const PairMotion motion(c.skeleton, c.pose0, c.pose1, MotionModel::kArticulated);
  for (LinkIndex link(0); link < 8; ++link) {
    Eigen::Vector3d a, b, a0, b0, a1, b1;
    double growth;
    motion.SweptCapsule(link, 0.5, 0.5 + 1e-3, &a, &b, &growth);
    motion.SegmentAt(link, 0.5, &a0, &b0);
    motion.SegmentAt(link, 0.5 + 1e-3, &a1, &b1);
    const double chord = std::max((a1 - a0).norm(), (b1 - b0).norm());
    EXPECT_LE(growth, 0.5 * chord + 1e-4) << "link " << link;
  }
}

}  // namespace
}  // namespace sweptccd
