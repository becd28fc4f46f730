// The device descent (core/gpu/device_descent.h) on llvmpipe in CI: the
// intervals it clears against their brute-force twin (the CPU's capsule of
// the same interval, tested against every unfiltered triangle with the
// exact double distance: every device-cleared interval must be one the CPU
// clears), and the records of queries that skip what it cleared against the
// CPU backend's, on seeded random pairs and on the real data, with budgets
// that cut pairs short, and capsules placed within the device's rounding
// growth of a triangle.

#include "core/gpu/device_descent.h"

#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <limits>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "core/avatar/motion.h"
#include "core/geometry/mesh.h"
#include "core/gpu/gl_context.h"
#include "core/query/swept_bounds.h"
#include "mocap/mocap_import.h"
#include "tests/common/brute_force.h"
#include "tests/common/random.h"
#include "tests/common/same_record.h"

namespace sweptccd::gpu {
namespace {

using Eigen::Vector3d;
using testing::Rng;

const std::string kData = SWEPTCCD_DATA_DIR;

std::shared_ptr<GlContext> SharedContext() {
  static std::shared_ptr<GlContext> context = std::make_shared<GlContext>();
  return context;
}

// A chain of `n` links, 0.3 m each along x, radius 4 cm.
Skeleton Chain(int n) {
  std::string links;
  for (int i = 0; i < n; ++i) {
    if (i > 0) links += ",";
    links += "{\"name\": \"l" + std::to_string(i) + "\", \"parent\": " +
             (i == 0 ? std::string("null") : "\"l" + std::to_string(i - 1) + "\"") +
             ", \"a\": [0, 0, 0], \"b\": [0.3, 0, 0], \"radius\": 0.04}";
  }
  return ParseSkeletonJson("{\"name\": \"chain\", \"links\": [" + links + "]}", "test chain");
}

// Random triangles (some slivers and degenerate ones) in a box of half size
// `half` around `centre`.
TriangleMesh Soup(Rng& rng, const Vector3d& centre, int count, double half) {
  TriangleMesh m;
  for (int t = 0; t < count; ++t) {
    const Vector3d a = centre + rng.Box(half);
    Vector3d b = a + rng.Box(0.3), c = a + rng.Box(0.3);
    const int kind = rng.I(10);
    if (kind == 0) c = a + 0.5 * (b - a);
    if (kind == 1) c = a + 0.5 * (b - a) + 1e-7 * rng.Dir();
    for (const Vector3d& v : {a, b, c}) {
      m.indices.push_back(static_cast<uint32_t>(m.vertices.size()));
      m.vertices.push_back(v.cast<float>());
    }
  }
  return m;
}

// A pose of the chain: every link frame near `centre`, the next link at the
// end of its parent, turned at random.
Pose ChainPose(Rng& rng, const Skeleton& skeleton, const Vector3d& centre, int64_t utime) {
  Pose pose;
  pose.utime = utime;
  Vector3d p = centre + rng.Box(0.3);
  for (int l = 0; l < skeleton.num_links(); ++l) {
    LinkPose lp;
    lp.q = rng.Quat();
    lp.p = p;
    p = lp.p + lp.q * Vector3d(0.3, 0, 0);
    pose.links.push_back(lp);
  }
  return pose;
}

// The same pose moved a little: translated up to `move` metres and every
// link turned by up to `turn` radians.
Pose Moved(Rng& rng, const Pose& pose0, double move, double turn, int64_t utime) {
  Pose pose = pose0;
  pose.utime = utime;
  const Vector3d shift = rng.Box(move);
  for (LinkPose& lp : pose.links) {
    lp.p += shift;
    lp.q = (rng.Turn(rng.U(0, turn)) * lp.q).normalized();
  }
  return pose;
}

// The CPU descent's capsule of interval k of 2^depth of `link` (the same
// SweptBounds, the same segment ends as its halving computes them).
LinkCapsule CpuCapsule(const CcdEngine& engine, const PairMotion& motion, LinkIndex link, int depth,
                       uint32_t k) {
  const sweptccd::internal::SweptBounds bounds(
      engine.skeleton(), motion,
      sweptccd::internal::SweptBounds::Tolerance(engine.environment(), motion));
  const double s0 = std::ldexp(static_cast<double>(k), -depth);
  const double s1 = std::ldexp(static_cast<double>(k + 1), -depth);
  return bounds.FromEnds(link, s0, s1, bounds.EndsOver(link, s0, s1));
}

struct TwinCounts {
  int64_t nodes = 0, device_cleared = 0, cpu_clear = 0, misses = 0;
  int64_t covered = 0;  // Cleared, or below an interval cleared (never tested).
};

// Every interval the device cleared, against its brute-force twin: the
// CPU's capsule of that interval meets no unfiltered triangle.
// With `all` false only the cleared intervals are measured (the real
// scenes' triangles are many), and only every fourth pair's.
void CheckTwin(const CcdEngine& engine, const Pose& pose0, const Pose& pose1,
               const QueryOptions& options, const PairClears& clears, bool all,
               TwinCounts* counts) {
  const PairMotion motion(engine.skeleton(), pose0, pose1, options.motion);
  for (LinkIndex l(0); l < engine.skeleton().num_links(); ++l) {
    std::vector<char> covered(size_t{1} << clears.levels(), 0);  // By heap index.
    for (int d = 0; d < clears.levels(); ++d) {
      for (uint32_t k = 0; k < (1u << d); ++k) {
        const double s0 = std::ldexp(static_cast<double>(k), -d);
        const double s1 = std::ldexp(static_cast<double>(k + 1), -d);
        const bool cleared = clears.Cleared(l, d, s0, s1);
        const size_t h = (size_t{1} << d) - 1 + k;
        covered[h] = cleared || (d > 0 && covered[(size_t{1} << (d - 1)) - 1 + k / 2]);
        counts->covered += covered[h];
        if (!all && !cleared) continue;
        const LinkCapsule c = CpuCapsule(engine, motion, l, d, k);
        const testing::BruteNearest n =
            testing::BruteForceNearest(engine.environment(), engine.filter(), l, c.a, c.b);
        const bool cpu_clear = !n.any || n.distance > c.radius;
        ++counts->nodes;
        counts->device_cleared += cleared;
        counts->cpu_clear += cpu_clear;
        if (cleared && !cpu_clear && ++counts->misses <= 5) {
          ADD_FAILURE() << "link " << l << " depth " << d << " k " << k
                        << " cleared on the device but the CPU's capsule (radius " << c.radius
                        << ") is " << n.distance << " from a triangle";
        }
      }
    }
  }
}

struct RandomScene {
  Environment env;
  Skeleton skeleton = Chain(4);
  std::vector<std::pair<Pose, Pose>> pairs;
};

RandomScene MakeRandomScene(uint64_t seed, const Vector3d& centre, int pairs) {
  Rng rng(seed);
  RandomScene scene;
  scene.env.AddMesh(Soup(rng, centre, 300, 1.5), "soup a");
  scene.env.AddMesh(Soup(rng, centre + Vector3d(0.5, 0, 0), 100, 1.0), "soup b");
  for (int i = 0; i < pairs; ++i) {
    const Pose p0 = ChainPose(rng, scene.skeleton, centre + rng.Box(1.0), 1000000);
    const Pose p1 = Moved(rng, p0, rng.P(0.5) ? 0.02 : 0.3, rng.P(0.5) ? 0.05 : 0.8, 1033333);
    scene.pairs.emplace_back(p0, p1);
  }
  return scene;
}

// Runs the descent on every pair of `scene` in one batch, then each query
// with and without the clears; returns the descent's counts.
DescentStats CompareRecords(const Environment& env, const CcdEngine& engine,
                            const std::vector<std::pair<Pose, Pose>>& pairs,
                            const QueryOptions& options, const DescentOptions& descent_options,
                            const std::string& what, TwinCounts* twin = nullptr,
                            int64_t* skipped = nullptr, bool twin_all = true) {
  auto gpu_env = std::make_shared<const GpuEnvironment>(SharedContext(), env);
  DeviceDescent descent(gpu_env, env, descent_options);
  const int e = descent.AddEngine(engine);
  std::vector<DeviceDescent::Pair> batch;
  for (const auto& [p0, p1] : pairs) batch.push_back({e, &p0, &p1, {}});
  std::vector<PairClears> clears;
  EXPECT_TRUE(descent.Run(batch, options, &clears));
  EXPECT_EQ(clears.size(), pairs.size());
  for (size_t i = 0; i < pairs.size(); ++i) {
    const QueryResult cpu = engine.Query(pairs[i].first, pairs[i].second, options);
    const QueryResult dev = engine.Query(pairs[i].first, pairs[i].second, options, &clears[i]);
    EXPECT_EQ(testing::RecordDifference(cpu, dev), "") << what << ", pair " << i;
    if (skipped != nullptr) *skipped += dev.stats.cull_cleared;
    if (twin != nullptr && (twin_all || i % 4 == 0)) {
      CheckTwin(engine, pairs[i].first, pairs[i].second, options, clears[i], twin_all, twin);
    }
  }
  return descent.stats();
}

TEST(DeviceDescentTest, ClearedIntervalsAreClearedByTheCpuBruteForce) {
  for (const Vector3d& centre : {Vector3d(0, 0, 0), Vector3d(1000, -700, 300)}) {
    RandomScene scene = MakeRandomScene(30, centre, 40);
    const CcdEngine engine(scene.skeleton, scene.env);
    TwinCounts twin;
    const DescentStats stats = CompareRecords(scene.env, engine, scene.pairs, QueryOptions(),
                                              DescentOptions(), "twin", &twin);
    std::printf(
        "centre %.0f: %lld intervals, %lld cleared on the device (%lld with those "
        "below them), %lld clear for the CPU; %lld dispatches, %lld items\n",
        centre.x(), static_cast<long long>(twin.nodes), static_cast<long long>(twin.device_cleared),
        static_cast<long long>(twin.covered), static_cast<long long>(twin.cpu_clear),
        static_cast<long long>(stats.dispatches), static_cast<long long>(stats.items));
    EXPECT_EQ(twin.misses, 0);
    // Not vacuous: the device clears much of what is clear, at every depth,
    // and the CPU has intervals left to decide.
    EXPECT_GT(twin.covered, twin.cpu_clear / 2);
    EXPECT_LT(twin.cpu_clear, twin.nodes);
    EXPECT_GE(stats.dispatches, 3);  // The whole pairs, then the levels below.
  }
}

TEST(DeviceDescentTest, RecordsEqualTheCpuBackendOnRandomPairs) {
  RandomScene scene = MakeRandomScene(31, Vector3d(0.2, 0.1, -0.3), 120);
  // A filter: link 1 ignores the second soup.
  CollisionFilter filter(scene.skeleton.num_links(), scene.env.num_objects());
  filter.Ignore(LinkIndex(1), ObjectIndex(1));
  const CcdEngine engine(scene.skeleton, scene.env, filter);
  int64_t skipped = 0;
  QueryOptions options;
  DescentStats stats = CompareRecords(scene.env, engine, scene.pairs, options, DescentOptions(),
                                      "first contact", nullptr, &skipped);
  EXPECT_GT(stats.cleared, 0);
  EXPECT_GT(skipped, 0) << "no query skipped a device-cleared interval";
  options.per_link = true;
  stats = CompareRecords(scene.env, engine, scene.pairs, options, DescentOptions(), "per link");
  EXPECT_GT(stats.cleared, 0);
  options.per_link = false;
  options.motion = MotionModel::kIndependent;
  stats = CompareRecords(scene.env, engine, scene.pairs, options, DescentOptions(), "independent");
  EXPECT_GT(stats.cleared, 0);
  int contacts = 0, free_pairs = 0;
  for (const auto& [p0, p1] : scene.pairs) {
    const QueryResult r = engine.Query(p0, p1, QueryOptions());
    contacts += r.contact;
    free_pairs += !r.contact;
  }
  EXPECT_GT(contacts, 10);
  EXPECT_GT(free_pairs, 10);
}

TEST(DeviceDescentTest, PairsOverBudgetAreFinishedByTheCpuIdentically) {
  RandomScene scene = MakeRandomScene(32, Vector3d(0, 0, 0), 60);
  const CcdEngine engine(scene.skeleton, scene.env);
  DescentOptions tight;
  tight.pair_budget = 6;  // Three links' halves, then nothing deeper.
  TwinCounts twin;
  DescentStats stats =
      CompareRecords(scene.env, engine, scene.pairs, QueryOptions(), tight, "pair budget", &twin);
  EXPECT_GT(stats.over_budget, 0);
  EXPECT_EQ(twin.misses, 0);
  DescentOptions small_queue;
  small_queue.queue_capacity = 8;
  twin = TwinCounts();
  stats = CompareRecords(scene.env, engine, scene.pairs, QueryOptions(), small_queue,
                         "queue capacity", &twin);
  EXPECT_GT(stats.over_budget, 0);
  EXPECT_EQ(twin.misses, 0);
  DescentOptions one_level;
  one_level.levels = 1;  // The whole pairs only.
  stats = CompareRecords(scene.env, engine, scene.pairs, QueryOptions(), one_level, "one level");
  EXPECT_EQ(stats.dispatches, 1);
}

// The host's preparation on several threads (DescentOptions::host_threads)
// sends the same tracks, grid and items as on one: with budgets no pair
// reaches (so no item is dropped in the atomics' order), every pair's
// cleared intervals are the same bits, and the counts the same.
TEST(DeviceDescentTest, HostThreadsGiveTheSameClears) {
  RandomScene scene = MakeRandomScene(34, Vector3d(0.1, -0.2, 0), 90);
  const CcdEngine engine(scene.skeleton, scene.env);
  auto gpu_env = std::make_shared<const GpuEnvironment>(SharedContext(), scene.env);
  std::vector<PairClears> clears[2];
  DescentStats stats[2];
  for (int run = 0; run < 2; ++run) {
    DescentOptions options;
    options.pair_budget = 1 << 20;
    options.host_threads = run == 0 ? 1 : 3;
    DeviceDescent descent(gpu_env, scene.env, options);
    const int e = descent.AddEngine(engine);
    std::vector<DeviceDescent::Pair> batch;
    for (const auto& [p0, p1] : scene.pairs) batch.push_back({e, &p0, &p1, {}});
    ASSERT_TRUE(descent.Run(batch, QueryOptions(), &clears[run]));
    stats[run] = descent.stats();
  }
  EXPECT_EQ(stats[0].over_budget, 0);
  EXPECT_GT(stats[0].cleared, 0);
  EXPECT_EQ(stats[1].tracks, stats[0].tracks);
  EXPECT_EQ(stats[1].items, stats[0].items);
  EXPECT_EQ(stats[1].cleared, stats[0].cleared);
  EXPECT_EQ(stats[1].dispatches, stats[0].dispatches);
  ASSERT_EQ(clears[1].size(), clears[0].size());
  for (size_t i = 0; i < clears[0].size(); ++i) {
    for (LinkIndex l(0); l < scene.skeleton.num_links(); ++l) {
      for (int d = 0; d < clears[0][i].levels(); ++d) {
        for (uint32_t k = 0; k < (1u << d); ++k) {
          const double s0 = std::ldexp(static_cast<double>(k), -d);
          const double s1 = std::ldexp(static_cast<double>(k + 1), -d);
          EXPECT_EQ(clears[1][i].Cleared(l, d, s0, s1), clears[0][i].Cleared(l, d, s0, s1))
              << "pair " << i << " link " << l << " depth " << d << " k " << k;
        }
      }
    }
  }
}

// One batch mixing engines of different link counts and filters (the
// daemon's clients, `sweptccd world`'s avatars) and both motion models, its
// preparation on one thread and on three: the pairs' slots of the
// preparation (first_link) differ from pair to pair, the pool's chunks
// split them anywhere, and each track must carry its own engine's filter.
// The same clears on both, and every interval cleared is clear for the CPU's
// capsule under that pair's engine's filter (the brute-force twin).
TEST(DeviceDescentTest, MixedEnginesBatchOnThreadsClearsOnlyWhatTheCpuClears) {
  Rng rng(36);
  const Vector3d centre(0.1, 0, 0.2);
  Environment env;
  env.AddMesh(Soup(rng, centre, 300, 1.5), "soup a");
  env.AddMesh(Soup(rng, centre + Vector3d(0.5, 0, 0), 100, 1.0), "soup b");
  const Skeleton chains[3] = {Chain(4), Chain(7), Chain(1)};
  // Engine 1 ignores soup a on every link but its first, engine 2 soup b:
  // a track given another engine's masks clears intervals its own filter
  // does not.
  CollisionFilter f0(4, 2), f1(7, 2), f2(1, 2);
  for (LinkIndex l(1); l < 7; ++l) f1.Ignore(l, ObjectIndex(0));
  f2.Ignore(LinkIndex(0), ObjectIndex(1));
  const CcdEngine engines[3] = {CcdEngine(chains[0], env, f0), CcdEngine(chains[1], env, f1),
                                CcdEngine(chains[2], env, f2)};
  struct MixedPair {
    int engine;
    Pose p0, p1;
    std::optional<MotionModel> motion;
  };
  std::vector<MixedPair> pairs;
  for (int i = 0; i < 96; ++i) {
    MixedPair p;
    p.engine = rng.I(3);
    p.p0 = ChainPose(rng, chains[p.engine], centre + rng.Box(1.0), 1000000);
    p.p1 = Moved(rng, p.p0, rng.P(0.5) ? 0.02 : 0.3, rng.P(0.5) ? 0.05 : 0.8, 1033333);
    if (rng.P(0.3)) p.motion = MotionModel::kIndependent;
    pairs.push_back(std::move(p));
  }
  auto gpu_env = std::make_shared<const GpuEnvironment>(SharedContext(), env);
  std::vector<PairClears> clears[2];
  DescentStats stats[2];
  for (int run = 0; run < 2; ++run) {
    DescentOptions options;
    options.pair_budget = 1 << 20;  // No item dropped in the atomics' order.
    options.host_threads = run == 0 ? 1 : 3;
    DeviceDescent descent(gpu_env, env, options);
    int slot[3];
    for (int e = 0; e < 3; ++e) slot[e] = descent.AddEngine(engines[e]);
    std::vector<DeviceDescent::Pair> batch;
    for (const MixedPair& p : pairs) batch.push_back({slot[p.engine], &p.p0, &p.p1, p.motion});
    ASSERT_TRUE(descent.Run(batch, QueryOptions(), &clears[run]));
    stats[run] = descent.stats();
  }
  EXPECT_EQ(stats[0].over_budget, 0);
  EXPECT_GT(stats[0].cleared, 0);
  EXPECT_EQ(stats[1].tracks, stats[0].tracks);
  EXPECT_EQ(stats[1].items, stats[0].items);
  EXPECT_EQ(stats[1].cleared, stats[0].cleared);
  ASSERT_EQ(clears[1].size(), pairs.size());
  TwinCounts twin;
  int64_t per_engine_cleared[3] = {0, 0, 0};
  for (size_t i = 0; i < pairs.size(); ++i) {
    const MixedPair& p = pairs[i];
    const CcdEngine& engine = engines[p.engine];
    for (LinkIndex l(0); l < engine.skeleton().num_links(); ++l) {
      for (int d = 0; d < clears[0][i].levels(); ++d) {
        for (uint32_t k = 0; k < (1u << d); ++k) {
          const double s0 = std::ldexp(static_cast<double>(k), -d);
          const double s1 = std::ldexp(static_cast<double>(k + 1), -d);
          EXPECT_EQ(clears[1][i].Cleared(l, d, s0, s1), clears[0][i].Cleared(l, d, s0, s1))
              << "pair " << i << " link " << l << " depth " << d << " k " << k;
        }
      }
    }
    per_engine_cleared[p.engine] += clears[1][i].count();
    QueryOptions options;
    options.motion = p.motion.value_or(options.motion);
    CheckTwin(engine, p.p0, p.p1, options, clears[1][i], /*all=*/true, &twin);
    const QueryResult cpu = engine.Query(p.p0, p.p1, options);
    const QueryResult dev = engine.Query(p.p0, p.p1, options, &clears[1][i]);
    EXPECT_EQ(testing::RecordDifference(cpu, dev), "") << "pair " << i;
  }
  EXPECT_EQ(twin.misses, 0);
  for (int e = 0; e < 3; ++e) EXPECT_GT(per_engine_cleared[e], 0) << "engine " << e;
  std::printf("mixed batch: %lld tracks, %lld cleared (%lld, %lld, %lld by engine)\n",
              static_cast<long long>(stats[1].tracks), static_cast<long long>(stats[1].cleared),
              static_cast<long long>(per_engine_cleared[0]),
              static_cast<long long>(per_engine_cleared[1]),
              static_cast<long long>(per_engine_cleared[2]));
}

// The descent's step cap (DescentOptions::max_steps): a search past it
// answers "may touch", its node's halves are tested and the CPU decides the
// rest. With a cap of one step no search can end, so nothing is cleared;
// with a small cap some are; either way nothing the CPU would not clear and
// the records are the CPU backend's.
TEST(DeviceDescentTest, ATinyStepCapClearsOnlyWhatTheCpuClears) {
  RandomScene scene = MakeRandomScene(35, Vector3d(0, 0.3, 0), 50);
  const CcdEngine engine(scene.skeleton, scene.env);
  DescentOptions one_step;
  one_step.max_steps = 1;
  TwinCounts twin;
  DescentStats stats =
      CompareRecords(scene.env, engine, scene.pairs, QueryOptions(), one_step, "cap 1", &twin);
  EXPECT_EQ(twin.misses, 0);
  EXPECT_EQ(stats.cleared, 0);
  EXPECT_GT(stats.items, stats.tracks);  // Every whole pair "may touch": halves tested.
  DescentOptions few_steps;
  few_steps.max_steps = 24;
  twin = TwinCounts();
  const DescentStats few =
      CompareRecords(scene.env, engine, scene.pairs, QueryOptions(), few_steps, "cap 24", &twin);
  EXPECT_EQ(twin.misses, 0);
  EXPECT_GT(few.cleared, 0);
  const DescentStats full = CompareRecords(scene.env, engine, scene.pairs, QueryOptions(),
                                           DescentOptions(), "default cap");
  std::printf("cleared with a cap of 1, 24 and %d steps: %lld, %lld, %lld\n",
              DescentOptions().max_steps, static_cast<long long>(stats.cleared),
              static_cast<long long>(few.cleared), static_cast<long long>(full.cleared));
}

// A still link (its growth is the rounding slack alone) with a small
// triangle in the plane tangent to the CPU's capsule of the whole pair, at
// the capsule's distance (touching) or a little farther but within the
// device's growth (2^-17 of the radius): no interval may be cleared,
// though the CPU's exact test would clear the second kind. The same
// triangle 20 % of the radius farther is cleared (so the test can fail).
TEST(DeviceDescentTest, CapsulesWithinTheRoundingGrowthOfATriangleAreNeverCleared) {
  Rng rng(33);
  const Skeleton skeleton = Chain(1);
  int touching = 0, within_growth = 0, cleared_far = 0, far = 0;
  for (const double scale : {1.0, 1e3, 1e5}) {
    for (int i = 0; i < 30; ++i) {
      Pose p0;
      p0.utime = 0;
      p0.links.push_back(LinkPose{scale * rng.Box(1.0), rng.Quat()});
      Pose p1 = p0;
      p1.utime = 33333;
      const int kind = i % 3;  // Touching, within the growth, 20 % farther.
      // The capsule, with an empty environment's tolerance first.
      Environment probe;
      const CcdEngine probe_engine(skeleton, probe);
      const PairMotion motion(skeleton, p0, p1, MotionModel::kArticulated);
      LinkCapsule c = CpuCapsule(probe_engine, motion, LinkIndex(0), 0, 0);
      const Vector3d axis = (c.b - c.a).normalized();
      const Vector3d n = rng.Perp(axis);
      const Vector3d x = c.a + rng.U(0.2, 0.8) * (c.b - c.a);
      const double extra = kind == 0 ? 0.0 : kind == 1 ? std::ldexp(c.radius, -18) : 0.2 * c.radius;
      const Vector3d y = x + n * (c.radius + extra);
      const Vector3d u = n.cross(axis).normalized(), v = axis;
      TriangleMesh m;
      for (const Vector3d& vert : {Vector3d(y + 0.01 * u), Vector3d(y - 0.01 * u + 0.01 * v),
                                   Vector3d(y - 0.01 * u - 0.01 * v)}) {
        m.indices.push_back(static_cast<uint32_t>(m.vertices.size()));
        m.vertices.push_back(vert.cast<float>());
      }
      Environment env;
      env.AddMesh(m, "tangent");
      const CcdEngine engine(skeleton, env);
      // The environment's own tolerance may differ: measure against its capsule.
      c = CpuCapsule(engine, motion, LinkIndex(0), 0, 0);
      const CollisionFilter none(1, 1);
      const double distance =
          testing::BruteForceNearest(env, none, LinkIndex(0), c.a, c.b).distance;
      auto gpu_env = std::make_shared<const GpuEnvironment>(SharedContext(), env);
      DeviceDescent descent(gpu_env, env, DescentOptions());
      const int e = descent.AddEngine(engine);
      std::vector<PairClears> clears;
      ASSERT_TRUE(descent.Run({{e, &p0, &p1, {}}}, QueryOptions(), &clears));
      const int64_t count = clears[0].count();
      // Within 2^-17 of the radius (the float vertices moved it by less at
      // these scales, or it is touching): the device's radius is larger.
      if (distance <= c.radius * (1 + std::ldexp(1.0, -17))) {
        touching += distance <= c.radius;
        within_growth += distance > c.radius;
        EXPECT_EQ(count, 0) << "scale " << scale << " kind " << kind << ": distance " << distance
                            << ", CPU radius " << c.radius;
      }
      if (kind == 2) {
        ++far;
        cleared_far += clears[0].Cleared(LinkIndex(0), 0, 0.0, 1.0);
      }
    }
  }
  std::printf("%d touching, %d within the growth (CPU-clear), %d of %d far ones cleared\n",
              touching, within_growth, cleared_far, far);
  EXPECT_GE(touching, 5);
  EXPECT_GE(within_growth, 5);
  EXPECT_GE(cleared_far, far / 3);
}

// The real data: a walk and a jump in the MORSE apartment (10,616
// triangles), every pair of each clip in one batch.
MocapClip LoadClip(const std::string& file) {
  const std::string path = kData + "/mocap/" + file;
  EXPECT_TRUE(std::filesystem::exists(path)) << "missing data file: " << path;
  MocapImportOptions options;
  options.up_axis = 'z';
  options.frame_step = 4;
  return ImportBvhFile(path, options);
}

double Lowest(const MocapClip& clip) {
  double lowest = std::numeric_limits<double>::infinity();
  for (const Pose& pose : clip.poses) {
    for (int l = 0; l < clip.skeleton.num_links(); ++l) {
      const Link& link = clip.skeleton.link(l);
      const Vector3d a = pose.links[l].p + pose.links[l].q * link.a_L;
      const Vector3d b = pose.links[l].p + pose.links[l].q * link.b_L;
      lowest = std::min(lowest, std::min(a.z(), b.z()) - link.radius);
    }
  }
  return lowest;
}

TEST(DeviceDescentTest, RealDataRecordsEqualTheCpuBackend) {
  Environment env;
  const std::string scene = kData + "/env/morse_apartment.ply.gz";
  ASSERT_TRUE(std::filesystem::exists(scene)) << "missing data file: " << scene;
  env.AddMesh(LoadMeshFile(scene), scene);
  int contacts = 0, free_pairs = 0;
  for (const auto& [file, where] :
       {std::pair<std::string, Vector3d>{"cmu_06_01_walk.bvh.gz", Vector3d(-0.7, 3.5, 0)},
        std::pair<std::string, Vector3d>{"cmu_02_04_jump_balance.bvh.gz",
                                         Vector3d(-2.3, -1.5, 0)}}) {
    MocapClip clip = LoadClip(file);
    ASSERT_GT(clip.poses.size(), 10u);
    Vector3d lo = Vector3d::Constant(1e30), hi = -lo;
    for (const Pose& pose : clip.poses) {
      lo = lo.cwiseMin(pose.links[clip.skeleton.root()].p);
      hi = hi.cwiseMax(pose.links[clip.skeleton.root()].p);
    }
    Vector3d offset = where - 0.5 * (lo + hi);
    offset.z() = -0.017 - 0.01 - Lowest(clip);  // Soles 1 cm into the ground plane.
    TranslateClip(&clip, offset);
    const CcdEngine engine(clip.skeleton, env);
    std::vector<std::pair<Pose, Pose>> pairs;
    for (size_t k = 0; k + 1 < clip.poses.size() && pairs.size() < 80; ++k) {
      pairs.emplace_back(clip.poses[k], clip.poses[k + 1]);
    }
    int64_t skipped = 0;
    TwinCounts twin;
    const DescentStats stats =
        CompareRecords(env, engine, pairs, QueryOptions(), DescentOptions(), file, &twin, &skipped,
                       /*twin_all=*/false);
    std::printf(
        "%s: %zu pairs, %lld tracks, %lld intervals tested and %lld cleared on the device "
        "in %lld dispatches, %lld skipped by the queries\n",
        file.c_str(), pairs.size(), static_cast<long long>(stats.tracks),
        static_cast<long long>(stats.items), static_cast<long long>(stats.cleared),
        static_cast<long long>(stats.dispatches), static_cast<long long>(skipped));
    EXPECT_EQ(twin.misses, 0);
    EXPECT_GT(stats.cleared, 0);
    for (const auto& [p0, p1] : pairs) {
      const bool contact = engine.Query(p0, p1, QueryOptions()).contact;
      contacts += contact;
      free_pairs += !contact;
    }
  }
  EXPECT_GT(contacts, 5);
  EXPECT_GT(free_pairs, 5);
}

}  // namespace
}  // namespace sweptccd::gpu
