// The GPU swept-volume test against its brute-force twin: the exact
// double-precision segment-triangle distance over every unfiltered triangle
// (core/distance.h, itself checked against golden-section search in
// distance_test.cc). The culler may keep a capsule that is clear (that only
// costs CPU time) but must never clear one that touches; and it should clear
// nearly everything that is clear by a visible margin.

#include "core/gpu/gpu_culler.h"

#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <memory>
#include <random>
#include <thread>

#include "core/geometry/distance.h"
#include "core/geometry/mesh.h"
#include "core/gpu/backend.h"
#include "core/gpu/gl_api.h"
#include "core/gpu/gl_context.h"
#include "core/query/ccd_query.h"
#include "tests/common/brute_force.h"
#include "tests/common/random.h"

namespace sweptccd::gpu {
namespace {

using Eigen::Vector3d;

using testing::Rng;

// One link from the origin of its frame to `b` (JSON array), radius 5 cm.
Skeleton OneLinkSkeleton(const std::string& b) {
  return ParseSkeletonJson(R"({"name": "one", "links": [{"name": "a", "parent": null,
                               "a": [0, 0, 0], "b": )" +
                               b + R"(, "radius": 0.05}]})",
                           "test skeleton");
}

std::shared_ptr<GlContext> SharedContext() {
  static std::shared_ptr<GlContext> context = std::make_shared<GlContext>();
  return context;
}

// A soup of random triangles (some slivers, some degenerate) around `centre`.
TriangleMesh Soup(Rng& rng, const Vector3d& centre, int count, double half) {
  TriangleMesh m;
  for (int t = 0; t < count; ++t) {
    const Vector3d a = centre + rng.Box(half);
    Vector3d b = a + rng.Box(0.3), c = a + rng.Box(0.3);
    const int kind = rng.I(12);
    if (kind == 0) c = a + 0.5 * (b - a);                     // Collinear (degenerate).
    if (kind == 1) c = b;                                     // Two equal vertices.
    if (kind == 2) c = a + 0.5 * (b - a) + 1e-7 * rng.Dir();  // Sliver.
    // Slivers whose cross product underflows in float (regression: the
    // certificate's r |n| vanished and everything was cleared).
    if (kind == 3) c = a + 0.5 * (b - a) + std::pow(10.0, -rng.U(15, 40)) * rng.Dir();
    if (kind == 4) {  // Micrometre-sized triangle.
      b = a + 1e-6 * rng.Dir();
      c = a + 1e-6 * rng.Dir();
    }
    for (const Vector3d& v : {a, b, c}) {
      m.indices.push_back(static_cast<uint32_t>(m.vertices.size()));
      m.vertices.push_back(v.cast<float>());
    }
  }
  return m;
}

struct Fixture {
  Environment env;
  CollisionFilter filter;
  int num_links = 4;
  // Exact separation (distance - radius) of a capsule from the unfiltered triangles.
  double Separation(const LinkCapsule& c) const {
    const testing::BruteNearest n = testing::BruteForceNearest(env, filter, c.link, c.a, c.b);
    return n.any ? n.distance - c.radius : 1e300;
  }
};

// Every capsule the culler clears is measured (a miss can only be one of
// those); of those it keeps, the first `measure_kept` (all by default).
// *touching, when given, counts the measured capsules that touch.
void CheckBatch(const Fixture& f, const GpuCuller& culler, const std::vector<LinkCapsule>& caps,
                const char* what, double scale, int64_t* clear, int64_t* cleared,
                size_t measure_kept = SIZE_MAX, int64_t* touching = nullptr) {
  std::vector<uint8_t> may_touch;
  ASSERT_TRUE(culler.Cull(caps, &may_touch));
  ASSERT_EQ(may_touch.size(), caps.size());
  int misses = 0;
  for (size_t i = 0; i < caps.size(); ++i) {
    if (may_touch[i] != 0 && i >= measure_kept) continue;
    const double sep = f.Separation(caps[i]);
    if (touching != nullptr) *touching += sep <= 0;
    if (sep <= 0 && may_touch[i] == 0 && ++misses <= 5) {
      const LinkCapsule& c = caps[i];
      ADD_FAILURE() << what << ": capsule " << i << " touches (separation " << sep
                    << ") but was cleared: a [" << c.a.transpose() << "] b [" << c.b.transpose()
                    << "] radius " << c.radius << " link " << c.link;
    }
    if (sep > 1e-5 * scale) {
      ++*clear;
      *cleared += may_touch[i] == 0;
    }
  }
  EXPECT_EQ(misses, 0) << what;
}

// Random scenes at the origin and 1 km away (relative rounding), random and
// exactly tangent capsules, filters on some (link, object) pairs.
TEST(GpuCullerTest, NeverClearsATouchingCapsuleRandomized) {
  int64_t clear = 0, cleared = 0, tangent = 0;
  for (uint64_t seed = 1; seed <= 6; ++seed) {
    Rng rng(seed * 7919);
    const Vector3d centre = seed % 2 == 0 ? Vector3d(1000.0, -750.0, 500.0) : Vector3d::Zero();
    const double scale = 1.0 + centre.norm();
    Fixture f;
    for (int o = 0; o < 3; ++o) {
      f.env.AddMesh(Soup(rng, centre, 120 + 40 * o, 1.5), "soup" + std::to_string(o));
    }
    f.filter = CollisionFilter(f.num_links, f.env.num_objects());
    f.filter.Ignore(LinkIndex(1), ObjectIndex(0));
    f.filter.Ignore(LinkIndex(3), ObjectIndex(2));
    if (seed == 3) f.filter.Ignore(LinkIndex(2), kAllObjects);  // Link 2 ignores everything.
    auto gpu_env = std::make_shared<const GpuEnvironment>(SharedContext(), f.env);
    const GpuCuller culler(gpu_env, f.filter, f.num_links);

    std::vector<LinkCapsule> caps;
    for (int i = 0; i < 1500; ++i) {
      LinkCapsule c;
      c.a = centre + rng.Box(2.0);
      c.b = rng.I(8) == 0 ? c.a : c.a + rng.Box(0.6);  // Some zero-length segments.
      c.radius = rng.I(6) == 0 ? 0.0 : rng.U(0.001, 0.2);
      c.link = LinkIndex(rng.I(f.num_links));
      caps.push_back(c);
    }
    // Tangent capsules: the radius set to the exact distance (touching at
    // exactly zero separation), or a hair below or above it.
    for (int i = 0; i < 1500; ++i) {
      LinkCapsule c;
      c.a = centre + rng.Box(2.0);
      c.b = c.a + rng.Box(0.4);
      c.link = LinkIndex(rng.I(f.num_links));
      c.radius = 0;
      const double d = f.Separation(c);
      if (d > 1e200) continue;
      const int kind = rng.I(3);
      c.radius = kind == 0 ? d : kind == 1 ? std::nextafter(d, 2 * d + 1) : d * (1 - 1e-7);
      tangent += kind != 2;
      caps.push_back(c);
    }
    CheckBatch(f, culler, caps, centre.norm() > 0 ? "far from the origin" : "at the origin", scale,
               &clear, &cleared);
  }
  std::printf(
      "clear by > 1e-5 of the scale: %lld, cleared by the GPU: %lld (%.2f%%); "
      "tangent capsules: %lld\n",
      static_cast<long long>(clear), static_cast<long long>(cleared),
      100.0 * cleared / std::max<int64_t>(1, clear), static_cast<long long>(tangent));
  EXPECT_GT(tangent, 3000);
  // Nearly tight: the certificate loses only rounding margins.
  EXPECT_GE(cleared, clear * 995 / 1000);
}

// Hand-made cases: a segment through a triangle, lying in its plane, parallel
// just above it, touching a vertex and an edge, and a degenerate triangle.
TEST(GpuCullerTest, HandCases) {
  Fixture f;
  TriangleMesh m;
  auto add = [&](Vector3d a, Vector3d b, Vector3d c) {
    for (const Vector3d& v : {a, b, c}) {
      m.indices.push_back(static_cast<uint32_t>(m.vertices.size()));
      m.vertices.push_back(v.cast<float>());
    }
  };
  add({0, 0, 0}, {1, 0, 0}, {0, 1, 0});
  add({5, 0, 0}, {6, 0, 0}, {7, 0, 0});               // Degenerate: a segment on the x axis.
  add({0, 20, 0}, {1, 20, 0}, {0.5, 20 + 1e-24, 0});  // Slivers (y rounds to 20 in float;
  add({0, 21, 0}, {1, 21, 0}, {0.5, 21, 1e-20});      // z keeps 1e-20).
  add({0.5, 19, 0}, {0.5 + 1e-12, 19, 0}, {0.5, 19 + 1e-12, 0});  // A 1e-12 m triangle.
  f.env.AddMesh(m, "hand");
  f.filter = CollisionFilter(f.num_links, 1);
  const GpuCuller culler(std::make_shared<const GpuEnvironment>(SharedContext(), f.env), f.filter,
                         f.num_links);
  struct Case {
    Vector3d a, b;
    double radius;
    bool touches;
    const char* name;
  };
  const std::vector<Case> cases = {
      {{0.2, 0.2, -1}, {0.2, 0.2, 1}, 0.0, true, "through the face"},
      // Coplanar: the double distance is ~6e-17 (rounding), hence the 1e-12 radius.
      {{-1, 0.3, 0}, {2, 0.3, 0}, 1e-12, true, "in the plane across it"},
      {{0, 0, 0.1}, {1, 0, 0.1}, 0.1, true, "parallel, tangent"},
      {{0, 0, 0.1}, {1, 0, 0.1}, 0.099, false, "parallel, 1 mm above"},
      {{1.5, 0, 0}, {1.5, 0, 0}, 0.5, true, "point touching a vertex"},
      {{1.5, 0, 0}, {1.5, 0, 0}, 0.49, false, "point 1 cm from a vertex"},
      {{0.5, 0.5, 0}, {1, 1, 0}, 0.0, true, "from the hypotenuse outwards"},
      {{6, -1, 0}, {6, 1, 0}, 0.0, true, "through the degenerate triangle"},
      {{6, 0.01, -1}, {6, 0.01, 1}, 0.0099, false, "beside the degenerate triangle"},
      {{3, 3, 3}, {4, 4, 4}, 1.0, false, "far away"},
      // Regression (review): tiny-area triangles, whose normal underflows.
      {{0.5, 20, 0.005}, {0.5, 20, 0.005}, 0.01, true, "above a 1e-24 sliver"},
      {{0.5, 21, 0.005}, {0.5, 21, 0.005}, 0.01, true, "above a 1e-20 sliver"},
      {{0.5, 19, -1}, {0.5, 19, 1}, 0.0, true, "through a 1e-12 m triangle"},
      {{0.5, 20, 0.02}, {0.5, 20, 0.02}, 0.01, false, "1 cm above a 1e-24 sliver"},
  };
  std::vector<LinkCapsule> caps;
  for (const Case& c : cases) caps.push_back(LinkCapsule{c.a, c.b, c.radius, LinkIndex(0)});
  std::vector<uint8_t> may_touch;
  ASSERT_TRUE(culler.Cull(caps, &may_touch));
  for (size_t i = 0; i < cases.size(); ++i) {
    EXPECT_EQ(may_touch[i] != 0, cases[i].touches) << cases[i].name;
    EXPECT_EQ(f.Separation(caps[i]) <= 0, cases[i].touches) << "brute force: " << cases[i].name;
  }
}

// A link moving over a sliver whose float normal underflows: the GPU
// backend must find the contact the CPU finds (it once answered free).
TEST(GpuCullerTest, SliverTriangleContactIsNotMissed) {
  for (const double tiny : {1e-24, 1e-20, 1e-30}) {
    TriangleMesh m;
    for (const Vector3d& v : {Vector3d(0, 0, 0), Vector3d(1, 0, 0), Vector3d(0.5, 0, tiny)}) {
      m.indices.push_back(static_cast<uint32_t>(m.vertices.size()));
      m.vertices.push_back(v.cast<float>());
    }
    Environment env;
    env.AddMesh(m, "sliver");
    const Skeleton skeleton = OneLinkSkeleton("[0, 0, 0]");  // A ball.
    auto culler = std::make_shared<GpuCuller>(
        std::make_shared<const GpuEnvironment>(SharedContext(), env), CollisionFilter(1, 1), 1);
    CcdEngine gpu(skeleton, env), cpu(skeleton, env);
    gpu.SetCuller(culler);
    Pose p0, p1;
    p0.utime = 0;
    p1.utime = 33333;
    p0.links = {LinkPose{Vector3d(0.5, -1, 0.02), Eigen::Quaterniond::Identity()}};
    p1.links = {LinkPose{Vector3d(0.5, 1, 0.02), Eigen::Quaterniond::Identity()}};
    const QueryResult c = cpu.Query(p0, p1, QueryOptions());
    const QueryResult g = gpu.Query(p0, p1, QueryOptions());
    ASSERT_TRUE(c.contact) << tiny;
    EXPECT_TRUE(g.contact) << "sliver " << tiny << ": the GPU backend missed the contact";
    EXPECT_EQ(g.s_lo, c.s_lo) << tiny;
    EXPECT_GT(g.stats.cull_round_trips, 0) << tiny;
  }
}

// Capsules a float cannot hold are never cleared (they go to the CPU).
TEST(GpuCullerTest, NonFiniteAndHugeCapsulesAreKept) {
  Rng rng(3);
  Fixture f;
  f.env.AddMesh(Soup(rng, Vector3d::Zero(), 50, 1.0), "soup");
  f.filter = CollisionFilter(f.num_links, 1);
  const GpuCuller culler(std::make_shared<const GpuEnvironment>(SharedContext(), f.env), f.filter,
                         f.num_links);
  const double nan = std::nan(""), inf = HUGE_VAL;
  const std::vector<LinkCapsule> caps = {
      LinkCapsule{Vector3d(nan, 0, 0), Vector3d(0, 0, 0), 0.1, LinkIndex(0)},
      LinkCapsule{Vector3d(0, 0, 0), Vector3d(0, inf, 0), 0.1, LinkIndex(0)},
      LinkCapsule{Vector3d(50, 50, 50), Vector3d(60, 60, 60), nan, LinkIndex(0)},
      LinkCapsule{Vector3d(1e35, 0, 0), Vector3d(1e35, 0, 0), 0.1, LinkIndex(0)},
      LinkCapsule{Vector3d(50, 50, 50), Vector3d(60, 60, 60), 0.1,
                  LinkIndex(0)},  // Clear: cleared.
  };
  std::vector<uint8_t> may_touch;
  ASSERT_TRUE(culler.Cull(caps, &may_touch));
  EXPECT_EQ(may_touch, (std::vector<uint8_t>{1, 1, 1, 1, 0}));
}

TEST(GpuCullerTest, ConcurrentCallersGetTheSerialAnswers) {
  Rng rng(42);
  Fixture f;
  f.env.AddMesh(Soup(rng, Vector3d::Zero(), 400, 1.5), "soup");
  f.filter = CollisionFilter(f.num_links, 1);
  const GpuCuller culler(std::make_shared<const GpuEnvironment>(SharedContext(), f.env), f.filter,
                         f.num_links);
  std::vector<LinkCapsule> caps;
  for (int i = 0; i < 500; ++i) {
    caps.push_back(
        LinkCapsule{rng.Box(2), rng.Box(2), rng.U(0, 0.1), LinkIndex(rng.I(f.num_links))});
  }
  std::vector<uint8_t> serial;
  ASSERT_TRUE(culler.Cull(caps, &serial));
  std::vector<std::vector<uint8_t>> answers(4);
  std::vector<std::thread> threads;
  for (int t = 0; t < 4; ++t) {
    threads.emplace_back([&, t] {
      for (int k = 0; k < 10; ++k) culler.Cull(caps, &answers[t]);
    });
  }
  for (std::thread& t : threads) t.join();
  for (const auto& a : answers) EXPECT_EQ(a, serial);
  EXPECT_EQ(culler.round_trips(), 41);
}

// Issue 30: the two ways capsules cross (read-back, and persistent mapped
// buffers with a fence) give the same answers, and several filters share one
// environment's mask buffer (each capsule names its filter's table): each
// culler's answers are its own filter's, checked against brute force, also
// after a culler is destroyed and its table's space reused by another.
TEST(GpuCullerTest, BothTransfersAndSharedMaskTablesGiveTheSameAnswers) {
  Rng rng(3030);
  Fixture f;
  f.env.AddMesh(Soup(rng, Vector3d::Zero(), 300, 1.5), "soup0");
  f.env.AddMesh(Soup(rng, Vector3d(0.5, 0, 0), 300, 1.5), "soup1");
  std::vector<LinkCapsule> caps;
  for (int i = 0; i < 1200; ++i) {
    caps.push_back(
        LinkCapsule{rng.Box(2), rng.Box(2), rng.U(0, 0.1), LinkIndex(rng.I(f.num_links))});
  }
  std::vector<CollisionFilter> filters(3, CollisionFilter(f.num_links, 2));
  filters[1].Ignore(LinkIndex(1), ObjectIndex(0));
  filters[1].Ignore(LinkIndex(3), ObjectIndex(1));
  filters[2].Ignore(LinkIndex(2), kAllObjects);
  filters[2].Ignore(kAllLinks, ObjectIndex(1));
  std::vector<std::vector<uint8_t>> by_transfer[2];
  const Transfer transfers[2] = {Transfer::kReadBack, Transfer::kPersistent};
  for (int t = 0; t < 2; ++t) {
    auto gpu_env = std::make_shared<const GpuEnvironment>(SharedContext(), f.env, transfers[t]);
    // llvmpipe has OpenGL 4.5, NVIDIA 4.6: both ways exist.
    EXPECT_EQ(gpu_env->transfer(), transfers[t]) << TransferName(transfers[t]);
    // A cleared capsule must be clear of every triangle the filter keeps.
    auto check = [&](const GpuCuller& culler, int k) {
      std::vector<uint8_t> may_touch;
      EXPECT_TRUE(culler.Cull(caps, &may_touch));
      for (size_t i = 0; i < caps.size(); ++i) {
        if (may_touch[i] != 0) continue;
        const testing::BruteNearest n =
            testing::BruteForceNearest(f.env, filters[k], caps[i].link, caps[i].a, caps[i].b);
        EXPECT_FALSE(n.any && n.distance <= caps[i].radius)
            << "filter " << k << ", capsule " << i << " touches but was cleared";
      }
      return may_touch;
    };
    std::vector<std::vector<uint8_t>> answers(3);
    {
      // Interleaved: tables at different offsets in one buffer.
      const GpuCuller a(gpu_env, filters[0], f.num_links);
      auto doomed = std::make_unique<GpuCuller>(gpu_env, filters[1], f.num_links);
      const GpuCuller c(gpu_env, filters[2], f.num_links);
      answers[0] = check(a, 0);
      answers[1] = check(*doomed, 1);
      answers[2] = check(c, 2);
      doomed.reset();  // Its table's space is reused by the next culler.
      const GpuCuller b(gpu_env, filters[1], f.num_links);
      EXPECT_EQ(check(b, 1), answers[1]);
      EXPECT_EQ(check(a, 0), answers[0]);
      EXPECT_EQ(check(c, 2), answers[2]);
    }
    // The filters matter: fewer capsules kept where objects are ignored.
    auto kept = [](const std::vector<uint8_t>& v) { return std::count(v.begin(), v.end(), 1); };
    EXPECT_LT(kept(answers[1]), kept(answers[0]));
    EXPECT_LT(kept(answers[2]), kept(answers[1]));
    by_transfer[t] = answers;
  }
  EXPECT_EQ(by_transfer[0], by_transfer[1]);
}

// Issue 30: requests from many threads and several cullers (different
// filters) on one environment are coalesced into shared dispatches, and
// each caller gets exactly the answers it gets alone. The first round waits
// (SetGather) until all eight threads have asked: one dispatch serves them.
TEST(GpuCullerTest, CoalescedRequestsGiveEachCallerItsOwnAnswers) {
  Rng rng(3031);
  Fixture f;
  f.env.AddMesh(Soup(rng, Vector3d::Zero(), 300, 1.5), "soup0");
  f.env.AddMesh(Soup(rng, Vector3d(0.3, 0, 0), 300, 1.5), "soup1");
  CollisionFilter some(f.num_links, 2);
  some.Ignore(LinkIndex(0), ObjectIndex(1));
  some.Ignore(LinkIndex(2), kAllObjects);
  auto gpu_env = std::make_shared<const GpuEnvironment>(SharedContext(), f.env);
  const GpuCuller plain(gpu_env, CollisionFilter(f.num_links, 2), f.num_links);
  const GpuCuller filtered(gpu_env, some, f.num_links);
  constexpr int kThreads = 8, kRounds = 25;
  std::vector<std::vector<LinkCapsule>> caps(kThreads);
  std::vector<std::vector<uint8_t>> alone(kThreads);
  for (int t = 0; t < kThreads; ++t) {
    for (int i = 0; i < 20 + 37 * t; ++i) {
      caps[t].push_back(
          LinkCapsule{rng.Box(2), rng.Box(2), rng.U(0, 0.1), LinkIndex(rng.I(f.num_links))});
    }
    ASSERT_TRUE((t % 2 ? filtered : plain).Cull(caps[t], &alone[t]));
  }
  const DispatchStats before = gpu_env->dispatch_stats();
  EXPECT_EQ(before.dispatches, kThreads);  // One by one: nothing to share.
  gpu_env->SetGather(kThreads, std::chrono::seconds(20));
  std::vector<int> wrong(kThreads, 0);
  std::vector<std::thread> threads;
  for (int t = 0; t < kThreads; ++t) {
    threads.emplace_back([&, t] {
      std::vector<uint8_t> answer;
      for (int k = 0; k < kRounds; ++k) {
        if (!(t % 2 ? filtered : plain).Cull(caps[t], &answer) || answer != alone[t]) ++wrong[t];
        if (k == 0 && t == 0) gpu_env->SetGather(1, std::chrono::microseconds(0));
      }
    });
  }
  for (std::thread& t : threads) t.join();
  for (int t = 0; t < kThreads; ++t) EXPECT_EQ(wrong[t], 0) << "thread " << t;
  const DispatchStats after = gpu_env->dispatch_stats();
  int64_t capsules = 0;
  for (const auto& c : caps) capsules += static_cast<int64_t>(c.size()) * kRounds;
  EXPECT_EQ(after.requests - before.requests, kThreads * kRounds);
  EXPECT_EQ(after.capsules - before.capsules, capsules);
  EXPECT_EQ(after.most_requests, kThreads);  // The gathered first round.
  EXPECT_LT(after.dispatches - before.dispatches, kThreads * kRounds);
  EXPECT_EQ(plain.round_trips() + filtered.round_trips(), kThreads * (kRounds + 1));
  std::printf("%d threads x %d requests: %lld dispatches\n", kThreads, kRounds,
              static_cast<long long>(after.dispatches - before.dispatches));
}

// A lost context: the culler logs once and answers false; queries continue on
// the CPU with the CPU's answers.
TEST(GpuCullerTest, LostContextFallsBackToTheCpu) {
  auto context = std::make_shared<GlContext>();
  Rng rng(5);
  Environment env;
  env.AddMesh(Soup(rng, Vector3d::Zero(), 200, 1.0), "soup");
  const Skeleton skeleton = OneLinkSkeleton("[0.4, 0, 0]");
  auto culler = std::make_shared<GpuCuller>(std::make_shared<const GpuEnvironment>(context, env),
                                            CollisionFilter(1, 1), 1);
  CcdEngine gpu(skeleton, env), cpu(skeleton, env);
  gpu.SetCuller(culler);
  QueryOptions options;
  int contacts = 0, lost_queries = 0;
  for (int i = 0; i < 40; ++i) {
    if (i == 20) {
      EXPECT_THROW(context->Run([] {
        eglMakeCurrent(eglGetCurrentDisplay(), EGL_NO_SURFACE, EGL_NO_SURFACE, EGL_NO_CONTEXT);
      }),
                   GpuError);
    }
    Pose p0, p1;
    p0.utime = 0;
    p1.utime = 33333;
    p0.links = {LinkPose{rng.Box(1.2), Eigen::Quaterniond::UnitRandom()}};
    p1.links = {LinkPose{p0.links[0].p + rng.Box(0.3), Eigen::Quaterniond::UnitRandom()}};
    const QueryResult g = gpu.Query(p0, p1, options), c = cpu.Query(p0, p1, options);
    EXPECT_EQ(g.contact, c.contact) << i;
    EXPECT_EQ(g.s_lo, c.s_lo) << i;
    EXPECT_EQ(g.s_hi, c.s_hi) << i;
    contacts += c.contact;
    if (i >= 20) {
      EXPECT_EQ(g.stats.cull_round_trips, 0) << "query " << i << " used a lost context";
      ++lost_queries;
    }
  }
  EXPECT_GT(contacts, 0);
  EXPECT_EQ(lost_queries, 20);
  std::vector<uint8_t> may_touch;
  EXPECT_FALSE(culler->Cull({LinkCapsule{}}, &may_touch));
  EXPECT_EQ(may_touch, std::vector<uint8_t>{1});
}

// The Backend says what answers now: "gpu", then "cpu (gpu failed: ...)" once
// its context is lost (the daemon reports this in status_t).
TEST(GpuBackendTest, StateReportsALostContext) {
  BackendOptions options;
  options.backend = gpu::BackendKind::kGpu;
  Backend backend(options);
  ASSERT_TRUE(backend.gpu());
  EXPECT_EQ(backend.State(), "gpu");
  EXPECT_THROW(backend.context()->Run([] {
    eglMakeCurrent(eglGetCurrentDisplay(), EGL_NO_SURFACE, EGL_NO_SURFACE, EGL_NO_CONTEXT);
  }),
               GpuError);
  EXPECT_EQ(backend.State(), "cpu (gpu failed: the OpenGL context was lost)");
  EXPECT_STREQ(backend.name(), "gpu");  // What was chosen at start.
  BackendOptions cpu_options;
  cpu_options.backend = gpu::BackendKind::kCpu;
  EXPECT_EQ(Backend(cpu_options).State(), "cpu");
}

// Regression: the Backend once cached uploads by the Environment's address;
// a later environment at the same address (a loop's local) was then tested
// against the earlier one's triangles and contacts were missed (found by the
// benchmark, which builds one environment per scene).
TEST(GpuBackendTest, EnvironmentsAtTheSameAddressAreNotConfused) {
  BackendOptions options;
  options.backend = gpu::BackendKind::kGpu;
  Backend backend(options);
  ASSERT_TRUE(backend.gpu()) << backend.reason();
  const Skeleton skeleton = OneLinkSkeleton("[0, 0.4, 0]");
  const void* first_address = nullptr;
  int same_address = 0;
  for (int k = 0; k < 4; ++k) {
    // A wall at x = k, 1 m wide; the stick moves from x = k - 0.5 to k + 0.5
    // and must hit it at s = 0.45 whatever the earlier walls were.
    TriangleMesh wall;
    for (const Vector3d& v :
         {Vector3d(k, -1, -1), Vector3d(k, 2, -1), Vector3d(k, 2, 1), Vector3d(k, -1, 1)}) {
      wall.vertices.push_back(v.cast<float>());
    }
    wall.indices = {0, 1, 2, 0, 2, 3};
    Environment env;
    env.AddMesh(wall, "wall");
    if (k == 0) first_address = &env;
    same_address += &env == first_address;
    CcdEngine gpu_engine(skeleton, env), cpu_engine(skeleton, env);
    backend.Attach(&gpu_engine);
    ASSERT_NE(gpu_engine.culler(), nullptr);
    Pose p0, p1;
    p0.utime = 0;
    p1.utime = 33333;
    p0.links = {LinkPose{Vector3d(k - 0.5, 0, 0), Eigen::Quaterniond::Identity()}};
    p1.links = {LinkPose{Vector3d(k + 0.5, 0, 0), Eigen::Quaterniond::Identity()}};
    const QueryResult g = gpu_engine.Query(p0, p1, QueryOptions());
    const QueryResult c = cpu_engine.Query(p0, p1, QueryOptions());
    ASSERT_TRUE(c.contact) << k;
    EXPECT_TRUE(g.contact) << "wall " << k;
    EXPECT_EQ(g.s_lo, c.s_lo) << k;
    EXPECT_NEAR(c.s_lo, 0.45, 1e-3) << k;
  }
  std::printf("environments at the first one's address: %d of 4\n", same_address);
}

}  // namespace
}  // namespace sweptccd::gpu

