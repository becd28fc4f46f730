// MotionMemo against its brute-force twin, PairMotion itself: every segment
// and swept capsule the memo answers is compared bit for bit with the
// motion's own SegmentAt and SweptCapsule, over seeded random skeletons
// (trees, chains deeper than PoseAt's 64-link step, stars), both motion
// models, times asked in random order and again (0, 0.5 and 1 included,
// -0.0 too), and memos small enough to be emptied mid-run.

#include "core/avatar/motion_memo.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cstring>
#include <string>
#include <vector>

#include "core/avatar/pose.h"
#include "core/avatar/skeleton.h"
#include "tests/common/random.h"

namespace sweptccd {
namespace {

using testing::Rng;

bool SameBits(const Eigen::Vector3d& x, const Eigen::Vector3d& y) {
  return std::memcmp(x.data(), y.data(), 3 * sizeof(double)) == 0;
}
bool SameBits(double x, double y) { return std::memcmp(&x, &y, sizeof x) == 0; }

Skeleton RandomSkeleton(Rng* rng, int n, int shape) {
  std::vector<Link> links(static_cast<size_t>(n));
  for (int i = 0; i < n; ++i) {
    Link& l = links[static_cast<size_t>(i)];
    l.name = "l" + std::to_string(i);
    l.parent = i == 0 ? -1 : shape == 0 ? i - 1 : shape == 1 ? 0 : rng->I(i);
    l.a_L = rng->P(0.5) ? Eigen::Vector3d::Zero() : rng->Box(0.3);
    l.b_L = rng->P(0.1) ? l.a_L : rng->Box(0.3);
    l.radius = rng->U(0.01, 0.1);
  }
  return Skeleton::FromLinks("random", std::move(links), "motion_memo_test");
}

Pose RandomPose(Rng* rng, int n, double scale) {
  Pose p;
  p.links.resize(static_cast<size_t>(n));
  for (LinkPose& l : p.links) {
    l.p = rng->Box(scale);
    l.q = rng->Quat();
  }
  return p;
}

TEST(MotionMemoTest, SegmentsAndSweptCapsulesMatchPairMotionBitForBit) {
  Rng rng(0x3e3011);
  for (int trial = 0; trial < 300; ++trial) {
    const int shape = rng.I(3);
    const int n = trial % 50 == 0 ? 70 + rng.I(40) : 1 + rng.I(30);
    const Skeleton skeleton = RandomSkeleton(&rng, n, shape);
    const double scale = std::vector<double>{0.01, 1.0, 50.0}[static_cast<size_t>(rng.I(3))];
    const Pose pose0 = RandomPose(&rng, n, scale);
    Pose pose1 = pose0;
    if (rng.P(0.8)) pose1 = RandomPose(&rng, n, scale);
    const MotionModel model = rng.P(0.7) ? MotionModel::kArticulated : MotionModel::kIndependent;
    const PairMotion motion(skeleton, pose0, pose1, model);
    MotionMemo memo(motion, rng.P(0.3) ? 1 + static_cast<size_t>(rng.I(4)) : 1024);
    // A few times, asked many times each (as the descents do).
    std::vector<double> times = {0.0, 0.5, 1.0, -0.0};
    for (int i = 0; i < 6; ++i) times.push_back(rng.U(0, 1));
    for (int ask = 0; ask < 200; ++ask) {
      const LinkIndex link(rng.I(n));
      const double s0 = times[static_cast<size_t>(rng.I(static_cast<int>(times.size())))];
      Eigen::Vector3d a, b, ta, tb;
      memo.SegmentAt(link, s0, &a, &b);
      motion.SegmentAt(link, s0, &ta, &tb);
      ASSERT_TRUE(SameBits(a, ta) && SameBits(b, tb))
          << "trial " << trial << " link " << link << " s " << s0;
      double s1 = times[static_cast<size_t>(rng.I(static_cast<int>(times.size())))];
      double lo = std::min(s0, s1), hi = std::max(s0, s1);
      double g, tg;
      memo.SweptCapsule(link, lo, hi, &a, &b, &g);
      motion.SweptCapsule(link, lo, hi, &ta, &tb, &tg);
      ASSERT_TRUE(SameBits(a, ta) && SameBits(b, tb) && SameBits(g, tg))
          << "trial " << trial << " link " << link << " [" << lo << ", " << hi << "]";
    }
  }
}

// One memo rebound from motion to motion (as the shared world keeps one per
// record): every answer after Rebind is the new motion's, bit for bit, none
// left over from the old one (the same times are asked of both).
// Skeletons of different link counts, so that a block of slots after
// Rebind overlaps slots of the old motion and new ones (a regression: those
// old slots once kept their composed poses).
TEST(MotionMemoTest, ReboundMemoAnswersForTheNewMotion) {
  Rng rng(0x3e3012);
  std::vector<Skeleton> skeletons;
  for (int k = 0; k < 40; ++k) skeletons.push_back(RandomSkeleton(&rng, 1 + rng.I(9), rng.I(3)));
  std::vector<PairMotion> motions;
  for (const Skeleton& sk : skeletons) {
    const int n = sk.num_links();
    motions.emplace_back(sk, RandomPose(&rng, n, 1.0), RandomPose(&rng, n, 1.0),
                         rng.P(0.7) ? MotionModel::kArticulated : MotionModel::kIndependent);
  }
  const std::vector<double> times = {0.0, 0.25, 0.5, 0.75, 1.0, 0.125, 0.375, 0.8, 0.9};
  MotionMemo memo(motions[0], 1 + static_cast<size_t>(rng.I(8)));
  for (size_t m = 0; m < motions.size(); ++m) {
    if (m > 0) memo.Rebind(motions[m]);
    ASSERT_EQ(&memo.motion(), &motions[m]);
    const int n = motions[m].num_links();
    for (int ask = 0; ask < 100; ++ask) {
      const LinkIndex link(rng.I(n));
      const double s0 = times[static_cast<size_t>(rng.I(static_cast<int>(times.size())))];
      const double s1 = times[static_cast<size_t>(rng.I(static_cast<int>(times.size())))];
      const double lo = std::min(s0, s1), hi = std::max(s0, s1);
      Eigen::Vector3d a, b, ta, tb;
      double g, tg;
      memo.SegmentAt(link, s0, &a, &b);
      motions[m].SegmentAt(link, s0, &ta, &tb);
      ASSERT_TRUE(SameBits(a, ta) && SameBits(b, tb)) << "motion " << m << " link " << link;
      memo.SweptCapsule(link, lo, hi, &a, &b, &g);
      motions[m].SweptCapsule(link, lo, hi, &ta, &tb, &tg);
      ASSERT_TRUE(SameBits(a, ta) && SameBits(b, tb) && SameBits(g, tg))
          << "motion " << m << " link " << link << " [" << lo << ", " << hi << "]";
    }
  }
}

// The smallest case of that regression: a 7-link motion's segments at one
// time fill slots 0-6; rebound to a 4-link motion, its second time's block
// is slots 4-7, of which 4-6 held the old motion's segments.
// A random 7-link motion and a random 4-link one, for the Rebind tests.
struct SevenThenFour {
  explicit SevenThenFour(uint64_t seed)
      : rng(seed),
        seven(RandomSkeleton(&rng, 7, 0)),
        four(RandomSkeleton(&rng, 4, 0)),
        m7(seven, RandomPose(&rng, 7, 1.0), RandomPose(&rng, 7, 1.0), MotionModel::kArticulated),
        m4(four, RandomPose(&rng, 4, 1.0), RandomPose(&rng, 4, 1.0), MotionModel::kArticulated) {}
  Rng rng;
  const Skeleton seven, four;
  const PairMotion m7, m4;
};

TEST(MotionMemoTest, ReboundToFewerLinksForgetsTheOldSegments) {
  const SevenThenFour f(0x3e3013);
  const PairMotion &m7 = f.m7, &m4 = f.m4;
  MotionMemo memo(m7);
  Eigen::Vector3d a, b, ta, tb;
  for (LinkIndex l(0); l < 7; ++l) memo.SegmentAt(l, 0.3, &a, &b);
  memo.Rebind(m4);
  for (double s : {0.3, 0.7}) {
    for (LinkIndex l(0); l < 4; ++l) {
      memo.SegmentAt(l, s, &a, &b);
      m4.SegmentAt(l, s, &ta, &tb);
      EXPECT_TRUE(SameBits(a, ta) && SameBits(b, tb)) << "link " << l << " s " << s;
    }
  }
}

// The same for the kept swept capsules: after Rebind to fewer links, a
// second interval's block overlaps swept slots of the old motion.
TEST(MotionMemoTest, ReboundToFewerLinksForgetsTheOldSweptCapsules) {
  const SevenThenFour f(0x3e3014);
  const PairMotion &m7 = f.m7, &m4 = f.m4;
  MotionMemo memo(m7);
  Eigen::Vector3d a, b, ta, tb;
  double g, tg;
  for (LinkIndex l(0); l < 7; ++l) memo.SweptCapsule(l, 0.3, 0.6, &a, &b, &g);
  memo.Rebind(m4);
  for (double s0 : {0.3, 0.1}) {
    for (LinkIndex l(0); l < 4; ++l) {
      memo.SweptCapsule(l, s0, 0.6, &a, &b, &g);
      m4.SweptCapsule(l, s0, 0.6, &ta, &tb, &tg);
      EXPECT_TRUE(SameBits(a, ta) && SameBits(b, tb) && SameBits(g, tg))
          << "link " << l << " s0 " << s0;
    }
  }
}

}  // namespace
}  // namespace sweptccd
