// CcdEngine::Query on the real scenes and motion capture of the project data
// (SWEPTCCD_DATA_DIR; the tests fail, not skip, when it is missing):
// 16-link avatars imported from BVH clips (subsampled 120 Hz -> 30 Hz), placed
// in the Bitterli grey & white room (Y-up), the MORSE apartment (Z-up) and in
// front of the Stanford dragon scaled x8, feet slightly below the floor in
// some placements. Every pair is checked against a reference that does not
// use CcdEngine: exact segment-triangle distances over the triangles that
// TriangleBvh::QueryCapsule returns (bvh_test validates QueryCapsule against
// brute force over all triangles), at 400+ sampled s per pair:
//   - no miss / G1: no link touches at any sample in [0, s_lo) (all of [0, 1]
//     for `free`), per link in per-link mode;
//   - initially_colliding exactly when some link touches at s = 0;
//   - G2: t_hi - t_lo <= eps; G3: the witness is inside the bracket and the
//     reference separation there is <= delta and equals the reported one.

#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <limits>
#include <random>
#include <regex>
#include <string>
#include <thread>
#include <utility>
#include <vector>

#include "core/avatar/motion.h"
#include "core/avatar/pose.h"
#include "core/avatar/skeleton.h"
#include "core/geometry/bvh.h"
#include "core/geometry/distance.h"
#include "core/geometry/mesh.h"
#include "core/query/capsule_culler.h"
#include "core/query/ccd_query.h"
#include "core/query/link_capsule.h"
#include "core/query/result_json.h"
#include "core/scene/collision_filter.h"
#include "core/scene/environment.h"
#include "core/worker_pool.h"
#include "mocap/mocap_import.h"
#include "tests/common/test_scale.h"
#include "tests/core/query/backend_under_test.h"

