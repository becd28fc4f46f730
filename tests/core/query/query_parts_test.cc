// The engine's internal parts (core/query, see docs/DESIGN.md section 3a)
// against their definitions: the swept capsule computed one way, the cull
// batching asking exactly the descent's capsules, and the time slicer's halves
// sharing the midpoint segment.

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <vector>

#include "core/avatar/motion.h"
#include "core/avatar/pose.h"
#include "core/avatar/skeleton.h"
#include "core/geometry/distance.h"
#include "core/query/candidate_pool.h"
#include "core/query/cull_batcher.h"
#include "core/query/environment_target.h"
#include "core/query/pair_clears.h"
#include "core/query/swept_bounds.h"
#include "core/query/time_slicer.h"
#include "core/scene/collision_filter.h"
#include "core/scene/environment.h"
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

// Two objects of random triangles centred in [-half, half]^3: a fifth of
// them large (size in [large_min, large_max]), the rest small (up to
// small_max), one in ten a sliver and, with `points`, one in twenty a point.
struct Soup {
  int count;
  double half, large_min, large_max, small_max;
  bool points;
};
Environment TwoSoups(Rng& rng, const Soup& soup) {
  Environment env;
  for (int o = 0; o < 2; ++o) {
    TriangleMesh mesh;
    for (int t = 0; t < soup.count; ++t) {
      const Eigen::Vector3d c = rng.Box(soup.half);
      const double size =
          rng.P(0.2) ? rng.U(soup.large_min, soup.large_max) : rng.U(0.005, soup.small_max);
      Eigen::Vector3d a = c + size * rng.Dir(), b = c + size * rng.Dir(), d = c + size * rng.Dir();
      if (rng.P(0.1)) d = a + rng.U(0, 1) * (b - a) + 1e-5 * size * rng.Dir();  // Sliver.
      if (soup.points && rng.P(0.05)) d = b = a;                                // A point.
      for (const Eigen::Vector3d& v : {a, b, d}) {
        mesh.indices.push_back(static_cast<uint32_t>(mesh.vertices.size()));
        mesh.vertices.push_back(v.cast<float>());
      }
    }
    env.AddMesh(mesh, "soup" + std::to_string(o));
  }
  return env;
}

// The candidate tests against their brute-force twin, the exact distance:
// for random capsules among a random soup of small and large, thin and
// sliver triangles (two objects), the pool's BVH collection lists exactly
// the triangles within the capsule, AnyWithin says whether there is one,
// and WithinCapsule gives each triangle the distance's answer; capsules are
// also shrunk to just below and just above a listed triangle's distance.
TEST(QueryPartsTest, CandidateTestsGiveTheDistancesAnswer) {
  Rng rng(0xca9d);
  const Environment env = TwoSoups(rng, Soup{400, 1.5, 0.5, 3, 0.3, /*points=*/true});
  std::vector<Link> links(1);
  links[0].name = "l";
  links[0].radius = 0.05;
  const Skeleton skeleton = Skeleton::FromLinks("one", links, "query_parts_test");
  const CollisionFilter filter(1, env.num_objects());
  const EnvironmentTarget target(skeleton, env, filter);
  int64_t tests = 0;
  int listed_total = 0, disagreements = 0, budget_undecided = 0;
  auto check = [&](const LinkCapsule& cap) {
    std::vector<Candidate> want;
    for (int o = 0; o < env.num_objects(); ++o) {
      const TriangleBvh& bvh = env.object(o).bvh;
      for (uint32_t slot = 0; slot < bvh.num_triangles(); ++slot) {
        Eigen::Vector3d ta, tb, tc;
        bvh.Triangle(slot, &ta, &tb, &tc);
        const bool within =
            SegmentTriangleDistance(cap.a, cap.b, ta, tb, tc).distance <= cap.radius;
        const Candidate c{static_cast<uint32_t>(o), slot};
        disagreements += target.WithinCapsule(cap, c) != within;
        if (within) want.push_back(c);
      }
    }
    CandidatePool pool(target, 1 << 20, &tests);
    EXPECT_TRUE(pool.CollectFromBvh(cap));
    std::vector<Candidate> got(pool.entries().begin(), pool.entries().end());
    auto key = [](const Candidate& c) { return (uint64_t{c.object} << 32) | c.slot; };
    auto less = [&](const Candidate& x, const Candidate& y) { return key(x) < key(y); };
    std::sort(got.begin(), got.end(), less);
    std::sort(want.begin(), want.end(), less);
    EXPECT_EQ(got.size(), want.size());
    for (size_t k = 0; k < std::min(got.size(), want.size()); ++k) {
      EXPECT_EQ(key(got[k]), key(want[k]));
    }
    for (int o = 0; o < env.num_objects(); ++o) {
      const bool any = std::any_of(want.begin(), want.end(),
                                   [&](const Candidate& c) { return c.object == uint32_t(o); });
      EXPECT_EQ(pool.AnyWithin(cap, ObjectIndex(o), 0), any);
      // The budgeted search: never the wrong answer, only undecided, and
      // decided when the budget covers every primitive.
      using Search = CandidatePool::Search;
      for (int budget : {0, 1, 4, 16}) {
        const Search got = pool.AnyWithinBudget(cap, ObjectIndex(o), 0, budget);
        EXPECT_TRUE(got != Search::kFound || any) << "budget " << budget;
        EXPECT_TRUE(got != Search::kNone || !any) << "budget " << budget;
        budget_undecided += got == Search::kUndecided;
      }
      EXPECT_EQ(pool.AnyWithinBudget(cap, ObjectIndex(o), 0, 1 << 30),
                any ? Search::kFound : Search::kNone);
    }
    listed_total += static_cast<int>(want.size());
    return want;
  };
  for (int i = 0; i < 300; ++i) {
    LinkCapsule cap;
    cap.link = LinkIndex(0);
    cap.a = rng.Box(1.8);
    cap.b = rng.P(0.1) ? cap.a : Eigen::Vector3d(cap.a + rng.U(0, 1) * rng.Dir());
    cap.radius = rng.U(0.001, 0.4);
    const std::vector<Candidate> listed = check(cap);
    if (listed.empty()) continue;
    // At a listed triangle's distance: the radius one step either side.
    const Candidate c = listed[rng.I(static_cast<int>(listed.size()))];
    Eigen::Vector3d ta, tb, tc;
    env.object(static_cast<int>(c.object)).bvh.Triangle(c.slot, &ta, &tb, &tc);
    const double d = SegmentTriangleDistance(cap.a, cap.b, ta, tb, tc).distance;
    if (d <= 0) continue;
    for (double r : {std::nextafter(d, 0.0), d, d * (1 + 1e-9)}) {
      cap.radius = r;
      check(cap);
    }
  }
  EXPECT_EQ(disagreements, 0);
  EXPECT_GT(listed_total, 1000);    // Capsules that meet triangles, not only misses.
  EXPECT_GT(budget_undecided, 50);  // Budgets that run out before the answer.
}

