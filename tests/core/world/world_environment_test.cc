// The shared world's static-environment part (SPEC 8: each record's
// top-level answer, through each avatar's CcdEngine on the chosen backend)
// in worlds that also hold other avatars and tracked objects: seeded random
// worlds (random skeletons, both motion models, filters, invalid lines,
// per-link mode) and real data (world-bench's grid of mocap avatars in the
// breakfast room with held and thrown objects, and its hands scenario with
// 16- and 81-link avatars). Built twice (tests/CMakeLists.txt), as the
// collision suites are:
//   - world_environment_test: every valid record's environment part against
//     a reference that does not use CcdEngine (exact segment-triangle
//     distances over the triangles TriangleBvh::QueryCapsule returns, at
//     dense samples): no touch before s_lo (none at all for `free`),
//     initially_colliding exactly when a link touches at s = 0, and the
//     witness's separation exact and <= delta;
//   - world_environment_gpu_test: the same, and every record of every world
//     answered by the GPU backend (world_backend_gpu.cc: the culler
//     attached, then the device descent as `sweptccd world --backend gpu
//     --device-descent` runs it), equal to the CPU-only record in every
//     field but elapsed_us and the environment part's stats.
// Each family must show environment contacts (some starting inside a pair)
// and free environment parts, and the GPU ways must have cleared intervals
// on the device.

#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <memory>
#include <nlohmann/json.hpp>
#include <optional>
#include <string>
#include <vector>

#include "core/avatar/motion.h"
#include "core/avatar/pose.h"
#include "core/geometry/distance.h"
#include "core/world/world_file.h"
#include "core/world/world_query.h"
#include "tests/common/random.h"
#include "tests/common/temp_dir_test.h"
#include "tests/common/test_scale.h"
#include "tests/core/world/world_backend_under_test.h"
#include "tools/world_bench_command.h"
#include "tools/world_bench_hands.h"