namespace sweptccd::gpu {
namespace {

// A dense real mesh (the Stanford bunny, 69,451 triangles in 0.16 m, three
// copies 0.1 m apart) and
// capsules from a few millimetres to larger than the bunny, through and
// around it: many traversals visit tens of thousands of nodes and
// triangles, past the 65,535 loop iterations after which Mesa's llvmpipe
// silently ends a shader's loops. The culler once answered "cleared" for
// those unfinished traversals (867 of 1,000 capsules touching the bunny,
// found by comparing the two backends' records); it must answer "may touch"
// whenever it has not finished. Against the brute-force twin, as above.
TEST(GpuCullerTest, LongTraversalsAreNeverCleared) {
  Fixture f;
  f.num_links = 2;
  // Three copies side by side, each its own object: a search goes on from
  // one object's BVH to the next (a driver's loop count runs on too).
  const TriangleMesh bunny = LoadMeshFile(SWEPTCCD_DATA_DIR "/env/stanford_bunny.obj.gz");
  for (int copy = -1; copy <= 1; ++copy) {
    TriangleMesh moved = bunny;
    for (Eigen::Vector3f& v : moved.vertices) v.x() += 0.1f * static_cast<float>(copy);
    f.env.AddMesh(moved, "bunny" + std::to_string(copy));
  }
  f.filter = CollisionFilter(f.num_links, f.env.num_objects());
  auto gpu_env = std::make_shared<const GpuEnvironment>(SharedContext(), f.env);
  const GpuCuller culler(gpu_env, f.filter, f.num_links);
  const Aabb box = f.env.object(1).bvh.bounds();
  const Vector3d centre = 0.5 * (box.lo + box.hi);
  Rng rng(0xb0bb1e);
  std::vector<LinkCapsule> caps;
  for (int i = 0; i < 160; ++i) {
    LinkCapsule c;
    const double size = rng.P(0.5) ? rng.U(0.005, 0.05) : rng.U(0.05, 0.4);
    c.a = centre + Vector3d(rng.U(-0.25, 0.25), rng.U(-0.15, 0.15), rng.U(-0.15, 0.15));
    c.b = c.a + size * rng.Dir();
    c.radius = rng.U(0.2, 1.0) * size;
    c.link = LinkIndex(0);
    caps.push_back(c);
  }
  // Each cleared capsule is measured; of the rest, the first 30, to show
  // what the batch holds.
  int64_t touching = 0, clear = 0, cleared = 0;
  CheckBatch(f, culler, caps, "bunnies", 1.0, &clear, &cleared, 30, &touching);
  EXPECT_GT(touching, 10);  // Many go through a bunny.
  EXPECT_GT(clear, 10);     // Some miss it by a visible margin,
  EXPECT_GT(cleared, 5);    // and the culler still clears some of those.
  std::printf(
      "bunnies: %lld of the capsules measured touch, %lld are clear by 1e-5 m, %lld of "
      "those cleared\n",
      static_cast<long long>(touching), static_cast<long long>(clear),
      static_cast<long long>(cleared));
}

}  // namespace
}  // namespace sweptccd::gpu