// EnvironmentTarget::Separation against its brute-force twin, the least
// exact distance over every triangle the filter keeps, with and without a
// starting triangle: the one TouchesAt names (it must touch), a random one
// (near, far, or on an object the filter ignores), a crossing one (distance
// 0: the search may stop there), and indices out of range (ignored). The
// separation is the least distance less the radius, to the bit, and the
// witness's triangle is at that distance. Half the links ignore object 1.
TEST(QueryPartsTest, SeparationFromAStartingTriangleIsTheLeastDistance) {
  Rng rng(0x5e9a);
  const Environment env = TwoSoups(rng, Soup{300, 1.0, 0.3, 2, 0.2, /*points=*/false});
  std::vector<Link> links(2);
  for (int l = 0; l < 2; ++l) {
    links[l].name = "l" + std::to_string(l);
    links[l].b_L = Eigen::Vector3d(0, 0.3, 0);
    links[l].radius = 0.08;
    links[l].parent = l == 0 ? -1 : 0;
  }
  const Skeleton skeleton = Skeleton::FromLinks("two", links, "query_parts_test");
  CollisionFilter filter(2, env.num_objects());
  filter.Ignore(LinkIndex(1), ObjectIndex(1));
  const EnvironmentTarget target(skeleton, env, filter);
  int touching = 0, crossing = 0, crossing_starts = 0, ignored_starts = 0, started = 0;
  for (int i = 0; i < 400; ++i) {
    const LinkIndex link(i % 2);
    const double radius = skeleton.link(link).radius;
    const Pose pose = RandomPose(rng, 0, 2);
    const PairMotion motion(skeleton, pose, pose, MotionModel::kIndependent);
    Eigen::Vector3d sa, sb;
    motion.SegmentAt(link, 0.0, &sa, &sb);
    double least = HUGE_VAL, least_ignored = HUGE_VAL;
    std::vector<Candidate> all, crossings;
    Candidate nearest_ignored{0, 0};
    for (int o = 0; o < env.num_objects(); ++o) {
      const TriangleBvh& bvh = env.object(o).bvh;
      for (uint32_t slot = 0; slot < bvh.num_triangles(); ++slot) {
        all.push_back(Candidate{static_cast<uint32_t>(o), slot});
        Eigen::Vector3d ta, tb, tc;
        bvh.Triangle(slot, &ta, &tb, &tc);
        const double d = SegmentTriangleDistance(sa, sb, ta, tb, tc).distance;
        if (filter.Ignores(link, ObjectIndex(o))) {
          if (d < least_ignored) {
            least_ignored = d;
            nearest_ignored = all.back();
          }
          continue;
        }
        least = std::min(least, d);
        if (d == 0) crossings.push_back(all.back());
      }
    }
    const double search = rng.P(0.5) ? 0.0 : rng.U(0, 0.5);
    const bool expect_found = least <= radius + search;
    Candidate hit{0, 0};
    const bool touches = target.TouchesAt(motion, link, 0.0, 0.0, &hit);
    EXPECT_EQ(touches, least <= radius);
    std::vector<Candidate> starts;
    if (touches) {
      ++touching;
      EXPECT_FALSE(filter.Ignores(link, ObjectIndex(static_cast<int>(hit.object))));
      Eigen::Vector3d ta, tb, tc;
      env.object(static_cast<int>(hit.object)).bvh.Triangle(hit.slot, &ta, &tb, &tc);
      EXPECT_LE(SegmentTriangleDistance(sa, sb, ta, tb, tc).distance, radius);
      starts.push_back(hit);
    }
    starts.push_back(all[rng.I(static_cast<int>(all.size()))]);
    // The nearest triangle the filter ignores, often nearer than any kept.
    if (least_ignored < least && least_ignored <= radius + search) {
      starts.push_back(nearest_ignored);
      ++ignored_starts;
    }
    if (!crossings.empty()) {
      ++crossing;
      starts.push_back(crossings[rng.I(static_cast<int>(crossings.size()))]);
      ++crossing_starts;
    }
    starts.push_back(Candidate{static_cast<uint32_t>(env.num_objects()), 0});  // No such object.
    starts.push_back(Candidate{0, 1u << 30});                                  // No such slot.
    auto check = [&](const Candidate* near) {
      ContactRecord record;
      const bool found = target.Separation(motion, link, 0.0, search, &record, near);
      EXPECT_EQ(found, expect_found);
      if (!found || !expect_found) return;
      EXPECT_EQ(record.separation, least - radius);
      EXPECT_FALSE(filter.Ignores(link, ObjectIndex(record.object)));
      const TriangleBvh& bvh = env.object(record.object).bvh;
      uint32_t slot = 0;
      while (slot < bvh.num_triangles() && bvh.TriangleId(slot) != record.triangle) ++slot;
      ASSERT_LT(slot, bvh.num_triangles());
      Eigen::Vector3d ta, tb, tc;
      bvh.Triangle(slot, &ta, &tb, &tc);
      EXPECT_EQ(SegmentTriangleDistance(sa, sb, ta, tb, tc).distance, least);
    };
    check(nullptr);
    for (const Candidate& c : starts) {
      check(&c);
      ++started;
    }
  }
  EXPECT_GT(touching, 40);         // Links that touch, not only misses,
  EXPECT_GT(crossing_starts, 10);  // searches that start on a crossing triangle,
  EXPECT_GT(ignored_starts, 20);   // and on a nearer triangle the filter ignores.
  EXPECT_GT(started, 1200);
  EXPECT_EQ(crossing, crossing_starts);
}

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