namespace sweptccd::world {
namespace {

using Eigen::Quaterniond;
using Eigen::Vector3d;
using sweptccd::testing::Rng;

// ---------------------------------------------------------------- reference

// The exact separation of `link` at s from the unfiltered triangles within
// radius + reach of its segment (infinity when none is).
double ReferenceSeparation(const Environment& env, const CollisionFilter& filter,
                           const Skeleton& skel, const PairMotion& motion, LinkIndex link, double s,
                           double reach) {
  Vector3d a, b;
  motion.SegmentAt(link, s, &a, &b);
  const double radius = skel.link(link).radius;
  double best = std::numeric_limits<double>::infinity();
  for (ObjectIndex o(0); o < env.num_objects(); ++o) {
    if (filter.Ignores(link, o)) continue;
    const TriangleBvh& bvh = env.object(o).bvh;
    bvh.QueryCapsule(a, b, radius + reach, [&](uint32_t slot) {
      Vector3d ta, tb, tc;
      bvh.Triangle(slot, &ta, &tb, &tc);
      const double d = SegmentTriangleDistance(a, b, ta, tb, tc).distance;
      if (d <= radius + reach) best = std::min(best, d - radius);
    });
  }
  return best;
}

bool Touches(const Environment& env, const CollisionFilter& filter, const Skeleton& skel,
             const PairMotion& motion, int link, double s) {
  return ReferenceSeparation(env, filter, skel, motion, LinkIndex(link), s, 0.0) <= 0;
}

// `n` samples evenly spread over [0, end), 8 more within `near` below it
// (where a G1 violation would hide), and `end` itself when asked.
std::vector<double> SamplesBelow(double end, double near, int n, bool include_end) {
  std::vector<double> s;
  if (end > 0) {
    for (int k = 0; k < n; ++k) s.push_back(end * k / n);
    for (int k = 1; k <= 8; ++k) s.push_back(std::max(0.0, end - near * k / 8));
    s.push_back(std::nextafter(end, 0.0));
  }
  if (include_end) s.push_back(end);
  return s;
}

struct EnvTally {
  int records = 0, invalid = 0, contact = 0, free = 0, initially = 0, onset = 0, undecided = 0;
  int entity_entries = 0, entity_contacts = 0;
  int compared = 0;  // Records compared with a GPU way's.
};

// Checks avatar a's valid record r's environment part `q` (as the CPU
// answerer gives it) against the reference at `samples` samples.
void CheckEnvironmentPart(const LoadedWorld& lw, AvatarIndex a, size_t r, const QueryResult& q,
                          const QueryOptions& options, int samples) {
  const AvatarEntity& A = lw.world.avatars[a];
  const Skeleton& skel = A.skeleton;
  const PairOutcome& rec = A.records[r];
  const CollisionFilter& filter = lw.env_filters[a];
  const PairMotion motion(skel, rec.pose0, rec.pose1, A.motion);
  bool touching_at_0 = false;
  for (int l = 0; l < skel.num_links() && !touching_at_0; ++l) {
    touching_at_0 = Touches(lw.env, filter, skel, motion, l, 0.0);
  }
  EXPECT_EQ(q.initially_colliding, touching_at_0);
  const double dt_us = static_cast<double>(rec.pose1.utime - rec.pose0.utime);
  const double near = 3 * options.eps_s * 1e6 / dt_us;
  int violations = 0;
  for (double s : SamplesBelow(q.contact ? q.s_lo : 1.0, near, samples, !q.contact)) {
    for (int l = 0; l < skel.num_links(); ++l) {
      if (Touches(lw.env, filter, skel, motion, l, s) && ++violations <= 3) {
        ADD_FAILURE() << (q.contact ? "G1 broken" : "missed contact") << ": link " << l
                      << " touches at s = " << s << (q.contact ? " < s_lo" : " of a free part");
      }
    }
  }
  if (!q.contact || q.undecided) return;  // Only G1 is promised of an undecided bracket.
  EXPECT_LE((q.s_hi - q.s_lo) * dt_us, options.eps_s * 1e6 * (1 + 1e-9)) << "G2";
  ASSERT_FALSE(q.contacts.empty()) << "a decided contact without a witness";
  const ContactRecord& w = q.contacts[0];
  EXPECT_GE(w.s, q.s_lo);
  EXPECT_LE(w.s, q.s_hi);
  EXPECT_FALSE(filter.Ignores(w.link, w.object)) << "witness on a filtered pair";
  const double ref = ReferenceSeparation(lw.env, filter, skel, motion, w.link, w.s,
                                         std::max(0.0, options.delta_m) + 0.05);
  EXPECT_LE(ref, options.delta_m) << "G3 (reference)";
  EXPECT_NEAR(w.separation, ref, 1e-9) << "the witness separation is not exact";
}

// A record without what may differ between backends: its elapsed_us and the
// environment part's stats (the GPU counts its round trips there). The
// entries of `others` (CPU under every backend) keep theirs.
nlohmann::json WithoutTiming(const std::string& line) {
  nlohmann::json j = nlohmann::json::parse(line);
  j.erase("elapsed_us");
  j.erase("stats");
  return j;
}

// Answers every record of `lw` on the CPU, checks each valid record's
// environment part against the reference (every `ref_stride`-th record, at
// `samples` samples), then has every way of the backend under test answer
// the world and compares its records with the CPU's.
void CheckWorld(const LoadedWorld& lw, const QueryOptions& options, const std::string& label,
                int ref_stride, int samples,
                const std::vector<std::unique_ptr<testing::WorldWay>>& ways, EnvTally* tally) {
  SCOPED_TRACE(label);
  const WorldAnswerer cpu(lw, options);
  std::vector<std::string> lines;
  for (AvatarIndex a(0); a < static_cast<int>(lw.world.avatars.size()); ++a) {
    const AvatarEntity& A = lw.world.avatars[a];
    for (size_t r = 0; r < A.records.size(); ++r) {
      lines.push_back(cpu.RecordJson(a, r));
      ++tally->records;
      if (!A.records[r].valid) {
        ++tally->invalid;
        continue;
      }
      const QueryResult q = cpu.AnswerEnvironment(a, r);
      tally->contact += q.contact;
      tally->free += !q.contact;
      tally->initially += q.initially_colliding;
      tally->onset += q.contact && q.s_lo > 0;
      tally->undecided += q.undecided;
      const nlohmann::json j = nlohmann::json::parse(lines.back());
      EXPECT_EQ(j["result"], q.contact ? "contact" : "free") << "record " << lines.size() - 1;
      for (const auto& e : j["others"]) {
        ++tally->entity_entries;
        tally->entity_contacts += e["result"] == "contact";
      }
      if (r % static_cast<size_t>(ref_stride) == 0) {
        SCOPED_TRACE("avatar " + A.id + " record " + std::to_string(r));
        CheckEnvironmentPart(lw, a, r, q, options, samples);
        if (::testing::Test::HasFatalFailure()) return;
      }
    }
  }
  for (const auto& way : ways) {
    const std::vector<std::string> got = way->Answer(lw, options);
    ASSERT_EQ(got.size(), lines.size()) << way->name();
    int differ = 0;
    for (size_t i = 0; i < lines.size(); ++i) {
      if (WithoutTiming(got[i]) != WithoutTiming(lines[i]) && ++differ <= 3) {
        ADD_FAILURE() << "BACKENDS DISAGREE (" << way->name() << ", record " << i
                      << "):\n  cpu: " << lines[i] << "\n  " << way->name() << ": " << got[i];
      }
    }
    EXPECT_EQ(differ, 0) << way->name() << ": records that differ from the CPU's";
    tally->compared += static_cast<int>(got.size());
  }
}

void Report(const char* family, const EnvTally& t,
            const std::vector<std::unique_ptr<testing::WorldWay>>& ways) {
  std::printf(
      "%s (%s): %d records (%d invalid): environment %d contact (%d initially, %d with s_lo > "
      "0, %d undecided), %d free; entities %d entries, %d contact; %d records compared with "
      "the GPU\n",
      family, testing::WorldBackendName(), t.records, t.invalid, t.contact, t.initially, t.onset,
      t.undecided, t.free, t.entity_entries, t.entity_contacts, t.compared);
  for (const auto& way : ways) {
    std::printf("  %s: %lld intervals cleared on the device\n", way->name().c_str(),
                static_cast<long long>(way->device_work()));
    EXPECT_GT(way->device_work(), 0) << family << ": " << way->name() << " never ran";
  }
  // Not a test of the engine, of the suite: both answers of the environment
  // part must occur, and contacts that begin inside a pair (before which
  // the backend clears intervals).
  EXPECT_GT(t.contact, 0) << family << ": no environment contact";
  EXPECT_GT(t.onset, 0) << family << ": no environment contact begins inside a pair";
  EXPECT_GT(t.free, 0) << family << ": no free environment part";
  EXPECT_GT(t.entity_entries, 0) << family << ": no entity entry";
}

// ---------------------------------------------------------------- random worlds

Skeleton RandomSkeleton(Rng& rng, int n) {
  std::vector<Link> links(n);
  for (int i = 0; i < n; ++i) {
    links[i].name = "l" + std::to_string(i);
    links[i].parent = i == 0 ? -1 : rng.I(i);
    links[i].a_L = rng.Box(0.05);
    links[i].b_L = rng.Box(0.25);
    links[i].radius = rng.U(0.02, 0.08);
  }
  return Skeleton::FromLinks("random", links, "test");
}

Pose RandomPose(Rng& rng, int n, int64_t utime, const Vector3d& centre) {
  Pose p;
  p.utime = utime;
  p.links.resize(n);
  for (int i = 0; i < n; ++i) {
    p.links[i].p = centre + rng.Box(0.3);
    p.links[i].q = rng.Quat();
  }
  return p;
}

Pose NextPose(Rng& rng, const Pose& prev, int64_t utime, const Vector3d& drift) {
  Pose p = prev;
  p.utime = utime;
  for (LinkPose& l : p.links) {
    l.p += drift + rng.Box(0.1);
    l.q = (rng.Turn(rng.U(0, 1.5)) * l.q).normalized();
  }
  return p;
}

TriangleMesh Triangles(Rng& rng, const Vector3d& centre, int n) {
  TriangleMesh m;
  for (int t = 0; t < n; ++t) {
    const Vector3d c = centre + rng.Box(0.25);
    for (int v = 0; v < 3; ++v) {
      m.vertices.push_back((c + rng.Box(0.15)).cast<float>());
      m.indices.push_back(static_cast<uint32_t>(m.vertices.size() - 1));
    }
  }
  return m;
}

// A floor (y = h, two triangles 4 m wide), a wall (x = w) and a cluster of
// random triangles near the origin; 2 or 3 avatars (1-4 random links, either
// motion model, 4-8 lines at 60-120 Hz from nearby start times, sometimes a
// garbage line, drifting down or sideways into the floor and wall, some of
// their links ignoring some objects) and a tracked object among them.
void RandomWorld(Rng& rng, LoadedWorld* lw) {
  World& w = lw->world;
  Environment& env = lw->env;
  const float h = static_cast<float>(rng.U(-0.6, -0.4));
  const float x = static_cast<float>(rng.U(0.45, 0.65));
  TriangleMesh floor;
  floor.vertices = {{-2, h, -2}, {2, h, -2}, {2, h, 2}, {-2, h, 2}};
  floor.indices = {0, 1, 2, 0, 2, 3};
  env.AddMesh(floor, "floor");
  TriangleMesh wall;
  wall.vertices = {{x, -2, -2}, {x, 2, -2}, {x, 2, 2}, {x, -2, 2}};
  wall.indices = {0, 1, 2, 0, 2, 3};
  env.AddMesh(wall, "wall");
  env.AddMesh(Triangles(rng, Vector3d(rng.Box(0.3)), 2 + rng.I(8)), "cluster");
  const int avatars = 2 + rng.I(2);
  w.avatars.resize(avatars);
  w.rules.assign(avatars, {});
  for (int e = 0; e < avatars; ++e) {
    AvatarEntity& A = w.avatars[e];
    A.id = "a" + std::to_string(e);
    A.skeleton = RandomSkeleton(rng, 1 + rng.I(4));
    A.motion = rng.P(0.5) ? MotionModel::kArticulated : MotionModel::kIndependent;
    const int n = A.skeleton.num_links();
    CollisionFilter filter(n, env.num_objects());
    if (rng.P(0.3)) filter.Ignore(LinkIndex(rng.I(n)), ObjectIndex(rng.I(env.num_objects())));
    lw->env_filters.push_back(filter);
    const int64_t step = std::vector<int64_t>{8'333, 11'111, 13'889, 16'667}[rng.I(4)];
    const Vector3d drift(rng.U(-0.02, 0.1), rng.U(-0.1, 0.02), rng.U(-0.03, 0.03));
    Pose pose = RandomPose(rng, n, 1'000'000 + rng.I(20'000), Vector3d(rng.Box(0.15)));
    PosePairer pairer;
    const int lines = 4 + rng.I(5);
    for (int k = 0; k < lines; ++k) {
      if (k > 0) pose = NextPose(rng, pose, pose.utime + step, drift);
      std::optional<PairOutcome> out =
          rng.P(0.1) && k > 0 ? pairer.Feed(std::nullopt, "garbage") : pairer.Feed(pose, "");
      if (!out) continue;
      if (out->valid) {
        if (A.used.empty()) A.used.push_back(out->pose0);
        A.used.push_back(out->pose1);
      }
      A.records.push_back(std::move(*out));
    }
  }
  w.objects.resize(1);
  ObjectEntity& O = w.objects[0];
  O.id = "o";
  auto mesh = std::make_shared<Environment>();
  mesh->AddMesh(Triangles(rng, Vector3d::Zero(), 3), "o");
  O.mesh = std::move(mesh);
  RigidSample s;
  s.utime = 1'000'000 + rng.I(20'000);
  s.p = rng.Box(0.3);
  s.q = rng.Quat();
  for (int k = 0; k < 4; ++k) {
    O.used.push_back(s);
    s.utime += 15'000;
    s.p += rng.Box(0.1);
    s.q = (rng.Turn(rng.U(0, 1.0)) * s.q).normalized();
  }
}

TEST(WorldEnvironmentRandom, EveryRecordAgainstTheReferenceAndTheCpu) {
  const auto ways = testing::WorldWays();
  EnvTally tally;
  int per_link_worlds = 0;
  for (int seed = 0; seed < testing::ScaledCount(150); ++seed) {
    Rng rng(3000 + seed);
    LoadedWorld lw;
    RandomWorld(rng, &lw);
    QueryOptions options;
    options.eps_s = rng.P(0.5) ? 1e-4 : 1e-3;
    options.per_link = rng.P(0.3);
    per_link_worlds += options.per_link;
    CheckWorld(lw, options, "seed " + std::to_string(seed), 1, 200, ways, &tally);
    if (::testing::Test::HasFatalFailure()) return;
  }
  Report("random worlds", tally, ways);
  EXPECT_GT(per_link_worlds, 0);
  EXPECT_GT(tally.invalid, 0);
  EXPECT_GE(tally.contact, testing::ScaledMinimum(40));
  EXPECT_GE(tally.onset, testing::ScaledMinimum(20));
  EXPECT_GE(tally.free, testing::ScaledMinimum(40));
}

// ---------------------------------------------------------------- real data

// Moves every entity of the world by `dy` along y (the breakfast room's up):
// the entities' answers are unchanged, and the avatars' feet meet the floor
// at other times.
void Lift(LoadedWorld* lw, double dy) {
  const Vector3d d(0, dy, 0);
  auto lift = [&](Pose* pose) {
    for (LinkPose& l : pose->links) l.p += d;
  };
  for (AvatarEntity& A : lw->world.avatars) {
    for (Pose& p : A.used) lift(&p);
    for (PairOutcome& r : A.records) {
      lift(&r.pose0);
      lift(&r.pose1);
    }
  }
  for (ObjectEntity& O : lw->world.objects) {
    for (RigidSample& x : O.used) x.p += d;
  }
}

class WorldEnvironmentRealData : public test::TempDirTest {
 protected:
  WorldEnvironmentRealData() : TempDirTest("world_environment") {}
};

// world-bench's grid (tools/world_bench_command.h): mocap avatars 1.5 m apart
// on the breakfast room's floor, the outer ones in its furniture, objects
// held in a hand and one thrown through the group.
TEST_F(WorldEnvironmentRealData, GridOfAvatarsInTheBreakfastRoom) {
  WorldBenchOptions o;
  o.out_dir = Path("grid");
  o.avatars = 9;
  o.objects = 2;
  o.seconds = 1.0;
  o.spacing = 1.5;
  o.generate_only = true;
  ASSERT_EQ(RunWorldBenchCommand(o), 0);
  LoadedWorld lw = LoadWorldFile(Path("grid/world.json"));
  Lift(&lw, -0.03);  // Soles 3 cm lower: steps that meet the floor inside a pair.
  ASSERT_EQ(lw.world.avatars.size(), 9u);
  const auto ways = testing::WorldWays();
  EnvTally tally;
  QueryOptions options;
  CheckWorld(lw, options, "grid", testing::ScaledStride(), 100, ways, &tally);
  options.per_link = true;
  CheckWorld(lw, options, "grid per link", 4 * testing::ScaledStride(), 50, ways, &tally);
  Report("grid in the breakfast room", tally, ways);
  EXPECT_GE(tally.contact, 20);
  EXPECT_GE(tally.free, 20);
}

// world-bench's hands scenario (tools/world_bench_hands.h): hands reaching
// for, grasping and carrying boxes in the breakfast room, 16- and 81-link.
TEST_F(WorldEnvironmentRealData, HandsInTheBreakfastRoom) {
  WorldBenchOptions o;
  o.out_dir = Path("hands");
  o.avatars = 2;
  o.seconds = 1.0;
  o.seed = 7;
  o.generate_only = true;
  RunHandsScenario(o, SWEPTCCD_DATA_DIR);
  const auto ways = testing::WorldWays();
  EnvTally tally;
  for (const char* links : {"16", "81"}) {
    LoadedWorld lw = LoadWorldFile(Path(std::string("hands/world") + links + ".json"));
    Lift(&lw, -0.01);  // Soles 1 cm lower: steps that meet the floor inside a pair.
    ASSERT_EQ(lw.world.avatars.size(), 2u);
    ASSERT_GT(lw.env.num_objects(), 0);
    CheckWorld(lw, QueryOptions(), std::string("hands, ") + links + " links",
               3 * testing::ScaledStride(), 50, ways, &tally);
    if (HasFatalFailure()) return;
  }
  Report("hands in the breakfast room", tally, ways);
}

}  // namespace
}  // namespace sweptccd::world