namespace sweptccd {
namespace {

namespace fs = std::filesystem;
using Eigen::Vector3d;

const std::string kData = SWEPTCCD_DATA_DIR;
constexpr int kSamples = 400;

std::string EnvPath(const std::string& file) { return kData + "/env/" + file; }
std::string MocapPath(const std::string& file) { return kData + "/mocap/" + file; }

// --- Reference (no CcdEngine) -----------------------------------------------

struct RefNearest {
  bool found = false;  // Some triangle within radius + reach.
  double separation = std::numeric_limits<double>::infinity();
  int object = -1;
  uint32_t triangle = 0;
};

// The exact separation of `link` at s over the unfiltered triangles within
// radius + reach of its segment.
RefNearest ReferenceSeparation(const Environment& env, const CollisionFilter& filter,
                               const Skeleton& skel, const PairMotion& motion, LinkIndex link,
                               double s, double reach) {
  Vector3d a, b;
  motion.SegmentAt(link, s, &a, &b);
  const double radius = skel.link(link).radius;
  RefNearest best;
  for (ObjectIndex o(0); o < env.num_objects(); ++o) {
    if (filter.Ignores(link, o)) continue;
    const TriangleBvh& bvh = env.object(o).bvh;
    bvh.QueryCapsule(a, b, radius + reach, [&](uint32_t slot) {
      Vector3d ta, tb, tc;
      bvh.Triangle(slot, &ta, &tb, &tc);
      const double d = SegmentTriangleDistance(a, b, ta, tb, tc).distance;
      if (d <= radius + reach && d - radius < best.separation) {
        best.found = true;
        best.separation = d - radius;
        best.object = o;
        best.triangle = bvh.TriangleId(slot);
      }
    });
  }
  return best;
}

bool Touches(const Environment& env, const CollisionFilter& filter, const Skeleton& skel,
             const PairMotion& motion, int link, double s) {
  const RefNearest r = ReferenceSeparation(env, filter, skel, motion, LinkIndex(link), s, 0.0);
  return r.found && r.separation <= 0;
}

// Samples of [0, end): kSamples evenly spread, plus 20 within `near` (a few
// eps in units of s) below `end`, where a G1 violation would hide.
std::vector<double> SamplesBelow(double end, double near, bool include_end) {
  std::vector<double> s;
  if (end <= 0) return s;
  for (int k = 0; k < kSamples; ++k) s.push_back(end * k / kSamples);
  for (int k = 1; k <= 20; ++k) {
    const double x = end - near * k / 20;
    if (x >= 0) s.push_back(x);
  }
  s.push_back(end * (1 - 1e-9));
  s.push_back(std::nextafter(end, 0.0));
  if (include_end) s.push_back(end);
  return s;
}

struct Tally {
  int pairs = 0, contact = 0, free_pairs = 0, initially = 0, onset = 0, undecided = 0;
  int per_link_checked = 0;
  int64_t cull_round_trips = 0, cull_cleared = 0;             // The backend's culler (GPU).
  std::vector<int> witness_objects = std::vector<int>(4, 0);  // Contact pairs per witness object.
  double query_s = 0;
};

void CheckWitness(const Environment& env, const CollisionFilter& filter, const Skeleton& skel,
                  const PairMotion& motion, const ContactRecord& w, double s_lo, double s_hi,
                  double delta, const std::string& what) {
  SCOPED_TRACE(what);
  ASSERT_GE(w.link, 0);
  ASSERT_LT(w.link, skel.num_links());
  ASSERT_GE(w.object, 0);
  ASSERT_LT(w.object, env.num_objects());
  EXPECT_FALSE(filter.Ignores(w.link, w.object)) << "witness on a filtered pair";
  EXPECT_GE(w.s, s_lo);
  EXPECT_LE(w.s, s_hi);
  EXPECT_LE(w.separation, delta) << "G3";
  const RefNearest ref =
      ReferenceSeparation(env, filter, skel, motion, w.link, w.s, std::max(0.0, delta) + 0.05);
  ASSERT_TRUE(ref.found) << "the reference finds nothing near the witness";
  EXPECT_LE(ref.separation, delta) << "G3 (reference)";
  EXPECT_NEAR(w.separation, ref.separation, 1e-9) << "the witness separation is not exact";
  // Points: on the link's segment at w.s, on the reported triangle.
  Vector3d a, b;
  motion.SegmentAt(w.link, w.s, &a, &b);
  Vector3d on_seg;
  ClosestPointOnSegment(w.point_link, a, b, &on_seg);
  EXPECT_LT((on_seg - w.point_link).norm(), 1e-9);
  ASSERT_LT(w.triangle, env.object(w.object).bvh.num_triangles());
  EXPECT_NEAR((w.point_link - w.point_env).norm() - skel.link(w.link).radius, w.separation, 1e-9);
  EXPECT_NEAR(w.normal.norm(), 1.0, 1e-9);
}

// The lowest point of any capsule of `pose` along `up`.
double LowestPoint(const Skeleton& skel, const Pose& pose, int up) {
  double lowest = std::numeric_limits<double>::infinity();
  for (int l = 0; l < skel.num_links(); ++l) {
    const Link& link = skel.link(l);
    const Vector3d a = pose.links[l].p + pose.links[l].q * link.a_L;
    const Vector3d b = pose.links[l].p + pose.links[l].q * link.b_L;
    lowest = std::min(lowest, std::min(a[up], b[up]) - link.radius);
  }
  return lowest;
}

// The lowest point of any capsule along `up` over the clip (the soles).
double LowestPoint(const MocapClip& clip, int up) {
  double lowest = std::numeric_limits<double>::infinity();
  for (const Pose& pose : clip.poses)
    lowest = std::min(lowest, LowestPoint(clip.skeleton, pose, up));
  return lowest;
}

void Translate(Pose* pose, const Vector3d& offset) {
  for (LinkPose& lp : pose->links) lp.p += offset;
}

// Optional per-pair placement: shift each pair along `up` so that the floor
// (at `floor_height`) lies halfway between the lowest points of its two poses;
// only pairs whose lowest point drops by more than 1 mm are kept (reversed in
// time when it rises). Contact with the floor then begins inside the pair.
struct Straddle {
  bool enabled = false;
  int up = 1;
  double floor_height = 0;
};

// Runs `pairs` consecutive pairs of the clip from pose `first` and checks each
// against the reference.
void CheckClip(const Environment& env, const CollisionFilter& filter, const MocapClip& clip,
               size_t first, size_t pairs, const std::string& label, Tally* tally,
               const Straddle& straddle = {}) {
  const Skeleton& skel = clip.skeleton;
  CcdEngine engine(skel, env, filter);
  testing::AttachBackend(&engine);  // With an accelerator, the CPU answers beside it.
  const CcdEngine cpu_engine(skel, env, filter);
  QueryOptions options;
  QueryOptions per_link_options;
  per_link_options.per_link = true;
  const double eps_us = options.eps_s * 1e6;
  Tally local;
  // Each pair forwards, then backwards in time (the later pose first, same
  // utimes): contact that ends within a pair then begins within one, which
  // gives more brackets with s_lo > 0.
  // A scaled run (tests/common/test_scale.h): every stride-th pair.
  const size_t stride = static_cast<size_t>(testing::ScaledStride());
  for (size_t step = 0; step < 2 * pairs && first + step / 2 + 1 < clip.poses.size(); ++step) {
    if ((step / 2) % stride != 0) continue;
    const size_t k = first + step / 2;
    const bool reversed = step % 2 == 1;
    Pose p0 = clip.poses[reversed ? k + 1 : k];
    Pose p1 = clip.poses[reversed ? k : k + 1];
    p0.utime = clip.poses[k].utime;
    p1.utime = clip.poses[k + 1].utime;
    if (straddle.enabled) {
      const double l0 = LowestPoint(skel, p0, straddle.up), l1 = LowestPoint(skel, p1, straddle.up);
      if (l0 - l1 < 1e-3) continue;  // Not dropping (the other direction may be).
      Vector3d offset = Vector3d::Zero();
      offset[straddle.up] = straddle.floor_height - 0.5 * (l0 + l1);
      Translate(&p0, offset);
      Translate(&p1, offset);
    }
    const std::string what = label + " pair " + std::to_string(k) + (reversed ? " reversed" : "");
    SCOPED_TRACE(what);
    const auto start = std::chrono::steady_clock::now();
    const QueryResult r = engine.Query(p0, p1, options);
    local.query_s +=
        std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    local.cull_round_trips += r.stats.cull_round_trips;
    local.cull_cleared += r.stats.cull_cleared;
    if (engine.culler() != nullptr) {
      const QueryResult cpu = cpu_engine.Query(p0, p1, options);
      EXPECT_TRUE(testing::SameAnswer(r, cpu))
          << "BACKENDS DISAGREE: " << testing::BackendName() << " contact " << r.contact << " ["
          << r.s_lo << ", " << r.s_hi << "] vs cpu contact " << cpu.contact << " [" << cpu.s_lo
          << ", " << cpu.s_hi << "]";
    }
    const PairMotion motion(skel, p0, p1, options.motion);
    ++local.pairs;
    local.contact += r.contact;
    local.free_pairs += !r.contact;
    local.initially += r.initially_colliding;
    local.onset += r.contact && r.s_lo > 0;
    local.undecided += r.undecided;

    // initially_colliding exactly when some link touches at s = 0.
    bool touching_at_0 = false;
    for (int l = 0; l < skel.num_links() && !touching_at_0; ++l) {
      touching_at_0 = Touches(env, filter, skel, motion, l, 0.0);
    }
    EXPECT_EQ(r.initially_colliding, touching_at_0);
    if (touching_at_0) {
      EXPECT_TRUE(r.contact);
      EXPECT_EQ(r.s_lo, 0.0);
    }

    // No miss, G1: nothing touches before s_lo (anywhere for `free`).
    const double dt_us = static_cast<double>(p1.utime - p0.utime);
    const double near = 3 * eps_us / dt_us;
    const double clear_until = r.contact ? r.s_lo : 1.0;
    int violations = 0;
    for (double s : SamplesBelow(clear_until, near, !r.contact)) {
      for (int l = 0; l < skel.num_links(); ++l) {
        if (Touches(env, filter, skel, motion, l, s) && ++violations <= 3) {
          ADD_FAILURE() << (r.contact ? "G1 broken" : "missed contact") << ": link " << l << " ("
                        << skel.link(l).name << ") touches at s = " << s
                        << (r.contact ? " < s_lo = " + std::to_string(r.s_lo) : " of a free pair");
        }
      }
    }
    if (!r.contact) continue;
    EXPECT_LE(0.0, r.s_lo);
    EXPECT_LE(r.s_lo, r.s_hi);
    EXPECT_LE(r.s_hi, 1.0);
    if (r.undecided) continue;  // Only G1 is promised.
    EXPECT_LE((r.s_hi - r.s_lo) * dt_us, eps_us * (1 + 1e-9)) << "G2";
    ASSERT_FALSE(r.contacts.empty()) << "a decided contact without a witness";
    if (r.contacts[0].object >= 0 && r.contacts[0].object < 4)
      ++local.witness_objects[r.contacts[0].object];
    CheckWitness(env, filter, skel, motion, r.contacts[0], r.s_lo, r.s_hi, options.delta_m,
                 what + " witness");

    // Per-link mode on every contact pair: each link's own bracket, and the
    // links it leaves out never touch at the samples.
    ++local.per_link_checked;
    const QueryResult pl = engine.Query(p0, p1, per_link_options);
    if (engine.culler() != nullptr) {
      EXPECT_TRUE(testing::SameAnswer(pl, cpu_engine.Query(p0, p1, per_link_options)))
          << "BACKENDS DISAGREE in per-link mode";
    }
    EXPECT_TRUE(pl.contact);
    EXPECT_EQ(pl.initially_colliding, r.initially_colliding);
    std::vector<const LinkBracket*> by_link(skel.num_links(), nullptr);
    for (const LinkBracket& b : pl.links) {
      ASSERT_GE(b.link, 0);
      ASSERT_LT(b.link, skel.num_links());
      EXPECT_EQ(by_link[b.link], nullptr) << "two brackets for link " << b.link;
      by_link[b.link] = &b;
    }
    for (int l = 0; l < skel.num_links(); ++l) {
      const LinkBracket* b = by_link[l];
      const double until = b ? b->s_lo : 1.0;
      int link_violations = 0;
      for (double s : SamplesBelow(until, near, b == nullptr)) {
        if (Touches(env, filter, skel, motion, l, s) && ++link_violations <= 2) {
          ADD_FAILURE() << "per-link: link " << l << " (" << skel.link(l).name
                        << ") touches at s = " << s
                        << (b ? " < its s_lo = " + std::to_string(b->s_lo) : " but has no bracket");
        }
      }
      if (b == nullptr || b->undecided) continue;
      EXPECT_LE((b->s_hi - b->s_lo) * dt_us, eps_us * (1 + 1e-9)) << "per-link G2, link " << l;
      ASSERT_TRUE(b->has_witness) << "link " << l;
      EXPECT_EQ(b->witness.link, l);
      CheckWitness(env, filter, skel, motion, b->witness, b->s_lo, b->s_hi, options.delta_m,
                   what + " per-link witness, link " + std::to_string(l));
      EXPECT_EQ(b->initially_colliding, b->s_lo == 0 && Touches(env, filter, skel, motion, l, 0));
    }
  }
  std::printf(
      "  %-40s %3d pairs: %3d contact (%3d initially, %3d with s_lo > 0; witness on "
      "object 0/1: %d/%d), %3d free, %d undecided, %d per-link checked, query %.3f s\n",
      label.c_str(), local.pairs, local.contact, local.initially, local.onset,
      local.witness_objects[0], local.witness_objects[1], local.free_pairs, local.undecided,
      local.per_link_checked, local.query_s);
  tally->pairs += local.pairs;
  tally->onset += local.onset;
  tally->contact += local.contact;
  tally->free_pairs += local.free_pairs;
  tally->initially += local.initially;
  tally->undecided += local.undecided;
  tally->per_link_checked += local.per_link_checked;
  tally->query_s += local.query_s;
  tally->cull_round_trips += local.cull_round_trips;
  tally->cull_cleared += local.cull_cleared;
}

MocapClip LoadClip(const std::string& file, char up_axis) {
  const std::string path = MocapPath(file);
  EXPECT_TRUE(fs::exists(path)) << "missing data file: " << path;
  MocapImportOptions options;
  options.up_axis = up_axis;
  options.frame_step = 4;  // 120 Hz -> 30 Hz.
  MocapClip clip = ImportBvhFile(path, options);
  EXPECT_EQ(clip.skeleton.num_links(), kMocapNumLinks);
  EXPECT_NEAR(clip.frame_time_s, 1.0 / 30, 1e-3);
  return clip;
}

// Centre of the clip's root path on the two horizontal axes.
Vector3d PathCentre(const MocapClip& clip) {
  Vector3d lo = Vector3d::Constant(1e30), hi = -lo;
  for (const Pose& pose : clip.poses) {
    lo = lo.cwiseMin(pose.links[clip.skeleton.root()].p);
    hi = hi.cwiseMax(pose.links[clip.skeleton.root()].p);
  }
  return 0.5 * (lo + hi);
}

// Moves the clip so its path centre is at `centre` (horizontal axes) and its
// lowest point at `sole_height` (up axis).
void Place(MocapClip* clip, int up, const Vector3d& centre, double sole_height) {
  Vector3d offset = centre - PathCentre(*clip);
  offset[up] = sole_height - LowestPoint(*clip, up);
  TranslateClip(clip, offset);
  EXPECT_NEAR(LowestPoint(*clip, up), sole_height, 1e-9);
}

Environment LoadScene(const std::vector<std::string>& files) {
  Environment env;
  for (const std::string& f : files) {
    const std::string path = EnvPath(f);
    EXPECT_TRUE(fs::exists(path)) << "missing data file: " << path;
    env.AddMesh(LoadMeshFile(path), path);
  }
  return env;
}

void Report(const char* scene, const Tally& t) {
  std::printf(
      "%s: %d pairs, %d contact (%d initially colliding, %d with s_lo > 0), %d free, "
      "%d undecided, query time %.2f s\n",
      scene, t.pairs, t.contact, t.initially, t.onset, t.free_pairs, t.undecided, t.query_s);
  if (std::string(testing::BackendName()) != "cpu") {
    std::printf("%s, %s backend: %lld culler round trips, %lld intervals cleared\n", scene,
                testing::BackendName(), static_cast<long long>(t.cull_round_trips),
                static_cast<long long>(t.cull_cleared));
    EXPECT_GT(t.cull_round_trips, 0) << scene << ": the backend under test never ran";
  }
  // The minimum counts of a scaled run are the full run's over its stride.
  EXPECT_GT(t.onset, testing::ScaledMinimum(40))
      << scene << " produced too few contacts that begin inside a pair";
  EXPECT_GT(t.contact, 0) << scene << " produced no contact pair";
  EXPECT_GT(t.free_pairs, 0) << scene << " produced no free pair";
  EXPECT_GE(t.pairs, 300 / testing::ScaledStride());
}

// --- Scenes ---------------------------------------------------------------

// The grey & white room: floor y = 0, x in [-0.5, 5.1], z in [-3.6, 0.6]; a
// sofa along the back wall, a table, shelves along the front wall.
TEST(RealDataTest, GreyWhiteRoom) {
  const Environment env = LoadScene({"bitterli_grey_white_room.ply.gz"});
  ASSERT_EQ(env.num_triangles(), 143163u);
  const int up = 1;
  const CollisionFilter no_filter(kMocapNumLinks, env.num_objects());
  Tally tally;
  {  // Walking the length of the room through the furniture, soles 1 cm into the floor.
    MocapClip clip = LoadClip("cmu_02_01_walk.bvh.gz", 'y');
    Place(&clip, up, Vector3d(2.0, 0, -1.5), -0.01);
    CheckClip(env, no_filter, clip, 0, 84, "walk, soles 1 cm down", &tally);
  }
  {  // Another walk between the table and the shelves, soles 2 cm above the floor.
    MocapClip clip = LoadClip("cmu_07_01_walk.bvh.gz", 'y');
    Place(&clip, up, Vector3d(1.2, 0, -1.6), 0.02);
    CheckClip(env, no_filter, clip, 0, 77, "walk, soles 2 cm up", &tally);
  }
  {  // Dancing (cartwheel, pirouettes) near the table, soles 2 cm into the floor.
    MocapClip clip = LoadClip("cmu_05_06_dance_cartwheel_pirouettes_jete.bvh.gz", 'y');
    Place(&clip, up, Vector3d(2.4, 0, -1.3), -0.02);
    CheckClip(env, no_filter, clip, 0, 221, "dance, soles 2 cm down", &tally);
  }
  for (const char* file : {"cmu_06_01_walk.bvh.gz", "cmu_13_41_jump.bvh.gz"}) {
    // Every dropping pair shifted so the floor is crossed mid-pair.
    MocapClip clip = LoadClip(file, 'y');
    Place(&clip, up, Vector3d(3.2, 0, -1.2), 0);
    CheckClip(env, no_filter, clip, 0, 122, std::string(file) + ", floor crossed mid-pair", &tally,
              Straddle{true, up, 0.0});
  }
  {  // Jumping in the middle of the room; landings reach 5 mm into the floor.
    MocapClip clip = LoadClip("cmu_13_41_jump.bvh.gz", 'y');
    Place(&clip, up, Vector3d(3.0, 0, -1.0), -0.005);
    CheckClip(env, no_filter, clip, 0, 91, "jump, soles 5 mm down", &tally);
  }
  Report("bitterli_grey_white_room", tally);
}

// The MORSE apartment is Z-up: walls 2.5 m, furniture around x in [-6, 2.7],
// y in [-3.1, 5.6], and a 21.8 m ground plane at z = -0.017 (not 0). The clips
// are imported with up_axis 'z' (file y up -> z up).
TEST(RealDataTest, MorseApartmentZUp) {
  const Environment env = LoadScene({"morse_apartment.ply.gz"});
  ASSERT_EQ(env.num_triangles(), 10616u);
  const int up = 2;
  const double ground = -0.017;
  const CollisionFilter no_filter(kMocapNumLinks, env.num_objects());
  Tally tally;
  {  // Walking (along -y) through the furniture at y in [2.8, 5.6], soles 1 cm down.
    MocapClip clip = LoadClip("cmu_06_01_walk.bvh.gz", 'z');
    Place(&clip, up, Vector3d(-0.7, 3.5, 0), ground - 0.01);
    CheckClip(env, no_filter, clip, 0, 122, "walk, soles 1 cm down", &tally);
  }
  {  // Jumping beside the furniture at x in [-5.7, -2.5], soles 1 cm up.
    MocapClip clip = LoadClip("cmu_02_04_jump_balance.bvh.gz", 'z');
    Place(&clip, up, Vector3d(-2.3, -1.5, 0), ground + 0.01);
    CheckClip(env, no_filter, clip, 0, 119, "jump/balance, soles 1 cm up", &tally);
  }
  for (const char* file : {"cmu_07_01_walk.bvh.gz", "cmu_02_04_jump_balance.bvh.gz"}) {
    // Every dropping pair shifted so the ground plane is crossed mid-pair.
    MocapClip clip = LoadClip(file, 'z');
    Place(&clip, up, Vector3d(-0.7, 3.5, 0), ground);
    CheckClip(env, no_filter, clip, 0, 119, std::string(file) + ", ground crossed mid-pair", &tally,
              Straddle{true, up, ground});
  }
  Report("morse_apartment", tally);
}

// The Stanford dragon (res2, 202k triangles) scaled x8 (~1.6 m long, 1.2 m
// tall) standing on a floor quad, in the path of a walking avatar.
TEST(RealDataTest, DragonInThePath) {
  TriangleMesh dragon = LoadMeshFile(EnvPath("stanford_dragon_vrip_res2.ply.gz"));
  ASSERT_EQ(dragon.num_triangles(), 202520u);
  float min_y = std::numeric_limits<float>::infinity();
  for (const auto& v : dragon.vertices) min_y = std::min(min_y, v.y());
  // x8, feet on y = 0, centred on x = 0.6, z = 0.9 (the walk goes along +z at x ~ 0.6).
  for (auto& v : dragon.vertices) {
    v = Eigen::Vector3f(v.x() * 8 + 0.6f, (v.y() - min_y) * 8, v.z() * 8 + 0.9f);
  }
  TriangleMesh floor;
  floor.vertices = {{-5, 0, -5}, {5, 0, -5}, {5, 0, 5}, {-5, 0, 5}};
  floor.indices = {0, 1, 2, 0, 2, 3};
  Environment env;
  env.AddMesh(dragon, "dragon_x8");
  env.AddMesh(floor, "floor");
  const int up = 1;
  Tally tally;
  {  // Walking into the dragon, soles 1 cm into the floor.
    MocapClip clip = LoadClip("cmu_02_01_walk.bvh.gz", 'y');
    Place(&clip, up, Vector3d(0.6, 0, 0.0), -0.01);
    const CollisionFilter no_filter(kMocapNumLinks, env.num_objects());
    CheckClip(env, no_filter, clip, 0, 84, "walk into the dragon", &tally);
  }
  {  // The same with the feet ignoring the floor (a typical filter).
    MocapClip clip = LoadClip("cmu_02_01_walk.bvh.gz", 'y');
    Place(&clip, up, Vector3d(0.6, 0, 0.0), -0.01);
    CollisionFilter feet_floor(kMocapNumLinks, env.num_objects());
    feet_floor.Ignore(LinkIndex(clip.skeleton.FindLink("foot_l")), ObjectIndex(1));
    feet_floor.Ignore(LinkIndex(clip.skeleton.FindLink("foot_r")), ObjectIndex(1));
    feet_floor.Ignore(LinkIndex(clip.skeleton.FindLink("shin_l")), ObjectIndex(1));
    feet_floor.Ignore(LinkIndex(clip.skeleton.FindLink("shin_r")), ObjectIndex(1));
    CheckClip(env, feet_floor, clip, 0, 84, "walk into the dragon, feet ignore floor", &tally);
  }
  {  // Jumping next to the dragon's tail; landings reach 5 mm into the floor.
    MocapClip clip = LoadClip("cmu_13_41_jump.bvh.gz", 'y');
    Place(&clip, up, Vector3d(-0.6, 0, 0.9), -0.005);
    const CollisionFilter no_filter(kMocapNumLinks, env.num_objects());
    CheckClip(env, no_filter, clip, 0, 91, "jump beside the dragon", &tally);
  }
  {  // Every dropping pair of the walk shifted so the floor is crossed mid-pair.
    MocapClip clip = LoadClip("cmu_02_01_walk.bvh.gz", 'y');
    Place(&clip, up, Vector3d(0.6, 0, 0.0), 0);
    const CollisionFilter no_filter(kMocapNumLinks, env.num_objects());
    CheckClip(env, no_filter, clip, 0, 84, "walk into the dragon, floor crossed mid-pair", &tally,
              Straddle{true, up, 0.0});
  }
  {  // The same for the jump beside the tail.
    MocapClip clip = LoadClip("cmu_13_41_jump.bvh.gz", 'y');
    Place(&clip, up, Vector3d(-0.6, 0, 0.9), 0);
    const CollisionFilter no_filter(kMocapNumLinks, env.num_objects());
    CheckClip(env, no_filter, clip, 0, 91, "jump beside the dragon, floor crossed mid-pair", &tally,
              Straddle{true, up, 0.0});
  }
  Report("stanford_dragon_vrip_res2 x8", tally);
}

// The full-resolution Stanford bunny (69,451 triangles in 0.16 m) under a
// dance, its soles 5 cm above the bunny's base, as tools/compare_records.sh
// places it: the legs sweep fat capsules through a mesh far denser than the
// rooms', so one capsule's test visits tens of thousands of nodes and
// triangles. On llvmpipe the GPU backend once cleared such capsules without
// finishing them (a loop limit of the driver, docs/GPU.md) and missed 96 of
// compare_records' 3,282 contacts; here it must give the CPU's answers.
TEST(RealDataTest, DanceOverTheBunny) {
  Environment env;
  env.AddMesh(LoadMeshFile(EnvPath("stanford_bunny.obj.gz")), "bunny");
  MocapClip clip = LoadClip("cmu_05_06_dance_cartwheel_pirouettes_jete.bvh.gz", 'y');
  clip.poses.resize(std::min<size_t>(clip.poses.size(), 90));
  const Aabb bounds = env.object(0).bvh.bounds();
  Place(&clip, 1, Vector3d(-0.02, 0, 0.0), bounds.lo.y() + 0.05);
  const CollisionFilter no_filter(kMocapNumLinks, env.num_objects());
  Tally tally;
  CheckClip(env, no_filter, clip, 0, 89, "dance over the bunny", &tally);
  EXPECT_GT(tally.contact, testing::ScaledMinimum(20));  // The legs go through the bunny,
  EXPECT_GE(tally.onset, testing::ScaledMinimum(3));     // some within a pair,
  EXPECT_GT(tally.free_pairs, 0);                        // and not in every pair.
  if (std::string(testing::BackendName()) != "cpu") {
    EXPECT_GT(tally.cull_round_trips, 0) << "the backend under test never ran";
  }
}

// The candidate test of the backend under test on real geometry, against
// SegmentTriangleDistance, for the links' swept capsules of a dance at 30 Hz
// and at 15 Hz (pairs two frames apart, larger capsules), in three scenes
// (every 5th pair; the sanitizer build's scale takes fewer). The CPU's is
// SegmentTriangleWithin (its early refusals and acceptances), asked for
// every triangle near a capsule at radii around the triangle's distance and
// at the capsule's own radius: it must give the distance's answer. The
// GPU's is the attached culler, asked for each capsule at radii around its
// nearest triangle's distance and at its own radius: it may keep a capsule
// that touches nothing (it is conservative) but must never clear one within
// reach of a triangle, and it must clear some.
TEST(RealDataTest, CandidateTestGivesTheDistancesAnswer) {
  struct Case {
    const char* scene;
    char up_axis;
    int up;
    Vector3d centre;
    double sole;
  };
  const Case cases[] = {
      {"bitterli_grey_white_room.ply.gz", 'y', 1, Vector3d(2.4, 0, -1.3), -0.02},
      {"morse_apartment.ply.gz", 'z', 2, Vector3d(-0.7, 3.5, 0), -0.017 + 0.01},
      {"bitterli_breakfast_room.ply.gz", 'y', 1, Vector3d(-0.67, 0, -1.9), -1.42 + 0.03},
  };
  int64_t checked = 0, within = 0, apart = 0, disagreements = 0;
  int64_t gpu_capsules = 0, gpu_cleared = 0;
  std::string first;
  for (const Case& c : cases) {
    const Environment env = LoadScene({c.scene});
    MocapClip clip = LoadClip("cmu_05_06_dance_cartwheel_pirouettes_jete.bvh.gz", c.up_axis);
    Place(&clip, c.up, c.centre, c.sole);
    CcdEngine engine(clip.skeleton, env,
                     CollisionFilter(clip.skeleton.num_links(), env.num_objects()));
    testing::AttachBackend(&engine);
    const CapsuleCuller* culler = engine.culler();  // The GPU's; none for the CPU.
    std::vector<LinkCapsule> capsules;
    std::vector<double> nearest;  // Per capsule: its nearest triangle's distance.
    const size_t stride = 5 * static_cast<size_t>(testing::ScaledStride());
    for (size_t k = 0; k + 2 < clip.poses.size(); k += stride) {
      for (int step : {1, 2}) {
        const PairMotion motion(clip.skeleton, clip.poses[k], clip.poses[k + step],
                                MotionModel::kArticulated);
        for (LinkIndex l(0); l < clip.skeleton.num_links(); ++l) {
          Vector3d a, b;
          double growth;
          motion.SweptCapsule(l, 0, 1, &a, &b, &growth);
          const double radius = clip.skeleton.link(l).radius + growth;
          double d_min = std::numeric_limits<double>::infinity();
          for (ObjectIndex o(0); o < env.num_objects(); ++o) {
            const TriangleBvh& bvh = env.object(o).bvh;
            bvh.QueryCapsule(a, b, 1.5 * radius, [&](uint32_t slot) {
              Vector3d ta, tb, tc;
              bvh.Triangle(slot, &ta, &tb, &tc);
              const double d = SegmentTriangleDistance(a, b, ta, tb, tc).distance;
              d_min = std::min(d_min, d);
              if (culler != nullptr) return;  // The GPU: asked per capsule below.
              for (double r :
                   {radius, d, d * (1 - 1e-9), d * (1 + 1e-9), d * (1 - 1e-6), d * (1 + 1e-6)}) {
                if (!(r > 0)) continue;
                const bool got = SegmentTriangleWithin(a, b, ta, tb, tc, r);
                ++checked;
                (got ? within : apart) += 1;
                if (got != (d <= r) && disagreements++ == 0) {
                  char buf[512];
                  std::snprintf(buf, sizeof(buf),
                                "%s pair %zu+%d link %d slot %u: distance %.17g radius %.17g "
                                "within %d",
                                c.scene, k, step, l.value(), slot, d, r, got);
                  first = buf;
                }
              }
            });
          }
          if (culler == nullptr) continue;
          // Every triangle within 1.5 radius was seen: d_min is exact there.
          for (double r : {radius, d_min, d_min * (1 - 1e-9), d_min * (1 + 1e-9),
                           d_min * (1 - 1e-6), d_min * (1 + 1e-6)}) {
            if (!(r > 0) || !(r <= 1.5 * radius)) continue;
            capsules.push_back(LinkCapsule{a, b, r, LinkIndex(l)});
            nearest.push_back(d_min);
          }
        }
      }
    }
    if (culler == nullptr) continue;
    std::vector<uint8_t> may_touch;
    ASSERT_TRUE(culler->Cull(capsules, &may_touch)) << c.scene << ": the culler could not answer";
    ASSERT_EQ(may_touch.size(), capsules.size());
    for (size_t i = 0; i < capsules.size(); ++i) {
      const bool reach = nearest[i] <= capsules[i].radius;
      ++checked;
      (reach ? within : apart) += 1;
      ++gpu_capsules;
      gpu_cleared += may_touch[i] == 0;
      if (reach && may_touch[i] == 0 && disagreements++ == 0) {
        char buf[512];
        std::snprintf(buf, sizeof(buf),
                      "%s capsule %zu link %d: nearest triangle at %.17g, radius %.17g, cleared",
                      c.scene, i, capsules[i].link.value(), nearest[i], capsules[i].radius);
        first = buf;
      }
    }
  }
  std::printf("[candidate test] %lld radii checked (%lld within, %lld apart)\n",
              static_cast<long long>(checked), static_cast<long long>(within),
              static_cast<long long>(apart));
  EXPECT_GT(apart, checked / 10);
  EXPECT_GT(within, checked / 10);
  EXPECT_EQ(disagreements, 0) << "first: " << first;
  if (std::string(testing::BackendName()) == "cpu") {
    EXPECT_GT(checked, testing::ScaledMinimum(1000000));
  } else {
    std::printf("[candidate test] %s: %lld capsules, %lld cleared\n", testing::BackendName(),
                static_cast<long long>(gpu_capsules), static_cast<long long>(gpu_cleared));
    EXPECT_GT(gpu_capsules, testing::ScaledMinimum(5000));  // 10964 at full scale.
    EXPECT_GT(gpu_cleared, gpu_capsules / 20) << "the backend under test never cleared a capsule";
  }
}

// The walk and the dance placed in the grey-white room (y up), their soles
// at the given heights (negative: sunk into the floor).
std::pair<MocapClip, MocapClip> WalkAndDanceInTheGreyRoom(double walk_sole, double dance_sole) {
  const int up = 1;
  MocapClip walk = LoadClip("cmu_02_01_walk.bvh.gz", 'y');
  Place(&walk, up, Vector3d(2.0, 0, -1.5), walk_sole);
  MocapClip dance = LoadClip("cmu_05_06_dance_cartwheel_pirouettes_jete.bvh.gz", 'y');
  Place(&dance, up, Vector3d(2.4, 0, -1.3), dance_sole);
  return {std::move(walk), std::move(dance)};
}

// Without --per-link, an initially colliding answer names the lowest link
// touching at s = 0; the search stops the traversal at the first touching
// link it finds and drops the links above it. Its twin is per-link mode,
// which decides every link: the same initially_colliding, and the lowest of
// its touching links with the same witness. Feet sunk into the floor make
// the touching links the legs' (above link 0), with the other links near
// the floor's and furniture's triangles. On the backend under test (the GPU
// culls the swept tests of the links above the cutoff in per-link mode).
TEST(RealDataTest, InitialContactIsTheLowestTouchingLink) {
  const Environment env = LoadScene({"bitterli_grey_white_room.ply.gz"});
  const auto [walk, dance] = WalkAndDanceInTheGreyRoom(-0.03, -0.05);
  const CollisionFilter filter(kMocapNumLinks, env.num_objects());
  int checked = 0, above_zero = 0, free_or_later = 0;
  int64_t cull_round_trips = 0;
  for (const MocapClip* clip : {&walk, &dance}) {
    CcdEngine engine(clip->skeleton, env, filter);
    testing::AttachBackend(&engine);
    QueryOptions first, per_link;
    per_link.per_link = true;
    for (size_t k = 0; k + 1 < clip->poses.size() && k < 240; k += 3) {
      const Pose& p0 = clip->poses[k];
      const Pose& p1 = clip->poses[k + 1];
      const QueryResult r = engine.Query(p0, p1, first);
      const QueryResult pl = engine.Query(p0, p1, per_link);
      cull_round_trips += r.stats.cull_round_trips + pl.stats.cull_round_trips;
      ASSERT_EQ(r.initially_colliding, pl.initially_colliding) << "pair " << k;
      if (!pl.initially_colliding) {
        ++free_or_later;
        continue;
      }
      const LinkBracket* lowest = nullptr;
      for (const LinkBracket& b : pl.links) {
        if (b.initially_colliding && (lowest == nullptr || b.link < lowest->link)) lowest = &b;
      }
      ASSERT_NE(lowest, nullptr);
      ASSERT_TRUE(lowest->has_witness);
      ASSERT_EQ(r.contacts.size(), 1u) << "pair " << k;
      const ContactRecord& w = r.contacts[0];
      EXPECT_EQ(w.link, lowest->link) << "pair " << k;
      EXPECT_EQ(w.object, lowest->witness.object) << "pair " << k;
      EXPECT_EQ(w.triangle, lowest->witness.triangle) << "pair " << k;
      EXPECT_EQ(w.separation, lowest->witness.separation) << "pair " << k;
      EXPECT_EQ(r.s_lo, 0.0);
      EXPECT_EQ(r.s_hi, lowest->s_hi) << "pair " << k;
      ++checked;
      above_zero += lowest->link > 0;
    }
  }
  EXPECT_GT(checked, 40);
  EXPECT_GT(above_zero, 40);  // The cutoff falls above link 0.
  EXPECT_GT(free_or_later, 5);
  if (std::string(testing::BackendName()) != "cpu") {
    EXPECT_GT(cull_round_trips, 0) << "the backend under test never ran";
  }
}

// A query reuses its thread's arrays from the last one (QueryBuffers in
// core/query/query_run.h), so nothing may carry over: a mixed sequence on
// one thread (skeletons of 16 and 3 links, both modes, both motion models,
// a candidate cap of 4 so that lists overflow) gives every record,
// statistics included, exactly as the same queries each on a new thread,
// which starts with none. On the backend under test (with the GPU, its
// culler answers the swept tests of both threads).
TEST(RealDataTest, ReusedQueryArraysCarryNothingFromQueryToQuery) {
  const Environment env = LoadScene({"bitterli_grey_white_room.ply.gz"});
  const auto [walk, dance] = WalkAndDanceInTheGreyRoom(-0.01, -0.02);
  std::vector<Link> links(3);
  for (int i = 0; i < 3; ++i) {
    links[i].name = "c" + std::to_string(i);
    links[i].parent = i - 1;
    links[i].b_L = Vector3d(0, 0.4, 0);
    links[i].radius = 0.05;
  }
  const Skeleton chain = Skeleton::FromLinks("chain", links, "real_data_test");
  std::mt19937_64 g(0xb0ffe5);
  std::uniform_real_distribution<double> u(-1, 1);
  auto chain_pose = [&](int64_t utime) {
    Pose p;
    p.utime = utime;
    for (int i = 0; i < 3; ++i) {
      p.links.push_back(LinkPose{Vector3d(2 + 1.5 * u(g), 0.5 + 0.5 * u(g), -1.5 + 1.5 * u(g)),
                                 Eigen::Quaterniond(u(g), u(g), u(g), u(g))});
    }
    EXPECT_EQ(ValidateAndNormalizePose(&p, 3), "");
    return p;
  };
  const CollisionFilter filter16(kMocapNumLinks, env.num_objects());
  const CollisionFilter filter3(3, env.num_objects());
  CcdEngine walk_engine(walk.skeleton, env, filter16);
  CcdEngine dance_engine(dance.skeleton, env, filter16);
  CcdEngine chain_engine(chain, env, filter3);
  for (CcdEngine* engine : {&walk_engine, &dance_engine, &chain_engine}) {
    testing::AttachBackend(engine);
  }
  struct Job {
    const CcdEngine* engine;
    Pose p0, p1;
    QueryOptions options;
  };
  std::vector<Job> jobs;
  QueryOptions first, per_link, overflow, independent;
  per_link.per_link = true;
  overflow.max_candidates = 1;
  independent.motion = MotionModel::kIndependent;
  for (size_t k = 0; k < 40; ++k) {
    jobs.push_back({&walk_engine, walk.poses[k], walk.poses[k + 1], first});
    jobs.push_back({&dance_engine, dance.poses[3 * k], dance.poses[3 * k + 1], per_link});
    jobs.push_back({&chain_engine, chain_pose(0), chain_pose(33333), k % 2 ? per_link : first});
    jobs.push_back({&walk_engine, walk.poses[k + 1], walk.poses[k + 2], independent});
    jobs.push_back({&dance_engine, dance.poses[3 * k + 1], dance.poses[3 * k + 2], overflow});
  }
  int64_t cull_round_trips = 0;
  auto record = [&cull_round_trips](const Job& job) {
    const QueryResult r = job.engine->Query(job.p0, job.p1, job.options);
    cull_round_trips += r.stats.cull_round_trips;
    return ResultToJson(0, job.p0.utime, job.p1.utime, r, job.options.per_link, 0);
  };
  int contacts = 0, overflowed = 0;
  for (const Job& job : jobs) {
    const std::string reused = record(job);
    std::string fresh;
    std::thread([&] { fresh = record(job); }).join();
    ASSERT_EQ(reused, fresh);
    contacts += reused.find("\"result\":\"contact\"") != std::string::npos;
    if (job.options.max_candidates == 1) {
      // A list past the cap is collected again per interval: the count of
      // triangle tests differs from the default cap's where one overflowed.
      const QueryResult capped = job.engine->Query(job.p0, job.p1, job.options);
      const QueryResult wide = job.engine->Query(job.p0, job.p1, first);
      overflowed += capped.stats.triangle_tests != wide.stats.triangle_tests;
    }
  }
  // The sequence does reach contacts and overflowing lists.
  EXPECT_GT(contacts, 20);
  EXPECT_GT(overflowed, 2);
  if (std::string(testing::BackendName()) != "cpu") {
    EXPECT_GT(cull_round_trips, 0) << "the backend under test never ran";
  }
}

// Issue 30: many pairs in flight at once. Walk and dance pairs in the grey
// room (143,163 triangles), answered by 6 worker threads on the
// backend under test (with the GPU, their swept tests coalesced into shared
// dispatches), give every record, statistics included, exactly as one
// thread does, and (statistics aside) exactly as a CPU-only engine.
TEST(RealDataTest, ManyThreadsGiveTheOneThreadRecords) {
  const Environment room = LoadScene({"bitterli_grey_white_room.ply.gz"});
  const auto [walk, dance] = WalkAndDanceInTheGreyRoom(-0.01, -0.02);
  const CollisionFilter filter(kMocapNumLinks, room.num_objects());
  CcdEngine walk_engine(walk.skeleton, room, filter), dance_engine(dance.skeleton, room, filter);
  const CcdEngine walk_cpu(walk.skeleton, room, filter), dance_cpu(dance.skeleton, room, filter);
  for (CcdEngine* engine : {&walk_engine, &dance_engine}) testing::AttachBackend(engine);
  struct Job {
    const CcdEngine* engine;
    const CcdEngine* cpu;
    const Pose* p0;
    const Pose* p1;
    QueryOptions options;
  };
  std::vector<Job> jobs;
  QueryOptions first, per_link;
  per_link.per_link = true;
  const size_t n = std::min<size_t>(120, std::min(walk.poses.size(), dance.poses.size()) - 1);
  for (size_t k = 0; k < n; ++k) {
    jobs.push_back({&walk_engine, &walk_cpu, &walk.poses[k], &walk.poses[k + 1], first});
    jobs.push_back({&dance_engine, &dance_cpu, &dance.poses[k], &dance.poses[k + 1],
                    k % 3 == 0 ? per_link : first});
  }
  auto answer = [](const CcdEngine& engine, const Job& job) {
    const QueryResult r = engine.Query(*job.p0, *job.p1, job.options);
    return std::make_pair(ResultToJson(0, job.p0->utime, job.p1->utime, r, job.options.per_link, 0),
                          r.stats.cull_round_trips);
  };
  std::vector<std::string> one(jobs.size()), many(jobs.size());
  int64_t round_trips = 0;
  for (size_t i = 0; i < jobs.size(); ++i) one[i] = answer(*jobs[i].engine, jobs[i]).first;
  std::vector<int64_t> trips(jobs.size(), 0);
  WorkerPool pool(6);
  pool.Run(jobs.size(), [&](size_t i, int) {
    const auto [line, t] = answer(*jobs[i].engine, jobs[i]);
    many[i] = line;
    trips[i] = t;
  });
  for (int64_t t : trips) round_trips += t;
  static const std::regex stats("\"stats\":\\{[^}]*\\}");
  int contacts = 0;
  for (size_t i = 0; i < jobs.size(); ++i) {
    ASSERT_EQ(many[i], one[i]) << "job " << i;
    const std::string cpu = answer(*jobs[i].cpu, jobs[i]).first;
    ASSERT_EQ(std::regex_replace(many[i], stats, ""), std::regex_replace(cpu, stats, ""))
        << "job " << i << ": the backend under test differs from the CPU";
    contacts += one[i].find("\"result\":\"contact\"") != std::string::npos;
  }
  EXPECT_GT(contacts, 20);
  EXPECT_LT(contacts, static_cast<int>(jobs.size()));
  if (std::string(testing::BackendName()) != "cpu") {
    EXPECT_GT(round_trips, 0) << "the backend under test never ran";
  }
}

}  // namespace
}  // namespace sweptccd