// What a query skips for the device descent: exactly the dyadic intervals
// marked, at their own depth, and nothing outside the recorded levels.
TEST(QueryPartsTest, PairClearsMatchOnlyTheMarkedDyadicIntervals) {
  PairClears c;
  c.Reset(3, 4);
  EXPECT_EQ(c.count(), 0);
  c.Set(LinkIndex(1), 0, 0);  // [0, 1]
  c.Set(LinkIndex(1), 3, 5);  // [5/8, 6/8]
  c.Set(LinkIndex(2), 2, 3);  // [3/4, 1]
  c.Set(LinkIndex(2), 4, 0);  // Depth 4 is not recorded: ignored.
  c.Set(LinkIndex(2), 1, 2);  // k out of range: ignored.
  c.Set(LinkIndex(7), 0, 0);  // No such link: ignored.
  EXPECT_EQ(c.count(), 3);
  EXPECT_TRUE(c.Cleared(LinkIndex(1), 0, 0.0, 1.0));
  EXPECT_TRUE(c.Cleared(LinkIndex(1), 3, 0.625, 0.75));
  EXPECT_TRUE(c.Cleared(LinkIndex(2), 2, 0.75, 1.0));
  EXPECT_FALSE(c.Cleared(LinkIndex(0), 0, 0.0, 1.0));     // Another link.
  EXPECT_FALSE(c.Cleared(LinkIndex(1), 3, 0.5, 0.625));   // Another interval.
  EXPECT_FALSE(c.Cleared(LinkIndex(1), 2, 0.625, 0.75));  // Not its depth.
  EXPECT_FALSE(c.Cleared(LinkIndex(1), 3, 0.625, 0.7));   // Not its end.
  EXPECT_FALSE(c.Cleared(LinkIndex(1), 3, std::nextafter(0.625, 1.0), 0.75));
  EXPECT_FALSE(c.Cleared(LinkIndex(2), 4, 0.0, 0.0625));  // Below the levels.
  EXPECT_FALSE(c.Cleared(LinkIndex(2), 2, std::nan(""), 1.0));
  EXPECT_FALSE(c.Cleared(LinkIndex(), 0, 0.0, 1.0));
  // A word: only the bits of recorded depths (15 for 4 levels) are kept.
  c.SetWord(LinkIndex(0), 0xFFFFFFFFu);
  EXPECT_EQ(c.count(), 3 + 15);
  EXPECT_TRUE(c.Cleared(LinkIndex(0), 3, 0.875, 1.0));
  c.Reset(3, PairClears::kMaxLevels + 3);  // Clamped.
  EXPECT_EQ(c.levels(), PairClears::kMaxLevels);
  EXPECT_EQ(c.count(), 0);
}

}  // namespace
}  // namespace sweptccd::internal
