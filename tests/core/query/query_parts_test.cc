// The engine's internal parts (core/query, see docs/DESIGN.md section 3a)
// against their definitions: the swept capsule computed one way, the cull
// batching asking exactly the descent's capsules, and the time slicer's halves
// sharing the midpoint segment.

#include <gtest/gtest.h>

#include <vector>

#include "core/avatar/motion.h"
#include "core/avatar/pose.h"
#include "core/avatar/skeleton.h"
#include "core/query/cull_batcher.h"
#include "core/query/swept_bounds.h"
#include "core/query/time_slicer.h"
#include "tests/common/random.h"

namespace sweptccd::internal {
namespace {

using testing::Rng;

Skeleton Chain(Rng& rng) {
  std::vector<Link> links(3);
  for (int i = 0; i < 3; ++i) {
    links[i].name = "l" + std::to_string(i);
    links[i].parent = i - 1;
    links[i].b_L = rng.Box(0.3);
    links[i].radius = rng.U(0.01, 0.1);
  }
  return Skeleton::FromLinks("chain", links, "query_parts_test");
}

Pose RandomPose(Rng& rng, int64_t utime, int n) {
  Pose p;
  p.utime = utime;
  for (int i = 0; i < n; ++i) p.links.push_back(LinkPose{rng.Box(1), rng.Quat()});
  EXPECT_EQ(ValidateAndNormalizePose(&p, n), "");
  return p;
}

// Records what it is asked; clears every capsule whose radius is below
// `clear_below`, or fails.
class FakeCuller : public CapsuleCuller {
 public:
  bool Cull(const std::vector<LinkCapsule>& capsules,
            std::vector<uint8_t>* may_touch) const override {
    asked.insert(asked.end(), capsules.begin(), capsules.end());
    ++round_trips;
    may_touch->clear();
    for (const LinkCapsule& c : capsules) may_touch->push_back(c.radius < clear_below ? 0 : 1);
    return !fail;
  }
  double clear_below = 0;
  bool fail = false;
  mutable std::vector<LinkCapsule> asked;
  mutable int round_trips = 0;
};

TEST(QueryPartsTest, SweptCapsuleIsOneRadiusComputedOneWay) {
  Rng rng(11);
  for (int trial = 0; trial < 200; ++trial) {
    const Skeleton sk = Chain(rng);
    const PairMotion motion(sk, RandomPose(rng, 0, 3), RandomPose(rng, 1000, 3),
                            trial % 2 ? MotionModel::kIndependent : MotionModel::kArticulated);
    const double tol = rng.U(1e-9, 1e-6);
    const SweptBounds bounds(sk, motion, tol);
    const LinkIndex link(rng.I(3));
    double s0 = rng.U(0, 1), s1 = rng.U(0, 1);
    if (s0 > s1) std::swap(s0, s1);
    const LinkCapsule over = bounds.Over(link, s0, s1);
    const LinkCapsule ends = bounds.FromEnds(link, s0, s1, bounds.EndsOver(link, s0, s1));
    Eigen::Vector3d a, b;
    double growth;
    motion.SweptCapsule(link, s0, s1, &a, &b, &growth);
    EXPECT_EQ(over.link, link);
    EXPECT_EQ(over.a, a);
    EXPECT_EQ(over.b, b);
    EXPECT_EQ(over.radius, sk.link(link).radius + growth + tol);
    EXPECT_EQ(ends.a, over.a);
    EXPECT_EQ(ends.b, over.b);
    EXPECT_EQ(ends.radius, over.radius);
  }
}

TEST(QueryPartsTest, SplitHalvesShareTheMidpointSegment) {
  Rng rng(12);
  const Skeleton sk = Chain(rng);
  const PairMotion motion(sk, RandomPose(rng, 0, 3), RandomPose(rng, 1000, 3),
                          MotionModel::kArticulated);
  const SweptBounds bounds(sk, motion, 1e-9);
  Interval parent;
  parent.link = LinkIndex(2);
  parent.ends = bounds.EndsOver(parent.link, 0, 1);
  for (int depth = 0; depth < 30; ++depth) {
    const LinkCapsule cap = bounds.FromEnds(parent.link, parent.s0, parent.s1, parent.ends);
    Interval lower, upper;
    ASSERT_TRUE(TimeSlicer::Split(parent, cap, CandidateList{3, 4, false}, &lower, &upper));
    EXPECT_EQ(lower.s1, upper.s0);
    EXPECT_EQ(lower.depth, parent.depth + 1);
    EXPECT_EQ(upper.candidates.begin, 3u);
    // The halves' capsules are what a fresh computation at their ends gives.
    for (const Interval* half : {&lower, &upper}) {
      const LinkCapsule fresh = bounds.Over(half->link, half->s0, half->s1);
      const LinkCapsule reused = bounds.FromEnds(half->link, half->s0, half->s1, half->ends);
      EXPECT_EQ(fresh.a, reused.a);
      EXPECT_EQ(fresh.radius, reused.radius);
    }
    parent = rng.I(2) ? lower : upper;
  }
  parent.s0 = 0.5;
  parent.s1 = std::nextafter(0.5, 1.0);  // No midpoint strictly inside.
  Interval lower, upper;
  EXPECT_FALSE(TimeSlicer::Split(parent, LinkCapsule{}, CandidateList{}, &lower, &upper));
}

TEST(QueryPartsTest, CullBatcherAsksTheDescentsCapsulesAhead) {
  Rng rng(13);
  const Skeleton sk = Chain(rng);
  const PairMotion motion(sk, RandomPose(rng, 0, 3), RandomPose(rng, 1000, 3),
                          MotionModel::kArticulated);
  const SweptBounds bounds(sk, motion, 1e-9);
  FakeCuller culler;
  culler.clear_below = 1e300;  // Clears everything.
  QueryStats stats;
  CullBatcher batcher(&culler, bounds, &stats);
  Interval root;
  root.link = LinkIndex(1);
  root.ends = bounds.EndsOver(root.link, 0, 1);
  const std::vector<bool> done(3, false);
  const CullAnswer* answer = batcher.AnswerFor(root, {}, done);
  ASSERT_NE(answer, nullptr);
  EXPECT_TRUE(answer->cleared);
  // The interval and 3 levels below it: 1 + 2 + 4 + 8 capsules, one round trip.
  EXPECT_EQ(culler.round_trips, 1);
  ASSERT_EQ(culler.asked.size(), 15u);
  EXPECT_EQ(stats.cull_capsules, 15);
  for (double w : {1.0, 0.5, 0.25, 0.125}) {
    for (double s0 = 0; s0 < 1; s0 += w) {
      const CullAnswer* sub = batcher.Find(root.link, s0, s0 + w);
      ASSERT_NE(sub, nullptr) << "[" << s0 << ", " << s0 + w << "] not asked";
      const LinkCapsule expected = bounds.Over(root.link, s0, s0 + w);
      EXPECT_EQ(sub->capsule.a, expected.a);
      EXPECT_EQ(sub->capsule.radius, expected.radius);
    }
  }
  EXPECT_EQ(batcher.Find(root.link, 0, 0.0625), nullptr);
  // Asked again: answered from the batch, no round trip.
  EXPECT_EQ(batcher.AnswerFor(root, {}, done), answer);
  EXPECT_EQ(culler.round_trips, 1);
}

TEST(QueryPartsTest, CullBatcherGoesInactiveWhenTheCullerFails) {
  Rng rng(14);
  const Skeleton sk = Chain(rng);
  const PairMotion motion(sk, RandomPose(rng, 0, 3), RandomPose(rng, 1000, 3),
                          MotionModel::kArticulated);
  const SweptBounds bounds(sk, motion, 1e-9);
  FakeCuller culler;
  culler.fail = true;
  QueryStats stats;
  CullBatcher batcher(&culler, bounds, &stats);
  Interval root;
  root.link = LinkIndex(0);
  root.ends = bounds.EndsOver(root.link, 0, 1);
  EXPECT_TRUE(batcher.active());
  EXPECT_EQ(batcher.AnswerFor(root, {}, std::vector<bool>(3, false)), nullptr);
  EXPECT_FALSE(batcher.active());
  EXPECT_EQ(stats.cull_round_trips, 0);
  EXPECT_EQ(batcher.AnswerFor(root, {}, std::vector<bool>(3, false)), nullptr);
  EXPECT_EQ(culler.round_trips, 1);  // Not asked again.
}

}  // namespace
}  // namespace sweptccd::internal
