// The shared-world engine (core/world/entity_query and its parts) against an independent
// dense-sampling reference: link against link of another avatar and link
// against a tracked object, both motion models, off-phase sampling, windows
// that start or stop mid-pair, thin fast objects, exactly touching and
// grazing capsules, initially interpenetrating avatars, zero-length links,
// 180-degree turns, filters, and real mocap (two walkers crossing, two
// boxers facing each other).
//
// The reference places every triangle in the world at each sample time
// (x + R v) and takes the minimum over all (unfiltered) primitives, so it
// shares neither the engine's object frame, its bounds, nor its BVH; every
// pose (avatars' links, objects) comes from the long double twin of SPEC 3's
// motion (tests/common/twin_motion.h), not from core/avatar. It
// checks SPEC 8's certificate: `free` only when no dense sample touches;
// `contact`: G1 (no sample before t_lo touches), G2 (t_hi - t_lo <= eps),
// G3 (the witness time is in the bracket and the separation there, by the
// reference, is <= delta), and the witness itself (points, normal,
// separation) recomputed.

#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <map>
#include <optional>
#include <string>
#include <thread>
#include <tuple>
#include <utility>
#include <vector>

#include "core/geometry/distance.h"
#include "core/world/avatar_target.h"
#include "core/world/entity_broad_phase.h"
#include "core/world/entity_query.h"
#include "core/world/entity_run.h"
#include "core/world/link_sweep_boxes.h"
#include "core/world/object_target.h"
#include "core/world/world_file.h"
#include "core/world/world_query.h"
#include "mocap/mocap_import.h"
#include "tests/common/random.h"
#include "tests/common/temp_dir_test.h"
#include "tests/common/twin_motion.h"
#include "tests/common/without_near_boxes.h"
#include "tools/world_bench_command.h"
#include "tools/world_bench_hands.h"

namespace sweptccd::world {
namespace {

using Eigen::Quaterniond;
using Eigen::Vector3d;
using sweptccd::testing::Rng;

// The views and entries of these tests' int indices (an avatar b, or an
// object o, the other -1).
AvatarWindow AvatarOf(const World& w, int a) { return WindowOfAvatar(w, AvatarIndex(a)); }
ObjectWindow ObjectOf(const World& w, int o) { return WindowOfObject(w, TrackedObjectIndex(o)); }
bool AnswerEntity(const WorldAnswerer& answerer, int a, size_t r, int b, int o, OtherAnswer* answer,
                  int64_t* t_from, int64_t* t_to) {
  const auto e = b >= 0 ? answerer.AnswerAvatar(AvatarIndex(a), r, AvatarIndex(b))
                        : answerer.AnswerObject(AvatarIndex(a), r, TrackedObjectIndex(o));
  if (!e) return false;
  *answer = e->answer;
  *t_from = e->t_from;
  *t_to = e->t_to;
  return true;
}

constexpr double kSlack = 1e-9;  // Reference rounding, metres.

// ---------------------------------------------------------------- reference

// E's sample bracket and normalised time at utime t (t within the samples).
template <typename T>
void Locate(const std::vector<T>& samples, double t, int* k, double* s,
            int64_t (*utime)(const T&)) {
  const int n = static_cast<int>(samples.size());
  if (n == 1) {
    *k = 0;
    *s = 0;
    return;
  }
  int i = 0;
  while (i + 2 < n && static_cast<double>(utime(samples[i + 1])) <= t) ++i;
  *k = i;
  const double t0 = static_cast<double>(utime(samples[i]));
  const double t1 = static_cast<double>(utime(samples[i + 1]));
  *s = std::clamp((t - t0) / (t1 - t0), 0.0, 1.0);
}
int64_t PoseUtime(const Pose& p) { return p.utime; }
int64_t RigidUtime(const RigidSample& x) { return x.utime; }

// Separation of A's link l (or all links, l = -1) from entity E at utime t,
// with every pose from the long double twin of SPEC 3 (tests/common/
// twin_motion.h), not from core/avatar.
struct Reference {
  Reference(const World& w_in, int a_in, int b_in, int o_in, const Pose& p0, const Pose& p1)
      : w(w_in),
        a(a_in),
        b(b_in),
        o(o_in),
        pose0(p0),
        pose1(p1),
        ma(w.avatars[a].skeleton, pose0, pose1, w.avatars[a].motion) {}
  const World& w;
  int a;
  int b = -1, o = -1;  // The other entity.
  Pose pose0, pose1;
  twin::TwinMotion ma;
  mutable std::map<int, twin::TwinMotion> mb_;  // B's motion per sample bracket.

  // Link l's segment at pose X (twin), in double for the distance routines.
  static void Segment(const Skeleton& skeleton, int l, const twin::TwinPose& X, Vector3d* p,
                      Vector3d* q) {
    const twin::Mat3L R = twin::RotL(X.q);
    *p = (X.p + R * twin::ToL(skeleton.link(l).a_L)).cast<double>();
    *q = (X.p + R * twin::ToL(skeleton.link(l).b_L)).cast<double>();
  }

  double Sep(double t, int only_link = -1) const {
    const AvatarEntity& A = w.avatars[a];
    const double sa = std::clamp((t - pose0.utime) / double(pose1.utime - pose0.utime), 0.0, 1.0);
    const std::vector<twin::TwinPose> xa = ma.PosesAt(sa);
    std::vector<twin::TwinPose> xb;
    if (b >= 0) {
      const AvatarEntity& B = w.avatars[b];
      int k;
      double s;
      Locate(B.used, t, &k, &s, &PoseUtime);
      const int k1 = std::min<int>(k + 1, B.used.size() - 1);
      auto it = mb_.find(k);
      if (it == mb_.end()) {
        it = mb_.emplace(std::piecewise_construct, std::forward_as_tuple(k),
                         std::forward_as_tuple(B.skeleton, B.used[k], B.used[k1], B.motion))
                 .first;
      }
      xb = it->second.PosesAt(s);
    }
    double best = HUGE_VAL;
    for (int l = 0; l < A.skeleton.num_links(); ++l) {
      if (only_link >= 0 && l != only_link) continue;
      Vector3d pa, pb;
      Segment(A.skeleton, l, xa[l], &pa, &pb);
      const double ra = A.skeleton.link(l).radius;
      if (b >= 0) {
        const AvatarEntity& B = w.avatars[b];
        for (int j = 0; j < B.skeleton.num_links(); ++j) {
          if (w.IgnoresLinkPair(AvatarIndex(a), LinkIndex(l), AvatarIndex(b), LinkIndex(j)))
            continue;
          Vector3d qa, qb, c1, c2;
          Segment(B.skeleton, j, xb[j], &qa, &qb);
          best = std::min(best, std::sqrt(SegmentSegmentDistanceSquared(pa, pb, qa, qb, &c1, &c2)) -
                                    ra - B.skeleton.link(j).radius);
        }
      } else {
        if (w.IgnoresObject(AvatarIndex(a), LinkIndex(l), TrackedObjectIndex(o))) continue;
        const ObjectEntity& O = w.objects[o];
        int k;
        double s;
        Locate(O.used, t, &k, &s, &RigidUtime);
        const int k1 = std::min<int>(k + 1, O.used.size() - 1);
        const twin::LD sl = s;
        const twin::Vec3L x = (1 - sl) * twin::ToL(O.used[k].p) + sl * twin::ToL(O.used[k1].p);
        const twin::Mat3L R =
            twin::RotL(twin::TwinSlerp(twin::ToQL(O.used[k].q), twin::ToQL(O.used[k1].q), sl));
        const TriangleBvh& bvh = O.mesh->object(0).bvh;
        auto place = [&](const Vector3d& v) -> Vector3d {
          return (x + R * twin::ToL(v)).cast<double>();
        };
        for (uint32_t slot = 0; slot < bvh.num_triangles(); ++slot) {
          Vector3d ta, tb, tc;
          bvh.Triangle(slot, &ta, &tb, &tc);
          best = std::min(
              best, SegmentTriangleDistance(pa, pb, place(ta), place(tb), place(tc)).distance - ra);
        }
      }
    }
    return best;
  }
};

struct Tally {
  int free = 0, contact = 0, initially = 0, undecided = 0, culled = 0;
};

// Checks `ans`, the answer for (A's pair, E) over the window [t_from, t_to],
// against the reference.
void CheckAnswer(const World& w, int a, int b, int o, const Pose& pose0, const Pose& pose1,
                 int64_t t_from, int64_t t_to, const OtherAnswer& ans,
                 const EntityQueryOptions& opt, Tally* tally, int samples) {
  const AvatarEntity& A = w.avatars[a];
  const Reference ref(w, a, b, o, pose0, pose1);
  const double u0 = static_cast<double>(pose0.utime);
  const double eps_us = opt.eps_s * 1e6;

  auto check_bracket = [&](const OtherBracket& br, int only_link) {
    EXPECT_GE(br.tau_lo, double(t_from - pose0.utime));
    EXPECT_LE(br.tau_hi, double(t_to - pose0.utime));
    EXPECT_LE(br.tau_lo, br.tau_hi);
    // G1: dense samples before t_lo never touch.
    for (int i = 0; i <= samples; ++i) {
      const double t = t_from + (t_to - t_from) * double(i) / samples;
      if (t >= u0 + br.tau_lo) break;
      ASSERT_GT(ref.Sep(t, only_link), -kSlack)
          << "G1 broken: touching at t=" << t << " before t_lo=" << u0 + br.tau_lo;
    }
    if (br.undecided) {
      // SPEC 8: a witness for every contact, undecided ones too: the nearest
      // of E at the bracket's start, at whatever separation.
      EXPECT_EQ(br.tau_hi, double(t_to - pose0.utime));
      ASSERT_TRUE(br.has_witness) << "undecided without a witness";
      EXPECT_EQ(br.witness.tau, br.tau_lo);
      EXPECT_EQ(br.witness.link, br.link);
      EXPECT_NEAR(br.witness.separation, ref.Sep(u0 + br.witness.tau, br.link), 1e-6);
      return;
    }
    EXPECT_LE(br.tau_hi - br.tau_lo, eps_us * (1 + 1e-12));  // G2.
    if (br.initially_colliding) {
      EXPECT_EQ(br.tau_lo, double(t_from - pose0.utime));
      EXPECT_LE(ref.Sep(t_from, only_link), kSlack);
    }
    ASSERT_TRUE(br.has_witness);
    const OtherContact& c = br.witness;
    EXPECT_GE(c.tau, br.tau_lo);  // G3: the witness time is in the bracket ...
    EXPECT_LE(c.tau, br.tau_hi);
    EXPECT_LE(ref.Sep(u0 + c.tau, only_link >= 0 ? only_link : c.link), opt.delta_m + kSlack);
    EXPECT_LE(c.separation, opt.delta_m + kSlack);  // ... and within delta there.
    EXPECT_NEAR(c.normal.norm(), 1.0, 1e-9);
    // The witness points are a closest pair: their distance is the separation
    // plus the radii (avatar) or the link radius (object).
    double radii = A.skeleton.link(c.link).radius;
    if (b >= 0) radii += w.avatars[b].skeleton.link(c.other_link).radius;
    EXPECT_NEAR((c.point_link - c.point_other).norm() - radii, c.separation, 1e-6);
    if ((c.point_link - c.point_other).norm() > 1e-9) {
      EXPECT_GT(c.normal.dot(c.point_link - c.point_other), 0);
    }
  };

  if (!ans.contact) {
    ++tally->free;
    tally->culled += ans.culled_by_box;
    // A contact seen by dense sampling is never answered `free`.
    for (int i = 0; i <= samples; ++i) {
      const double t = t_from + (t_to - t_from) * double(i) / samples;
      ASSERT_GT(ref.Sep(t), -kSlack) << "missed contact at t=" << t;
    }
  } else {
    ++tally->contact;
    tally->initially += ans.bracket.initially_colliding;
    tally->undecided += ans.bracket.undecided;
    check_bracket(ans.bracket, -1);
  }
  if (opt.per_link) {
    for (int l = 0; l < A.skeleton.num_links(); ++l) {
      const OtherBracket* br = nullptr;
      for (const OtherBracket& x : ans.links) {
        if (x.link == l) br = &x;
      }
      if (br != nullptr) {
        check_bracket(*br, l);
      } else {
        for (int i = 0; i <= samples / 4; ++i) {
          const double t = t_from + (t_to - t_from) * double(i) / (samples / 4);
          ASSERT_GT(ref.Sep(t, l), -kSlack) << "per-link: link " << l << " missed at " << t;
        }
      }
    }
  }
}

// Runs the engine on (A's pair, E) and checks it against the reference.
void CheckPair(const World& w, int a, int b, int o, const Pose& pose0, const Pose& pose1,
               const EntityQueryOptions& opt, Tally* tally, int samples = 1500,
               const std::string& label = "") {
  SCOPED_TRACE(label);
  std::vector<int64_t> times;
  if (b >= 0) {
    for (const Pose& p : w.avatars[b].used) times.push_back(p.utime);
  } else {
    for (const RigidSample& x : w.objects[o].used) times.push_back(x.utime);
  }
  const int64_t t_from = std::max(pose0.utime, times.front());
  const int64_t t_to = std::min(pose1.utime, times.back());
  if (t_from > t_to) return;
  const AvatarEntity& A = w.avatars[a];
  const PairMotion motion(A.skeleton, pose0, pose1, A.motion);
  const auto target = b >= 0 ? MakeAvatarTarget(AvatarOf(w, a).who, AvatarOf(w, b))
                             : MakeObjectTarget(AvatarOf(w, a).who, ObjectOf(w, o));
  const std::vector<Piece> pieces = SplitWindow(pose0.utime, t_from, t_to, times);
  ASSERT_FALSE(pieces.empty());
  const OtherAnswer ans =
      AnswerOther(A.skeleton, motion, pose0.utime, pose1.utime, pieces, *target, opt);
  CheckAnswer(w, a, b, o, pose0, pose1, t_from, t_to, ans, opt, tally, samples);
}

// ---------------------------------------------------------------- scenes

Skeleton RandomSkeleton(Rng& rng, int n, bool zero_length) {
  std::vector<Link> links(n);
  for (int i = 0; i < n; ++i) {
    links[i].name = "l" + std::to_string(i);
    links[i].parent = i == 0 ? -1 : rng.I(i);
    links[i].a_L = rng.Box(0.05);
    links[i].b_L = (zero_length && rng.P(0.3)) ? links[i].a_L : Vector3d(rng.Box(0.25));
    links[i].radius = rng.U(0.02, 0.08);
  }
  return Skeleton::FromLinks("random", links, "test");
}

Pose RandomPose(Rng& rng, int n, int64_t utime, const Vector3d& centre, double spread) {
  Pose p;
  p.utime = utime;
  p.links.resize(n);
  for (int i = 0; i < n; ++i) {
    p.links[i].p = centre + rng.Box(spread);
    p.links[i].q = rng.Quat();
  }
  return p;
}

// The next pose: moved and turned (sometimes by exactly 180 degrees).
Pose NextPose(Rng& rng, const Pose& prev, int64_t utime, double move) {
  Pose p = prev;
  p.utime = utime;
  for (LinkPose& l : p.links) {
    l.p += rng.Box(move);
    if (rng.P(0.1)) {
      l.q = l.q * Quaterniond(0, 0, 0, 1);  // A 180-degree turn.
    } else {
      l.q = (rng.Turn(rng.U(0, 2.0)) * l.q).normalized();
    }
  }
  return p;
}

// A's pair at 72 Hz, B sampled at 90 Hz (or a random rate) starting and
// stopping anywhere around the pair.
void RandomAvatarWorld(Rng& rng, World* w, Pose* p0, Pose* p1) {
  w->avatars.resize(2);
  w->rules.assign(2, {});
  for (int e = 0; e < 2; ++e) {
    AvatarEntity& A = w->avatars[e];
    A.id = e == 0 ? "a" : "b";
    A.skeleton = RandomSkeleton(rng, 1 + rng.I(4), true);
    A.motion = rng.P(0.5) ? MotionModel::kArticulated : MotionModel::kIndependent;
  }
  const int n0 = w->avatars[0].skeleton.num_links(), n1 = w->avatars[1].skeleton.num_links();
  const int64_t u0 = 1'000'000 + rng.I(1000);
  const int64_t u1 = u0 + 13'889;
  *p0 = RandomPose(rng, n0, u0, Vector3d::Zero(), 0.3);
  *p1 = NextPose(rng, *p0, u1, 0.3);
  w->avatars[0].used = {*p0, *p1};
  const int64_t step = rng.P(0.7) ? 11'111 : 3'000 + rng.I(20'000);
  int64_t t = u0 - step * (rng.I(3)) + rng.I(static_cast<int>(step));
  if (rng.P(0.25)) t = u0 + rng.I(13'889);       // Starts mid-pair.
  const int count = 1 + rng.I(5);                // May stop mid-pair (or be one instant).
  if (rng.P(0.08)) t = u0 - step * (count - 1);  // Ends as the pair starts.
  if (rng.P(0.08)) t = u1;                       // Starts as the pair ends.
  Pose q = RandomPose(rng, n1, t, Vector3d(rng.Box(0.3)), 0.3);
  for (int i = 0; i < count; ++i) {
    w->avatars[1].used.push_back(q);
    q = NextPose(rng, q, q.utime + step, 0.25);
  }
}

TriangleMesh RandomMesh(Rng& rng, bool thin_plate) {
  TriangleMesh m;
  if (thin_plate) {  // A thin square plate (two triangles), 0.3 m wide.
    const float h = 0.15f;
    m.vertices = {{-h, -h, 0}, {h, -h, 0}, {h, h, 0}, {-h, h, 0}};
    m.indices = {0, 1, 2, 0, 2, 3};
    return m;
  }
  const int n = 2 + rng.I(6);
  for (int t = 0; t < n; ++t) {
    const Vector3d c = rng.Box(0.2);
    for (int v = 0; v < 3; ++v) {
      Vector3d p = c + rng.Box(0.1);
      if (rng.P(0.05) && v > 0) p = m.vertices.back().cast<double>();  // Degenerate.
      m.vertices.push_back(p.cast<float>());
      m.indices.push_back(static_cast<uint32_t>(m.vertices.size() - 1));
    }
  }
  return m;
}

void RandomObjectWorld(Rng& rng, World* w, Pose* p0, Pose* p1) {
  w->avatars.resize(1);
  w->rules.assign(1, {});
  AvatarEntity& A = w->avatars[0];
  A.id = "a";
  A.skeleton = RandomSkeleton(rng, 1 + rng.I(4), true);
  A.motion = rng.P(0.5) ? MotionModel::kArticulated : MotionModel::kIndependent;
  const int n = A.skeleton.num_links();
  const int64_t u0 = 2'000'000 + rng.I(1000);
  const int64_t u1 = u0 + 13'889;
  *p0 = RandomPose(rng, n, u0, Vector3d::Zero(), 0.2);
  *p1 = NextPose(rng, *p0, u1, 0.2);
  A.used = {*p0, *p1};
  w->objects.resize(1);
  ObjectEntity& O = w->objects[0];
  O.id = "o";
  const bool thrown = rng.P(0.3);
  auto mesh = std::make_shared<Environment>();
  mesh->AddMesh(RandomMesh(rng, thrown), "mesh");
  O.mesh = std::move(mesh);
  const int64_t step = rng.P(0.7) ? 11'111 : 3'000 + rng.I(20'000);
  int64_t t = u0 - step + rng.I(static_cast<int>(step));
  if (rng.P(0.25)) t = u0 + rng.I(13'889);
  const int count = 1 + rng.I(4);
  if (rng.P(0.08)) t = u0 - step * (count - 1);  // Ends as the pair starts.
  if (rng.P(0.08)) t = u1;                       // Starts as the pair ends.
  RigidSample x;
  x.utime = t;
  x.p = rng.Box(0.3);
  x.q = rng.Quat();
  const Vector3d velocity = thrown ? Vector3d(rng.Dir() * 3.0) : Vector3d::Zero();
  if (thrown) x.p = -velocity * 0.5;  // Through the avatar in one or two samples.
  for (int i = 0; i < count; ++i) {
    O.used.push_back(x);
    x.utime += step;
    x.p += thrown ? velocity : Vector3d(rng.Box(0.2));
    x.q = rng.P(0.1) ? Quaterniond(x.q * Quaterniond(0, 1, 0, 0))
                     : Quaterniond((rng.Turn(rng.U(0, 1.5)) * x.q).normalized());
  }
}

// The cases the issue lists, read off a generated world (the generators'
// random draws are untouched): each seed counts for every case it holds, with
// whether its answer was a contact, so that the suite can show it exercised
// every case both ways where that matters.
bool TurnedByHalf(const Quaterniond& from, const Quaterniond& to) {
  return to.coeffs() == (from * Quaterniond(0, 0, 0, 1)).coeffs() ||
         to.coeffs() == (from * Quaterniond(0, 1, 0, 0)).coeffs();
}
bool AnyHalfTurn(const std::vector<Pose>& poses) {
  for (size_t k = 0; k + 1 < poses.size(); ++k) {
    for (size_t l = 0; l < poses[k].links.size(); ++l) {
      if (TurnedByHalf(poses[k].links[l].q, poses[k + 1].links[l].q)) return true;
    }
  }
  return false;
}
bool AnyHalfTurn(const std::vector<RigidSample>& samples) {
  for (size_t k = 0; k + 1 < samples.size(); ++k) {
    if (TurnedByHalf(samples[k].q, samples[k + 1].q)) return true;
  }
  return false;
}
bool AnyZeroLength(const Skeleton& skeleton) {
  for (int l = 0; l < skeleton.num_links(); ++l) {
    if (skeleton.link(l).a_L == skeleton.link(l).b_L) return true;
  }
  return false;
}

struct CaseTally {
  std::map<std::string, std::pair<int, int>> seeds_and_contacts;
  void Add(const std::string& name, bool holds, bool contact) {
    if (!holds) return;
    auto& [seeds, contacts] = seeds_and_contacts[name];
    ++seeds;
    contacts += contact;
  }
  // Every case seen at least `min_seeds` times, with at least `min_contacts`
  // contacts among them.
  void Expect(const std::string& name, int min_seeds, int min_contacts) const {
    const auto it = seeds_and_contacts.find(name);
    const std::pair<int, int> got =
        it == seeds_and_contacts.end() ? std::pair<int, int>{0, 0} : it->second;
    std::printf("  %-34s %4d seeds, %4d contacts\n", name.c_str(), got.first, got.second);
    EXPECT_GE(got.first, min_seeds) << name;
    EXPECT_GE(got.second, min_contacts) << name;
  }
};

// The entity's samples against A's pair [u0, u1].
void AddWindowCases(const std::vector<int64_t>& times, int64_t u0, int64_t u1, bool contact,
                    CaseTally* cases) {
  const int64_t first = times.front(), last = times.back();
  cases->Add("starts mid-pair", first > u0 && first < u1, contact);
  cases->Add("stops mid-pair", last > u0 && last < u1, contact);
  cases->Add("one sample in the pair", times.size() == 1 && first >= u0 && first <= u1, contact);
  cases->Add("ends as the pair starts", last == u0, contact);
  cases->Add("starts as the pair ends", first == u1, contact);
  cases->Add("no overlap (no window)", last < u0 || first > u1, contact);
}
// AddWindowCases's cases that must occur, with contacts among them.
void ExpectWindowCases(const CaseTally& cases) {
  cases.Expect("starts mid-pair", 40, 10);
  cases.Expect("stops mid-pair", 40, 10);
  cases.Expect("one sample in the pair", 10, 2);
  cases.Expect("ends as the pair starts", 10, 2);
  cases.Expect("starts as the pair ends", 10, 2);
}

TEST(EntityCcdRandom, LinkLinkAgainstDenseSampling) {
  Tally tally;
  CaseTally cases;
  for (int seed = 0; seed < 600; ++seed) {
    Rng rng(1000 + seed);
    World w;
    Pose p0, p1;
    RandomAvatarWorld(rng, &w, &p0, &p1);
    EntityQueryOptions opt;
    opt.eps_s = rng.P(0.5) ? 1e-4 : 1e-3;
    opt.per_link = rng.P(0.3);
    const int contacts_before = tally.contact, initially_before = tally.initially;
    CheckPair(w, 0, 1, -1, p0, p1, opt, &tally, 600, "seed " + std::to_string(seed));
    if (HasFatalFailure()) return;
    const bool contact = tally.contact > contacts_before;
    const AvatarEntity& B = w.avatars[1];
    std::vector<int64_t> times;
    for (const Pose& p : B.used) times.push_back(p.utime);
    AddWindowCases(times, p0.utime, p1.utime, contact, &cases);
    cases.Add("90 Hz against 72 Hz", B.used.size() > 1 && times[1] - times[0] == 11'111, contact);
    cases.Add("a 180-degree turn (A or B)", AnyHalfTurn(w.avatars[0].used) || AnyHalfTurn(B.used),
              contact);
    cases.Add("a zero-length link (A or B)",
              AnyZeroLength(w.avatars[0].skeleton) || AnyZeroLength(B.skeleton), contact);
    cases.Add("initially interpenetrating", tally.initially > initially_before, contact);
    cases.Add(
        "both articulated",
        w.avatars[0].motion == MotionModel::kArticulated && B.motion == MotionModel::kArticulated,
        contact);
    cases.Add(
        "both independent",
        w.avatars[0].motion == MotionModel::kIndependent && B.motion == MotionModel::kIndependent,
        contact);
    cases.Add("per link", opt.per_link, contact);
  }
  // The generator makes both answers common (not a test of the engine, of
  // the suite: it must exercise both, and every listed case).
  std::printf("%d contact (%d initially), %d free (%d by box)\n", tally.contact, tally.initially,
              tally.free, tally.culled);
  EXPECT_GT(tally.contact, 60);
  EXPECT_GT(tally.initially, 10);
  EXPECT_GT(tally.free, 40);
  EXPECT_EQ(tally.undecided, 0);
  ExpectWindowCases(cases);
  cases.Expect("no overlap (no window)", 5, 0);
  cases.Expect("90 Hz against 72 Hz", 200, 40);
  cases.Expect("a 180-degree turn (A or B)", 100, 20);
  cases.Expect("a zero-length link (A or B)", 100, 20);
  cases.Expect("initially interpenetrating", 10, 10);
  cases.Expect("both articulated", 60, 10);
  cases.Expect("both independent", 60, 10);
  cases.Expect("per link", 100, 20);
}

TEST(EntityCcdRandom, LinkObjectAgainstDenseSampling) {
  Tally tally;
  CaseTally cases;
  for (int seed = 0; seed < 600; ++seed) {
    Rng rng(5000 + seed);
    World w;
    Pose p0, p1;
    RandomObjectWorld(rng, &w, &p0, &p1);
    EntityQueryOptions opt;
    opt.eps_s = rng.P(0.5) ? 1e-4 : 1e-3;
    opt.per_link = rng.P(0.3);
    const int contacts_before = tally.contact, initially_before = tally.initially;
    CheckPair(w, 0, -1, 0, p0, p1, opt, &tally, 600, "seed " + std::to_string(seed));
    if (HasFatalFailure()) return;
    const bool contact = tally.contact > contacts_before;
    const ObjectEntity& O = w.objects[0];
    std::vector<int64_t> times;
    for (const RigidSample& x : O.used) times.push_back(x.utime);
    AddWindowCases(times, p0.utime, p1.utime, contact, &cases);
    // The thin plate (two triangles) thrown at 3 m a sample: 270 m/s at 90 Hz.
    const bool thrown = O.mesh->object(0).bvh.num_triangles() == 2 && O.used.size() > 1 &&
                        (O.used[1].p - O.used[0].p).norm() > 2.9;
    cases.Add("a thin plate thrown through", thrown, contact);
    cases.Add("a 180-degree turn (A or object)",
              AnyHalfTurn(w.avatars[0].used) || AnyHalfTurn(O.used), contact);
    cases.Add("a zero-length link", AnyZeroLength(w.avatars[0].skeleton), contact);
    cases.Add("initially interpenetrating", tally.initially > initially_before, contact);
    cases.Add("per link", opt.per_link, contact);
  }
  std::printf("%d contact (%d initially), %d free (%d by box)\n", tally.contact, tally.initially,
              tally.free, tally.culled);
  EXPECT_GT(tally.contact, 60);
  EXPECT_GT(tally.initially, 10);
  EXPECT_GT(tally.free, 40);
  EXPECT_EQ(tally.undecided, 0);
  ExpectWindowCases(cases);
  cases.Expect("a thin plate thrown through", 60, 10);
  cases.Expect("a 180-degree turn (A or object)", 100, 20);
  cases.Expect("a zero-length link", 100, 20);
  cases.Expect("initially interpenetrating", 10, 10);
  cases.Expect("per link", 100, 20);
}

// Under a small work limit (1 to 8 intervals): undecided brackets keep G1,
// end at t_to and carry a witness (SPEC 8: at least one for a contact), the
// nearest of E at the bracket's start by the reference.
TEST(EntityCcdRandom, UndecidedBracketsKeepG1AndCarryAWitness) {
  Tally avatars, objects;
  for (int seed = 0; seed < 300; ++seed) {
    for (int kind = 0; kind < 2; ++kind) {
      Rng rng((kind == 0 ? 1000 : 5000) + seed);
      World w;
      Pose p0, p1;
      if (kind == 0) {
        RandomAvatarWorld(rng, &w, &p0, &p1);
      } else {
        RandomObjectWorld(rng, &w, &p0, &p1);
      }
      EntityQueryOptions opt;
      opt.per_link = rng.P(0.3);
      opt.max_intervals = 1 + rng.I(8);
      CheckPair(w, 0, kind == 0 ? 1 : -1, kind == 0 ? -1 : 0, p0, p1, opt,
                kind == 0 ? &avatars : &objects, 300,
                "seed " + std::to_string(seed) + " kind " + std::to_string(kind));
      if (HasFatalFailure()) return;
    }
  }
  std::printf("undecided: %d of %d avatar contacts, %d of %d object contacts\n", avatars.undecided,
              avatars.contact, objects.undecided, objects.contact);
  EXPECT_GT(avatars.undecided, 20);
  EXPECT_GT(objects.undecided, 20);
}

// ------------------------------------------------- link-level broad phase

// LinkSweepBoxes against the boxes the descent builds: for random motions
// (both models, 180-degree turns, zero-length links) and random parts
// [s0, s1] of [0, 1] (whole, tiny, at the ends), the box of every swept
// capsule and every instant segment, with the descent's margins, lies in
// the link's box.
TEST(EntityCcdLinkBoxes, HoldEverySweptAndInstantBox) {
  int checked = 0;
  for (int seed = 0; seed < 300; ++seed) {
    Rng rng(9000 + seed);
    const int n = 1 + rng.I(6);
    const Skeleton sk = RandomSkeleton(rng, n, true);
    const MotionModel model = rng.P(0.5) ? MotionModel::kArticulated : MotionModel::kIndependent;
    const Pose p0 = RandomPose(rng, n, 1'000'000, Vector3d(rng.Box(3.0)), 0.3);
    const Pose p1 = rng.P(0.1) ? p0 : NextPose(rng, p0, 1'013'889, rng.U(0.0, 0.3));
    const PairMotion motion(sk, p0, p1, model);
    const double extra = rng.P(0.3) ? 0.0 : rng.U(0, 1e-3);
    const std::vector<Aabb> boxes = LinkSweepBoxes(sk, motion, extra);
    // As AnswerOther uses A's: with extra 0, apart only by more than the
    // extra (BoxesApart's margin).
    const std::vector<Aabb> base = LinkSweepBoxes(sk, motion, 0.0);
    ASSERT_EQ(static_cast<int>(boxes.size()), n);
    ASSERT_EQ(static_cast<int>(base.size()), n);
    auto inside = [](const Aabb& x, const Aabb& outer) {
      return (outer.lo.array() <= x.lo.array()).all() && (x.hi.array() <= outer.hi.array()).all();
    };
    const double margin = extra * (1 + 1e-8);
    auto inside_base = [&](const Aabb& x, int l) {
      Aabb grown = base[l];
      grown.lo.array() -= margin;
      grown.hi.array() += margin;
      return inside(x, grown);
    };
    for (int trial = 0; trial < 200; ++trial) {
      double s0 = rng.U(0, 1), s1 = rng.U(0, 1);
      if (s0 > s1) std::swap(s0, s1);
      if (trial % 5 == 0) s1 = std::min(1.0, s0 + rng.U(0, 1e-6));
      if (trial == 1) s0 = 0, s1 = 1;
      if (trial == 2) s0 = 0;
      if (trial == 3) s1 = 1;
      for (LinkIndex l(0); l < n; ++l) {
        Vector3d a, b;
        double g;
        motion.SweptCapsule(l, s0, s1, &a, &b, &g);
        const double r = sk.link(l).radius + extra;
        const Aabb swept = Aabb::OfCapsule(a, b, (r + g) * (1 + 1e-9) + 1e-9);
        ASSERT_TRUE(inside(swept, boxes[l])) << "seed " << seed << " link " << l;
        ASSERT_TRUE(inside_base(swept, l)) << "seed " << seed << " link " << l;
        motion.SegmentAt(l, s0, &a, &b);
        const Aabb instant = Aabb::OfCapsule(a, b, r * (1 + 1e-9) + 1e-9);
        ASSERT_TRUE(inside(instant, boxes[l])) << "seed " << seed << " link " << l;
        ASSERT_TRUE(inside_base(instant, l)) << "seed " << seed << " link " << l;
        ++checked;
      }
    }
  }
  EXPECT_GT(checked, 100000);
}

// The broad phase's brute-force twin: two random avatars moving over one
// pair each; every link pair whose boxes are apart is separated at dense
// samples of both motions (the capsules at s, for s over [0, 1]). Both
// kinds of pair must occur.
TEST(EntityCcdLinkBoxes, ApartMeansSeparatedAtDenseSamples) {
  int apart = 0, near = 0;
  for (int seed = 0; seed < 300; ++seed) {
    Rng rng(12000 + seed);
    Skeleton sk[2];
    PairMotion* motions[2];
    std::vector<PairMotion> held;
    held.reserve(2);
    for (int e = 0; e < 2; ++e) {
      const int n = 1 + rng.I(5);
      sk[e] = RandomSkeleton(rng, n, true);
      const MotionModel model = rng.P(0.5) ? MotionModel::kArticulated : MotionModel::kIndependent;
      const Pose p0 = RandomPose(rng, n, 1'000'000, Vector3d(rng.Box(0.6)), 0.3);
      const Pose p1 = NextPose(rng, p0, 1'011'111, rng.U(0.0, 0.3));
      held.emplace_back(sk[e], p0, p1, model);
    }
    motions[0] = &held[0];
    motions[1] = &held[1];
    const std::vector<Aabb> boxes0 = LinkSweepBoxes(sk[0], *motions[0], 0.0);
    const std::vector<Aabb> boxes1 = LinkSweepBoxes(sk[1], *motions[1], 0.0);
    for (LinkIndex i(0); i < sk[0].num_links(); ++i) {
      for (LinkIndex j(0); j < sk[1].num_links(); ++j) {
        if (!BoxesApart(boxes0[i], boxes1[j])) {
          ++near;
          continue;
        }
        ++apart;
        for (int k = 0; k <= 400; ++k) {
          const double s = k / 400.0;
          Vector3d a0, b0, a1, b1, c0, c1;
          motions[0]->SegmentAt(i, s, &a0, &b0);
          motions[1]->SegmentAt(j, s, &a1, &b1);
          const double d = std::sqrt(SegmentSegmentDistanceSquared(a0, b0, a1, b1, &c0, &c1));
          ASSERT_GT(d - sk[0].link(i).radius - sk[1].link(j).radius, 0)
              << "seed " << seed << " links " << i << " " << j << " s " << s;
        }
      }
    }
  }
  std::printf("%d link pairs apart, %d near\n", apart, near);
  EXPECT_GT(apart, 300);
  EXPECT_GT(near, 300);
}

// A target without link boxes (and whose PieceBoxMeets is the whole
// PieceBox): the descent as it was before the link-level broad phase.
class WithoutLinkBoxes : public OtherTarget {
 public:
  explicit WithoutLinkBoxes(const OtherTarget& t) : t_(t) {}
  void RootCandidatesInto(LinkIndex link_a, std::vector<int>* out) const override {
    t_.RootCandidatesInto(link_a, out);
  }
  Aabb PieceBox(const Piece& p, double tau0, double tau1) const override {
    return t_.PieceBox(p, tau0, tau1);
  }
  void Cull(const Piece& p, double tau0, double tau1, const Vector3d& a, const Vector3d& b,
            double radius_a, double growth_a, std::vector<int>* cands) const override {
    t_.Cull(p, tau0, tau1, a, b, radius_a, growth_a, cands);
  }
  bool Nearest(const Piece& p, double tau, LinkIndex link_a, const Vector3d& a, const Vector3d& b,
               double radius_a, const std::vector<int>& cands, double search,
               OtherContact* out) const override {
    return t_.Nearest(p, tau, link_a, a, b, radius_a, cands, search, out);
  }
  double tolerance() const override { return t_.tolerance(); }

 private:
  const OtherTarget& t_;
};

bool SameBits(double x, double y) { return std::memcmp(&x, &y, sizeof x) == 0; }
bool SameBits(const Vector3d& x, const Vector3d& y) {
  return SameBits(x.x(), y.x()) && SameBits(x.y(), y.y()) && SameBits(x.z(), y.z());
}
void ExpectSameBracket(const OtherBracket& x, const OtherBracket& y) {
  EXPECT_EQ(x.link, y.link);
  EXPECT_TRUE(SameBits(x.tau_lo, y.tau_lo) && SameBits(x.tau_hi, y.tau_hi));
  EXPECT_EQ(x.initially_colliding, y.initially_colliding);
  EXPECT_EQ(x.undecided, y.undecided);
  EXPECT_EQ(x.has_witness, y.has_witness);
  if (!x.has_witness || !y.has_witness) return;
  EXPECT_EQ(x.witness.link, y.witness.link);
  EXPECT_EQ(x.witness.other_link, y.witness.other_link);
  EXPECT_TRUE(SameBits(x.witness.tau, y.witness.tau));
  EXPECT_TRUE(SameBits(x.witness.point_link, y.witness.point_link));
  EXPECT_TRUE(SameBits(x.witness.point_other, y.witness.point_other));
  EXPECT_TRUE(SameBits(x.witness.normal, y.witness.normal));
  EXPECT_TRUE(SameBits(x.witness.separation, y.witness.separation));
}

// The link-level broad phase never changes an answer: random avatar pairs
// (close, so that both contacts and free answers occur), answered with and
// without the link boxes, agree bit for bit, per-link mode and small work
// limits included (where the descent runs out of work at the same item).
TEST(EntityCcdLinkBoxes, NeverChangeAnAnswer) {
  int contact = 0, n_free = 0, undecided = 0, by_link_boxes = 0;
  for (int seed = 0; seed < 3000; ++seed) {
    Rng rng(15000 + seed);
    World w;
    Pose p0, p1;
    RandomAvatarWorld(rng, &w, &p0, &p1);
    EntityQueryOptions opt;
    opt.eps_s = rng.P(0.5) ? 1e-4 : 1e-3;
    opt.per_link = rng.P(0.3);
    if (rng.P(0.2)) opt.max_intervals = 1 + rng.I(40);
    if (rng.P(0.5)) {  // A slower (its links' boxes tighter).
      p1.links = p0.links;
      for (LinkPose& l : p1.links) l.p += rng.Box(0.02);
      w.avatars[0].used[1] = p1;
    }
    if (rng.P(0.5)) {  // B slower too.
      for (size_t i = 1; i < w.avatars[1].used.size(); ++i) {
        w.avatars[1].used[i].links = w.avatars[1].used[i - 1].links;
        for (LinkPose& l : w.avatars[1].used[i].links) l.p += rng.Box(0.02);
      }
    }
    if (rng.P(0.5)) {  // B moved off: near misses, boxes that meet while links do not.
      const Vector3d shift = rng.Dir() * rng.U(0.2, 1.0);
      for (Pose& p : w.avatars[1].used) {
        for (LinkPose& l : p.links) l.p += shift;
      }
    }
    std::vector<int64_t> times;
    for (const Pose& p : w.avatars[1].used) times.push_back(p.utime);
    const int64_t t_from = std::max(p0.utime, times.front());
    const int64_t t_to = std::min(p1.utime, times.back());
    if (t_from > t_to) continue;
    const std::vector<Piece> pieces = SplitWindow(p0.utime, t_from, t_to, times);
    const PairMotion motion(w.avatars[0].skeleton, p0, p1, w.avatars[0].motion);
    // The link boxes alone: near boxes spare items the descent would visit
    // (a pair they clear is culled only deeper down), so under a small work
    // limit they can answer where the descent alone runs out of work.
    const auto boxed_target = MakeAvatarTarget(AvatarOf(w, 0).who, AvatarOf(w, 1));
    const WithoutNearBoxes target(*boxed_target);
    const auto plain_target =
        MakeAvatarTarget(AvatarOf(w, 0).who, AvatarOf(w, 1));  // Its own memos.
    const WithoutLinkBoxes plain(*plain_target);
    const OtherAnswer x =
        AnswerOther(w.avatars[0].skeleton, motion, p0.utime, p1.utime, pieces, target, opt);
    const OtherAnswer y =
        AnswerOther(w.avatars[0].skeleton, motion, p0.utime, p1.utime, pieces, plain, opt);
    SCOPED_TRACE("seed " + std::to_string(seed));
    ASSERT_EQ(x.contact, y.contact);
    if (x.contact) ExpectSameBracket(x.bracket, y.bracket);
    ASSERT_EQ(x.links.size(), y.links.size());
    for (size_t i = 0; i < x.links.size(); ++i) ExpectSameBracket(x.links[i], y.links[i]);
    contact += x.contact && !x.bracket.undecided;
    undecided += x.contact && x.bracket.undecided;
    n_free += !x.contact;
    by_link_boxes += x.culled_by_box && !y.culled_by_box;  // No descent, where it ran before.
  }
  std::printf("%d contact, %d undecided, %d free (%d by the link boxes alone)\n", contact,
              undecided, n_free, by_link_boxes);
  EXPECT_GT(by_link_boxes, 20);
  EXPECT_GT(contact, 60);
  EXPECT_GT(undecided, 5);
  EXPECT_GT(n_free, 40);
}

// Two one-link avatars; B's link is placed by the caller.
World TwoCapsules(double ra, double rb) {
  World w;
  w.avatars.resize(2);
  w.rules.assign(2, {});
  for (int e = 0; e < 2; ++e) {
    Link l;
    l.name = "bar";
    l.a_L = Vector3d(-0.5, 0, 0);
    l.b_L = Vector3d(0.5, 0, 0);
    l.radius = e == 0 ? ra : rb;
    w.avatars[e].id = e == 0 ? "a" : "b";
    w.avatars[e].skeleton = Skeleton::FromLinks("bar", {l}, "test");
  }
  return w;
}

Pose At(int64_t utime, const Vector3d& p) {
  Pose pose;
  pose.utime = utime;
  pose.links = {LinkPose{p, Quaterniond::Identity()}};
  return pose;
}

TEST(EntityCcdCases, ExactlyTouchingAndGrazing) {
  EntityQueryOptions opt;
  Tally tally;
  // Exactly touching all along (0.25 + 0.125 = 0.375, exact in binary):
  // initially colliding.
  {
    World w = TwoCapsules(0.25, 0.125);
    Pose p0 = At(0, {0, 0, 0}), p1 = At(10'000, {0.5, 0, 0});
    w.avatars[0].used = {p0, p1};
    w.avatars[1].used = {At(0, {0, 0.375, 0}), At(20'000, {1.25, 0.375, 0})};
    CheckPair(w, 0, 1, -1, p0, p1, opt, &tally);
    EXPECT_EQ(tally.initially, 1);
  }
  // Grazing at the last instant only: B comes down to touch at t_to.
  {
    World w = TwoCapsules(0.25, 0.125);
    Pose p0 = At(0, {0, 0, 0}), p1 = At(10'000, {0, 0, 0});
    w.avatars[0].used = {p0, p1};
    w.avatars[1].used = {At(0, {0, 1.0, 0}), At(10'000, {0, 0.375, 0})};
    Tally t2;
    CheckPair(w, 0, 1, -1, p0, p1, opt, &t2);
    EXPECT_EQ(t2.contact, 1);
    EXPECT_EQ(t2.initially, 0);
  }
  // Missing by 1 mm + a bit more than delta: free.
  {
    World w = TwoCapsules(0.25, 0.125);
    Pose p0 = At(0, {0, 0, 0}), p1 = At(10'000, {0, 0, 0});
    w.avatars[0].used = {p0, p1};
    w.avatars[1].used = {At(0, {0, 1.0, 0}), At(10'000, {0, 0.378, 0})};
    Tally t3;
    CheckPair(w, 0, 1, -1, p0, p1, opt, &t3);
    EXPECT_EQ(t3.free, 1);
  }
}

TEST(EntityCcdCases, InterpenetratingZeroLengthAndWindows) {
  EntityQueryOptions opt;
  opt.per_link = true;
  World w = TwoCapsules(0.1, 0.1);
  // A sphere link (zero length) for B.
  Link s;
  s.name = "ball";
  s.radius = 0.1;
  w.avatars[1].skeleton = Skeleton::FromLinks("ball", {s}, "test");
  Pose p0 = At(0, {0, 0, 0}), p1 = At(20'000, {0, 0, 0});
  w.avatars[0].used = {p0, p1};
  // B is inside A when it appears mid-pair (t = 5000) and leaves.
  w.avatars[1].used = {At(5'000, {0.2, 0.05, 0}), At(15'000, {0.2, 2, 0})};
  Tally tally;
  CheckPair(w, 0, 1, -1, p0, p1, opt, &tally);
  EXPECT_EQ(tally.initially, 1);
  // One instant only (B has one sample inside the pair).
  w.avatars[1].used = {At(7'000, {0.2, 0.05, 0})};
  Tally t2;
  CheckPair(w, 0, 1, -1, p0, p1, opt, &t2);
  EXPECT_EQ(t2.initially, 1);
  // Samples only after the pair, or only before it: no window, so no entry
  // (SPEC 8), though the capsules would overlap if B were there.
  for (const std::vector<int64_t>& times :
       {std::vector<int64_t>{30'000, 40'000}, std::vector<int64_t>{-20'000, -1}}) {
    LoadedWorld lw;
    lw.world = w;
    lw.world.avatars[1].used.clear();
    for (int64_t t : times) lw.world.avatars[1].used.push_back(At(t, {0.2, 0.05, 0}));
    PairOutcome rec;
    rec.valid = true;
    rec.pose0 = p0;
    rec.pose1 = p1;
    lw.world.avatars[0].records = {rec};
    for (int e = 0; e < 2; ++e) lw.env_filters.emplace_back(1, 0);
    const WorldAnswerer answerer(lw, QueryOptions());
    OtherAnswer ans;
    int64_t t_from = -7, t_to = -7;
    EXPECT_FALSE(AnswerEntity(answerer, 0, 0, 1, -1, &ans, &t_from, &t_to)) << times.front();
    EXPECT_TRUE(SplitWindow(p0.utime, std::max(p0.utime, times.front()),
                            std::min(p1.utime, times.back()), times)
                    .empty());
  }
}

// A link of an avatar and a tracked object given the same two orientations
// turn alike, bit for bit, through turns of exactly 180 degrees and one ulp
// off them, where the rounded dot is noise around 0 (found by a review: the
// avatar kept the long arc where the object took the short one). Both
// normalise the same way and decide SPEC 3's sign exactly.
TEST(EntityCcdCases, AvatarAndObjectTurnAlikeThroughHalfTurns) {
  Rng rng(4242);
  Link link;
  link.name = "l";
  link.b_L = Vector3d(0.3, 0, 0);
  link.radius = 0.05;
  const Skeleton skeleton = Skeleton::FromLinks("one", {link}, "test");
  const Quaterniond axes[3] = {{0, 1, 0, 0}, {0, 0, 1, 0}, {0, 0, 0, 1}};
  int flipped = 0;
  for (int c = 0; c < 3000; ++c) {
    const Quaterniond q0 = rng.Quat();
    Quaterniond q1 = q0 * axes[c % 3];
    if (c % 2 == 1) {
      const int k = rng.I(4);
      q1.coeffs()[k] = std::nextafter(q1.coeffs()[k], rng.P(0.5) ? 2.0 : -2.0);
    }
    // As written in a stream: scaled (not unit), the same numbers for both.
    const double scale0 = rng.U(0.5, 2.0), scale1 = rng.U(0.5, 2.0);
    Pose p0, p1;
    p0.utime = 0;
    p1.utime = 10'000;
    p0.links = {LinkPose{Vector3d(0, 0, 0), Quaterniond(q0.coeffs() * scale0)}};
    p1.links = {LinkPose{Vector3d(0.1, 0, 0), Quaterniond(q1.coeffs() * scale1)}};
    const double v0[7] = {
        0, 0, 0, p0.links[0].q.w(), p0.links[0].q.x(), p0.links[0].q.y(), p0.links[0].q.z()};
    const double v1[7] = {
        0.1, 0, 0, p1.links[0].q.w(), p1.links[0].q.x(), p1.links[0].q.y(), p1.links[0].q.z()};
    ASSERT_EQ(ValidateAndNormalizePose(&p0, 1), "");
    ASSERT_EQ(ValidateAndNormalizePose(&p1, 1), "");
    RigidSample x0, x1;
    ASSERT_EQ(MakeRigidSample(0, v0, &x0), "");
    ASSERT_EQ(MakeRigidSample(10'000, v1, &x1), "");
    ASSERT_EQ(x0.q.coeffs(), p0.links[0].q.coeffs()) << "the same normalisation, case " << c;
    ASSERT_EQ(x1.q.coeffs(), p1.links[0].q.coeffs()) << "case " << c;
    const PairMotion avatar(skeleton, p0, p1, MotionModel::kIndependent);
    const RigidMotion object(x0, x1);
    for (double s : {0.125, 0.5, 0.75}) {
      ASSERT_EQ(avatar.PoseAt(LinkIndex(0), s).q.coeffs(), object.RotationAt(s).coeffs())
          << "case " << c << " s " << s;
    }
    // And the arc is SPEC 3's (the twin's, which decides the sign near 0 in
    // binary128): the same rotation up to rounding, not the other arc.
    const twin::QL want = twin::TwinSlerp(twin::ToQL(x0.q), twin::ToQL(x1.q), 0.5L);
    const Quaterniond got = object.RotationAt(0.5);
    const double diff =
        std::max({std::fabs(double(want.w) - got.w()), std::fabs(double(want.x) - got.x()),
                  std::fabs(double(want.y) - got.y()), std::fabs(double(want.z) - got.z())});
    ASSERT_LT(diff, 1e-9) << "the other arc, case " << c;
    flipped += internal::DotSign(x0.q.coeffs().data(), x1.q.coeffs().data()) < 0;
  }
  EXPECT_GT(flipped, 300);  // Both arcs occur.
  EXPECT_LT(flipped, 2700);
}

TEST(EntityCcdCases, FiltersApplyFromEitherAvatar) {
  EntityQueryOptions opt;
  World w = TwoCapsules(0.1, 0.1);
  Pose p0 = At(0, {0, 0, 0}), p1 = At(10'000, {0, 0, 0});
  w.avatars[0].used = {p0, p1};
  w.avatars[1].used = {At(0, {0, 0.1, 0}), At(10'000, {0, 0.1, 0})};
  Tally t0;
  CheckPair(w, 0, 1, -1, p0, p1, opt, &t0);
  EXPECT_EQ(t0.contact, 1);
  // B's rule about A's link 0 silences A's answer too.
  w.rules[1].push_back(EntityRule{LinkIndex(0), "a", LinkIndex(0)});
  const auto target = MakeAvatarTarget(AvatarOf(w, 0).who, AvatarOf(w, 1));
  EXPECT_TRUE(target->RootCandidates(LinkIndex(0)).empty());
  Tally t1;
  CheckPair(w, 0, 1, -1, p0, p1, opt, &t1);
  EXPECT_EQ(t1.free, 1);
  EXPECT_TRUE(w.IgnoresLinkPair(AvatarIndex(1), LinkIndex(0), AvatarIndex(0), LinkIndex(0)));
}

TEST(EntityCcdCases, SplitWindowAtSampleTimes) {
  const std::vector<int64_t> samples = {90, 100, 111, 122, 133};
  const std::vector<Piece> pieces = SplitWindow(95, 95, 120, samples);
  ASSERT_EQ(pieces.size(), 3u);
  EXPECT_EQ(pieces[0].tau0, 0);
  EXPECT_EQ(pieces[0].tau1, 5);
  EXPECT_EQ(pieces[1].tau0, 5);
  EXPECT_EQ(pieces[1].tau1, 16);
  EXPECT_EQ(pieces[2].tau1, 25);
  EXPECT_EQ(pieces[2].k, 2);
  EXPECT_DOUBLE_EQ(pieces[2].SE(25), 9.0 / 11.0);
  const std::vector<Piece> instant = SplitWindow(95, 111, 111, samples);
  ASSERT_EQ(instant.size(), 1u);
  EXPECT_EQ(instant[0].tau0, instant[0].tau1);
  // Regression: the instant of the last sample (an entity that stops as
  // the pair starts) is the end of the last interval.
  const std::vector<Piece> last = SplitWindow(133, 133, 133, samples);
  ASSERT_EQ(last.size(), 1u);
  EXPECT_EQ(last[0].k, 3);
  EXPECT_EQ(last[0].SE(0), 1.0);
  const std::vector<Piece> first = SplitWindow(80, 90, 90, samples);
  ASSERT_EQ(first.size(), 1u);
  EXPECT_EQ(first[0].k, 0);
  EXPECT_EQ(first[0].SE(10), 0.0);
  // A window over the whole stream: one piece per interval, contiguous.
  const std::vector<Piece> all = SplitWindow(90, 90, 133, samples);
  ASSERT_EQ(all.size(), 4u);
  for (size_t i = 1; i < all.size(); ++i) EXPECT_EQ(all[i].tau0, all[i - 1].tau1);
}

// The world's broad phase (per-entity boxes of every sample interval) never
// changes an answer: every (record, entity) of random worlds of four avatars
// and two objects, through WorldAnswerer, equals AnswerOther run directly,
// and an entity the boxes clear is free by AnswerOther too. AnswerOther on
// a new thread (no kept arrays) gives the direct answer bit for bit, also
// per link with a small work limit.
TEST(EntityCcdWorld, BroadPhaseNeverChangesAnAnswer) {
  int culled = 0, contacts = 0, undecided = 0, per_link_brackets = 0;
  for (int seed = 0; seed < 12; ++seed) {
    Rng rng(9000 + seed);
    LoadedWorld lw;
    World& w = lw.world;
    for (int e = 0; e < 4; ++e) {
      AvatarEntity A;
      A.id = "a" + std::to_string(e);
      A.skeleton = RandomSkeleton(rng, 1 + rng.I(4), true);
      A.motion = rng.P(0.5) ? MotionModel::kArticulated : MotionModel::kIndependent;
      const int64_t step = 8'000 + rng.I(8'000);
      Pose p = RandomPose(rng, A.skeleton.num_links(), rng.I(20'000), Vector3d(rng.Box(1.0)), 0.3);
      for (int k = 0; k < 8; ++k) {
        A.used.push_back(p);
        if (k > 0) {
          PairOutcome out;
          out.pair = k - 1;
          out.valid = true;
          out.pose0 = A.used[k - 1];
          out.pose1 = p;
          A.records.push_back(out);
        }
        p = NextPose(rng, p, p.utime + step, 0.2);
      }
      w.avatars.push_back(A);
      lw.env_filters.emplace_back(A.skeleton.num_links(), 0);
    }
    w.rules.assign(4, {});
    for (int e = 0; e < 2; ++e) {
      ObjectEntity O;
      O.id = "o" + std::to_string(e);
      auto mesh = std::make_shared<Environment>();
      mesh->AddMesh(RandomMesh(rng, false), "mesh");
      O.mesh = std::move(mesh);
      RigidSample x;
      x.utime = rng.I(30'000);
      x.p = rng.Box(1.0);
      for (int k = 0; k < 6; ++k) {
        O.used.push_back(x);
        x.utime += 11'111;
        x.p += rng.Box(0.2);
        x.q = (rng.Turn(rng.U(0, 1.0)) * x.q).normalized();
      }
      w.objects.push_back(std::move(O));
    }
    QueryOptions qo;
    EntityQueryOptions eo, eo_pl;
    eo_pl.per_link = true;
    eo_pl.max_intervals = 40;
    // The records avatar by avatar, then in reverse time order from a fresh
    // answerer (its memos and kept interval motions see other orders).
    std::vector<std::pair<int, size_t>> order;
    for (int a = 0; a < 4; ++a) {
      for (size_t r = 0; r < w.avatars[a].records.size(); ++r) order.emplace_back(a, r);
    }
    std::vector<std::pair<int, size_t>> reversed = order;
    std::sort(reversed.begin(), reversed.end(), [&](const auto& x, const auto& y) {
      return w.avatars[x.first].records[x.second].pose1.utime >
             w.avatars[y.first].records[y.second].pose1.utime;
    });
    order.insert(order.end(), reversed.begin(), reversed.end());
    std::optional<WorldAnswerer> answerer;
    for (size_t i = 0; i < order.size(); ++i) {
      if (i == 0 || i == reversed.size()) answerer.emplace(lw, qo);
      const auto [a, r] = order[i];
      {
        const PairOutcome& rec = w.avatars[a].records[r];
        for (int e = 0; e < 6; ++e) {
          const int b = e < 4 ? e : -1, o = e < 4 ? -1 : e - 4;
          if (b == a) continue;
          OtherAnswer via_world;
          int64_t t_from, t_to;
          if (!AnswerEntity(*answerer, a, r, b, o, &via_world, &t_from, &t_to)) continue;
          std::vector<int64_t> times;
          if (b >= 0) {
            for (const Pose& p : w.avatars[b].used) times.push_back(p.utime);
          } else {
            for (const RigidSample& x : w.objects[o].used) times.push_back(x.utime);
          }
          const PairMotion motion(w.avatars[a].skeleton, rec.pose0, rec.pose1, w.avatars[a].motion);
          // The pair's box, which the answerer takes from its per-interval
          // boxes, is the one made from the pair's own motion.
          const Aabb pair_box = answerer->PairBox(AvatarIndex(a), r);
          const Aabb own_box = AvatarMotionBox(w.avatars[a].skeleton, motion);
          EXPECT_TRUE(pair_box.lo == own_box.lo && pair_box.hi == own_box.hi) << seed << " " << a;
          const std::vector<Piece> pieces = SplitWindow(rec.pose0.utime, t_from, t_to, times);
          // Fresh: the target's own motions, a memo for this answer alone.
          const auto target = b >= 0 ? MakeAvatarTarget(AvatarOf(w, a).who, AvatarOf(w, b),
                                                        WindowScale(w.avatars[b], pieces))
                                     : MakeObjectTarget(AvatarOf(w, a).who, ObjectOf(w, o),
                                                        WindowScale(w.objects[o], pieces));
          const OtherAnswer direct = AnswerOther(w.avatars[a].skeleton, motion, rec.pose0.utime,
                                                 rec.pose1.utime, pieces, *target, eo);
          ASSERT_EQ(via_world.contact, direct.contact) << seed << " " << a << " " << r << " " << e;
          {
            // The same call on a new thread, which starts without the
            // arrays AnswerOther keeps per thread: bit for bit the same
            // (nothing carries over from the calls before it); also in
            // per-link mode with a small work limit, on both threads.
            OtherAnswer fresh, fresh_pl;
            const OtherAnswer direct_pl =
                AnswerOther(w.avatars[a].skeleton, motion, rec.pose0.utime, rec.pose1.utime, pieces,
                            *target, eo_pl);
            std::thread([&] {
              fresh = AnswerOther(w.avatars[a].skeleton, motion, rec.pose0.utime, rec.pose1.utime,
                                  pieces, *target, eo);
              fresh_pl = AnswerOther(w.avatars[a].skeleton, motion, rec.pose0.utime,
                                     rec.pose1.utime, pieces, *target, eo_pl);
            }).join();
            EXPECT_EQ(fresh.contact, direct.contact);
            EXPECT_EQ(fresh.culled_by_box, direct.culled_by_box);
            EXPECT_EQ(fresh.intervals, direct.intervals);
            if (direct.contact) ExpectSameBracket(fresh.bracket, direct.bracket);
            EXPECT_EQ(fresh_pl.contact, direct_pl.contact);
            EXPECT_EQ(fresh_pl.culled_by_box, direct_pl.culled_by_box);
            EXPECT_EQ(fresh_pl.intervals, direct_pl.intervals);
            ASSERT_EQ(fresh_pl.links.size(), direct_pl.links.size());
            for (size_t k = 0; k < fresh_pl.links.size(); ++k) {
              ExpectSameBracket(fresh_pl.links[k], direct_pl.links[k]);
            }
            undecided += direct_pl.contact && direct_pl.bracket.undecided;
            per_link_brackets += static_cast<int>(direct_pl.links.size());
            // And as the world's answer, made on this thread after calls for
            // other targets (of other sizes): the same descent.
            if (!fresh.culled_by_box && !via_world.culled_by_box) {
              EXPECT_EQ(fresh.intervals, via_world.intervals);
            }
          }
          culled += i < reversed.size() && via_world.culled_by_box;
          contacts += i < reversed.size() && direct.contact;
          if (!via_world.culled_by_box) {
            // Not cleared: the same descent, bit for bit.
            EXPECT_EQ(via_world.intervals, direct.intervals);
            EXPECT_EQ(via_world.culled_by_box, direct.culled_by_box);
          }
          if (direct.contact) {
            EXPECT_EQ(via_world.bracket.tau_lo, direct.bracket.tau_lo);
            EXPECT_EQ(via_world.bracket.tau_hi, direct.bracket.tau_hi);
            EXPECT_EQ(via_world.bracket.initially_colliding, direct.bracket.initially_colliding);
            EXPECT_EQ(via_world.bracket.witness.link, direct.bracket.witness.link);
            EXPECT_EQ(via_world.bracket.witness.other_link, direct.bracket.witness.other_link);
            EXPECT_EQ(via_world.bracket.witness.triangle, direct.bracket.witness.triangle);
            EXPECT_EQ(via_world.bracket.witness.point_link, direct.bracket.witness.point_link);
            EXPECT_EQ(via_world.bracket.witness.point_other, direct.bracket.witness.point_other);
            EXPECT_EQ(via_world.bracket.witness.separation, direct.bracket.witness.separation);
          }
        }
      }
    }
  }
  std::printf(
      "%d culled by the world's boxes, %d contacts; per-link, limit 40: %d brackets, "
      "%d answers out of work\n",
      culled, contacts, per_link_brackets, undecided);
  EXPECT_GT(culled, 50);
  EXPECT_GT(contacts, 10);
  EXPECT_GT(per_link_brackets, 10);
  EXPECT_GT(undecided, 0);
}

// The broad phase's boxes against dense sampling: every link's capsule (its
// segment at 401 instants, 11 points along it, grown by the radius along
// each axis) lies in AvatarMotionBox; every mesh vertex, moved by the
// object's motion at those instants, lies in ObjectMotionBox.
TEST(EntityCcdWorld, MotionBoxesHoldDenseSamples) {
  Rng rng(9100);
  int points = 0;
  for (int trial = 0; trial < 200; ++trial) {
    const Skeleton sk = RandomSkeleton(rng, 1 + rng.I(8), true);
    const MotionModel model = rng.P(0.5) ? MotionModel::kArticulated : MotionModel::kIndependent;
    const Pose p0 = RandomPose(rng, sk.num_links(), 0, Vector3d(rng.Box(3.0)), 0.5);
    const Pose p1 = rng.P(0.1) ? p0 : NextPose(rng, p0, 11'111, rng.U(0, 0.5));
    const PairMotion motion(sk, p0, p1, model);
    const Aabb box = AvatarMotionBox(sk, motion);
    for (int i = 0; i <= 400; ++i) {
      for (LinkIndex l(0); l < sk.num_links(); ++l) {
        Vector3d a, b;
        motion.SegmentAt(l, i / 400.0, &a, &b);
        for (int f = 0; f <= 10; ++f) {
          const Vector3d x = a + (b - a) * (f / 10.0);
          for (int axis = 0; axis < 3; ++axis) {
            for (double sign : {-1.0, 1.0}) {
              const Vector3d y = x + sign * sk.link(l).radius * Vector3d::Unit(axis);
              ASSERT_TRUE((y.array() >= box.lo.array()).all() &&
                          (y.array() <= box.hi.array()).all())
                  << "trial " << trial << " link " << l << " s " << i / 400.0;
              ++points;
            }
          }
        }
      }
    }
    Environment mesh;
    mesh.AddMesh(RandomMesh(rng, rng.P(0.3)), "mesh");
    const TriangleBvh& bvh = mesh.object(0).bvh;
    RigidSample x0, x1;
    x0.p = rng.Box(3.0);
    x0.q = rng.Quat();
    x1.p = rng.P(0.1) ? x0.p : Vector3d(x0.p + rng.Box(1.0));
    x1.q = rng.P(0.1) ? x0.q : rng.Quat();
    const RigidMotion m(x0, x1);
    const Aabb obox = ObjectMotionBox(x0, x1, ObjectRadius(bvh), bvh.max_abs_coordinate());
    for (int i = 0; i <= 400; ++i) {
      const Vector3d c = m.PositionAt(i / 400.0);
      const Eigen::Matrix3d R = m.RotationAt(i / 400.0).toRotationMatrix();
      for (uint32_t t = 0; t < static_cast<uint32_t>(bvh.num_triangles()); ++t) {
        Vector3d ta, tb, tc;
        bvh.Triangle(t, &ta, &tb, &tc);
        for (const Vector3d& v : {ta, tb, tc}) {
          const Vector3d y = c + R * v;
          ASSERT_TRUE((y.array() >= obox.lo.array()).all() && (y.array() <= obox.hi.array()).all())
              << "trial " << trial << " s " << i / 400.0;
          ++points;
        }
      }
    }
  }
  EXPECT_GT(points, 1'000'000);
}

// Regression: an entity whose last sample is the pair's first instant
// exists for that instant only; touching then is a contact (the broad phase
// once skipped the last sample interval and answered `free`).
TEST(EntityCcdWorld, EntityEndingAsThePairStarts) {
  LoadedWorld lw;
  lw.world = TwoCapsules(0.1, 0.1);
  lw.world.avatars[0].used = {At(0, {0, 0, 0}), At(10'000, {0, 0, 0})};
  PairOutcome rec;
  rec.valid = true;
  rec.pose0 = lw.world.avatars[0].used[0];
  rec.pose1 = lw.world.avatars[0].used[1];
  lw.world.avatars[0].records = {rec};
  lw.world.avatars[1].used = {At(-10'000, {0, 1, 0}), At(0, {0, 0.15, 0})};
  for (int e = 0; e < 2; ++e) lw.env_filters.emplace_back(1, 0);
  const WorldAnswerer answerer(lw, QueryOptions());
  OtherAnswer ans;
  int64_t t_from, t_to;
  ASSERT_TRUE(AnswerEntity(answerer, 0, 0, 1, -1, &ans, &t_from, &t_to));
  EXPECT_EQ(t_from, 0);
  EXPECT_EQ(t_to, 0);
  ASSERT_TRUE(ans.contact);
  EXPECT_TRUE(ans.bracket.initially_colliding);
  EXPECT_EQ(ans.bracket.tau_lo, 0);
  EXPECT_EQ(ans.bracket.tau_hi, 0);
}

// ---------------------------------------------------------------- real mocap

std::string MocapPath(const std::string& file) {
  return std::string(SWEPTCCD_DATA_DIR) + "/mocap/" + file;
}

MocapClip Load(const std::string& file, int frame_step) {
  MocapImportOptions options;
  options.up_axis = 'y';
  options.frame_step = frame_step;
  return ImportBvhFile(MocapPath(file), options);
}

Vector3d RootMean(const MocapClip& clip) {
  Vector3d sum = Vector3d::Zero();
  for (const Pose& p : clip.poses) sum += p.links[clip.skeleton.root()].p;
  return sum / clip.poses.size();
}

void Shift(std::vector<Pose>* poses, const Vector3d& d, int64_t dt) {
  for (Pose& p : *poses) {
    p.utime += dt;
    for (LinkPose& l : p.links) l.p += d;
  }
}

// Runs every A pair in [first, last) against B and checks it.
Tally RunClips(const World& w, size_t first, size_t last, const EntityQueryOptions& opt) {
  Tally tally;
  const std::vector<Pose>& a = w.avatars[0].used;
  for (size_t k = first; k + 1 < a.size() && k < last; ++k) {
    CheckPair(w, 0, 1, -1, a[k], a[k + 1], opt, &tally, 120, "pair " + std::to_string(k));
    if (::testing::Test::HasFatalFailure()) break;
  }
  return tally;
}

TEST(EntityCcdMocap, TwoWalkersCrossing) {
  // Walk 02_01 at 30 Hz against walk 07_01 at 40 Hz (off-phase), the second
  // turned by 180 degrees about the vertical and placed on the first's path
  // so that they walk through each other.
  MocapClip a = Load("cmu_02_01_walk.bvh.gz", 4);
  MocapClip b = Load("cmu_07_01_walk.bvh.gz", 3);
  ASSERT_GT(a.poses.size(), 20u);
  const Quaterniond turn(Eigen::AngleAxisd(M_PI, Vector3d::UnitY()));
  const Vector3d ca = RootMean(a), cb = RootMean(b);
  for (Pose& p : b.poses) {
    for (LinkPose& l : p.links) {
      l.p = ca + turn * (l.p - cb);
      l.q = turn * l.q;
    }
  }
  Shift(&b.poses, Vector3d::Zero(), 4'321);
  World w;
  w.rules.assign(2, {});
  w.avatars.resize(2);
  w.avatars[0] = {"walker_a", a.skeleton, MotionModel::kArticulated, {}, a.poses};
  w.avatars[1] = {"walker_b", b.skeleton, MotionModel::kIndependent, {}, b.poses};
  EntityQueryOptions opt;
  const Tally t = RunClips(w, 0, 150, opt);
  std::printf("walkers: %d contact (%d initially), %d free (%d by box)\n", t.contact, t.initially,
              t.free, t.culled);
  EXPECT_GT(t.contact, 0);
  EXPECT_GT(t.free, 0);
  // As they come together, a first touch inside a pair (not only pairs that
  // start touching): the descent, not only the check at the start.
  EXPECT_GE(t.contact - t.initially, 1);
  EXPECT_EQ(t.undecided, 0);
}

TEST(EntityCcdMocap, BoxersFacingEachOther) {
  // The boxing clip and its mirror image (x -> 2c - x: positions mirrored,
  // rotations conjugated by the mirror, link segments mirrored), the mirror
  // plane 0.45 m in front of the boxer's mean root position.
  MocapClip a = Load("boxing_toes.bvh.gz", 4);
  ASSERT_GT(a.poses.size(), 20u);
  std::vector<Link> links = a.skeleton.links();
  for (Link& l : links) {
    l.a_L.x() = -l.a_L.x();
    l.b_L.x() = -l.b_L.x();
  }
  const Skeleton mirrored = Skeleton::FromLinks("mirrored", links, "test");
  const double plane = RootMean(a).x() + 0.45;
  std::vector<Pose> m = a.poses;
  for (Pose& p : m) {
    for (LinkPose& l : p.links) {
      l.p.x() = 2 * plane - l.p.x();
      l.q = Quaterniond(l.q.w(), l.q.x(), -l.q.y(), -l.q.z());
    }
  }
  World w;
  w.rules.assign(2, {});
  w.avatars.resize(2);
  w.avatars[0] = {"boxer", a.skeleton, MotionModel::kArticulated, {}, a.poses};
  w.avatars[1] = {"mirror", mirrored, MotionModel::kArticulated, {}, m};
  EntityQueryOptions opt;
  opt.per_link = true;
  const Tally t = RunClips(w, 0, 120, opt);
  std::printf("boxers: %d contact (%d initially), %d free (%d by box)\n", t.contact, t.initially,
              t.free, t.culled);
  EXPECT_EQ(t.contact + t.free, 120);
  EXPECT_GT(t.contact, 0);
  // Punches that first touch inside a pair, and pairs the boxes leave to the
  // link descent that it finds free.
  EXPECT_GE(t.contact - t.initially, 1);
  EXPECT_GE(t.free - t.culled, 1);
  EXPECT_EQ(t.undecided, 0);
}

// `sweptccd world-bench --scenario hands` (issue 31; tools/world_bench_hands.h):
// two avatars reach for, grasp, carry and release their own boxes, as
// 16-link CMU avatars and as 81-link meta-full-body avatars (procedurally
// animated fingers). Every third valid record's entry for the avatar's own
// box, as the shared world answers it (WorldAnswerer, broad phase
// included: what world-bench times and `sweptccd world` writes), is
// certified against the dense reference; its fingers' contacts with the box
// among them.
class EntityCcdHands : public test::TempDirTest {
 protected:
  EntityCcdHands() : TempDirTest("entity_ccd_hands") {}
};

TEST_F(EntityCcdHands, GraspAndCarryAnswersHoldAgainstDenseSampling) {
  WorldBenchOptions o;
  o.out_dir = Path("hands");
  o.avatars = 2;
  o.seconds = 1.5;
  o.seed = 7;
  o.generate_only = true;
  RunHandsScenario(o, SWEPTCCD_DATA_DIR);
  for (const char* links : {"16", "81"}) {
    SCOPED_TRACE(std::string(links) + " links");
    const LoadedWorld lw = LoadWorldFile(Path(std::string("hands/world") + links + ".json"));
    const World& w = lw.world;
    ASSERT_EQ(w.avatars.size(), 2u);
    ASSERT_EQ(w.objects.size(), 2u);
    const WorldAnswerer answerer(lw, QueryOptions());
    const EntityQueryOptions opt;  // QueryOptions' eps and delta.
    Tally tally;
    int finger_contacts = 0;
    for (int a = 0; a < 2; ++a) {
      const AvatarEntity& A = w.avatars[a];
      for (size_t r = 0; r < A.records.size(); r += 3) {
        if (!A.records[r].valid) continue;
        const auto e = answerer.AnswerObject(AvatarIndex(a), r, TrackedObjectIndex(a));
        ASSERT_TRUE(e.has_value()) << "the box exists for the whole clip";
        SCOPED_TRACE("avatar " + std::to_string(a) + " record " + std::to_string(r));
        CheckAnswer(w, a, -1, a, A.records[r].pose0, A.records[r].pose1, e->t_from, e->t_to,
                    e->answer, opt, &tally, 120);
        if (::testing::Test::HasFatalFailure()) return;
        if (e->answer.contact) {
          const std::string& name = A.skeleton.link(e->answer.bracket.link.value()).name;
          finger_contacts += name.find("HAND_") != std::string::npos;
        }
      }
    }
    std::printf(
        "hands, %s links: %d contact (%d initially), %d free (%d by box), %d by a hand "
        "link of the full body\n",
        links, tally.contact, tally.initially, tally.free, tally.culled, finger_contacts);
    // The grasp happens, and not only as a carried box touching from the
    // start of a pair; the reach leaves pairs free.
    EXPECT_GT(tally.contact, 10);
    EXPECT_GE(tally.contact - tally.initially, 1);
    EXPECT_GT(tally.free, 10);
    EXPECT_EQ(tally.undecided, 0);
    if (std::string(links) == "81") {
      EXPECT_GT(finger_contacts, 0);
    }
  }
}

}  // namespace
}  // namespace sweptccd::world
