// Seeded randomised comparison of CcdEngine::Query (SPEC sections 3, 5, 6)
// against an independent dense-sampling reference written here.
//
// The reference
// - interpolates every link from SPEC section 3's text with its own
//   quaternion product and rotation matrices: slerp(q0, q1, s) is
//   R(q0) * AxisAngle(axis, s * angle) with (axis, angle) from
//   conj(q0) * q1' (q1' = -q1 when dot(q0, q1) < 0), and the articulated
//   model composes R_i(s) = R_k(s) R(r_i(s)), p_i(s) = p_k(s) + R_k(s) c_i(s)
//   root down. It never calls PairMotion.
// - computes a link's separation at s as the minimum over ALL triangles of
//   the environment (no BVH) of dist(segment, triangle) - radius, skipping
//   filtered (link, object) pairs. The segment-triangle distance is
//   SegmentTriangleDistance from core/distance.h, used here only because
//   distance_test.cc validates it against its own brute-force twin (golden
//   section over the segment parameter of an independent point-triangle
//   distance, and nested golden-section sampling of the barycentrics).
//   For speed, the dense samples skip triangles whose bounding box is farther
//   than radius + kFar from the link's sampled segments (an axis-aligned box
//   test that only drops triangles whose distance is provably larger); a
//   sample's separation is then exact when below kFar, and ">= kFar"
//   otherwise. Single-time checks (witnesses) use the plain brute force.
// - samples s at 2001 uniform points, plus points packed just below every
//   reported s_lo (where a G1 violation would be), plus generator hints (the
//   constructed contact or grazing times).
//
// Checks per query (tolerance 1e-9 m for floating point):
// - no miss: a sample with separation <= 0 needs contact and s_lo <= its s;
// - G1: no sample before s_lo has separation <= 0 (per link in per-link mode);
// - G2: (s_hi - s_lo) (utime1 - utime0) <= eps unless undecided;
// - G3: the witness lies in [s_lo, s_hi] and the reference separation there is
//   <= delta; witness fields are consistent (point_link on the segment,
//   point_env on the named triangle, |point_link - point_env| - radius ==
//   separation, unit normal);
// - initially_colliding matches the reference at s = 0, and then s_lo == 0;
// - undecided answers stay below 0.5% of the queries of a scenario.
// Queries mix both motion models, per-link mode, filters, small and LCM-epoch
// utimes, random eps/delta and (sometimes) a tiny max_candidates that forces
// the engine's BVH re-query paths.
// On failure the case is printed: scenario, seed, index, options, skeleton
// JSON, both pose lines, filtered pairs and every triangle.

#include <gtest/gtest.h>

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <memory>
#include <random>
#include <sstream>
#include <string>
#include <utility>
#include <vector>

#include "core/avatar/joint_frame.h"
#include "core/avatar/joint_set.h"
#include "core/avatar/motion.h"
#include "core/avatar/pose.h"
#include "core/avatar/skeleton.h"
#include "core/geometry/distance.h"
#include "core/geometry/mesh.h"
#include "core/query/ccd_query.h"
#include "core/scene/collision_filter.h"
#include "core/scene/environment.h"
#include "mocap/full_body_frames.h"
#include "mocap/mocap_import.h"
#include "tests/common/random.h"
#include "tests/common/same_record.h"
#include "tests/common/test_scale.h"
#include "tests/core/query/backend_under_test.h"

namespace sweptccd {
namespace {

using Vec3 = Eigen::Vector3d;
using Mat3 = Eigen::Matrix3d;

constexpr double kPi = 3.14159265358979323846;
constexpr double kTol = 1e-9;  // Metres: floating-point slack of the checks.
constexpr double kFar = 0.05;  // Reference samples are exact below this separation.
constexpr int kUniformSamples = 2001;

// ---------------------------------------------------------------------------
// Reference motion, from SPEC section 3.

struct RQ {
  double w = 1, x = 0, y = 0, z = 0;
};
RQ ToRQ(const Eigen::Quaterniond& q) { return {q.w(), q.x(), q.y(), q.z()}; }
RQ Conj(const RQ& a) { return {a.w, -a.x, -a.y, -a.z}; }
RQ Neg(const RQ& a) { return {-a.w, -a.x, -a.y, -a.z}; }
double Dot(const RQ& a, const RQ& b) { return a.w * b.w + a.x * b.x + a.y * b.y + a.z * b.z; }
RQ Mul(const RQ& a, const RQ& b) {
  return {
      a.w * b.w - a.x * b.x - a.y * b.y - a.z * b.z, a.w * b.x + a.x * b.w + a.y * b.z - a.z * b.y,
      a.w * b.y - a.x * b.z + a.y * b.w + a.z * b.x, a.w * b.z + a.x * b.y - a.y * b.x + a.z * b.w};
}
RQ Unit(const RQ& a) {
  const double n = std::sqrt(Dot(a, a));
  return {a.w / n, a.x / n, a.y / n, a.z / n};
}
Mat3 Rot(const RQ& q_in) {
  const RQ q = Unit(q_in);
  const double w = q.w, x = q.x, y = q.y, z = q.z;
  Mat3 r;
  r << 1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y),  //
      2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x),   //
      2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y);
  return r;
}
// Rodrigues: rotation by `angle` about the unit `axis`.
Mat3 AxisAngle(const Vec3& axis, double angle) {
  Mat3 k;
  k << 0, -axis.z(), axis.y(),  //
      axis.z(), 0, -axis.x(),   //
      -axis.y(), axis.x(), 0;
  return Mat3::Identity() + std::sin(angle) * k + (1 - std::cos(angle)) * k * k;
}

// slerp(q0, q1, s) as a rotation matrix: R(q0) * AxisAngle(axis, s * angle).
struct RefSlerp {
  RefSlerp() = default;
  RefSlerp(const RQ& q0, RQ q1) {
    if (Dot(q0, q1) < 0) q1 = Neg(q1);  // Shortest arc (SPEC section 3).
    const RQ d = Mul(Conj(q0), q1);
    const Vec3 v(d.x, d.y, d.z);
    const double vn = v.norm();
    angle = 2 * std::atan2(vn, d.w);
    axis = vn > 0 ? Vec3(v / vn) : Vec3(1, 0, 0);
    R0 = Rot(q0);
  }
  Mat3 At(double s) const { return R0 * AxisAngle(axis, s * angle); }
  Mat3 R0 = Mat3::Identity();
  Vec3 axis{1, 0, 0};
  double angle = 0;
};

class RefMotion {
 public:
  RefMotion(const Skeleton& skeleton, const Pose& pose0, const Pose& pose1, bool articulated) {
    const int n = skeleton.num_links();
    links_.resize(n);
    std::vector<int> depth(n, -1);
    for (int i = 0; i < n; ++i) {
      int d = 0;
      for (int k = skeleton.link(i).parent; k >= 0; k = skeleton.link(k).parent) ++d;
      depth[i] = d;
    }
    order_.resize(n);
    for (int i = 0; i < n; ++i) order_[i] = i;
    std::stable_sort(order_.begin(), order_.end(),
                     [&](int x, int y) { return depth[x] < depth[y]; });
    for (int i = 0; i < n; ++i) {
      L& l = links_[i];
      l.a = skeleton.link(i).a_L;
      l.b = skeleton.link(i).b_L;
      const int k = skeleton.link(i).parent;
      const LinkPose& x0 = pose0.links[i];
      const LinkPose& x1 = pose1.links[i];
      if (articulated && k >= 0) {
        l.parent = k;
        const LinkPose& k0 = pose0.links[k];
        const LinkPose& k1 = pose1.links[k];
        l.c0 = Rot(ToRQ(k0.q)).transpose() * (x0.p - k0.p);
        l.c1 = Rot(ToRQ(k1.q)).transpose() * (x1.p - k1.p);
        l.rot = RefSlerp(Unit(Mul(Conj(ToRQ(k0.q)), ToRQ(x0.q))),
                         Unit(Mul(Conj(ToRQ(k1.q)), ToRQ(x1.q))));
      } else {
        l.parent = -1;
        l.c0 = x0.p;
        l.c1 = x1.p;
        l.rot = RefSlerp(ToRQ(x0.q), ToRQ(x1.q));
      }
    }
  }

  int num_links() const { return static_cast<int>(links_.size()); }

  // World segments (A_i, B_i) of every link at s.
  void Segments(double s, Vec3* A, Vec3* B) const {
    const int n = num_links();
    R_.resize(n);
    P_.resize(n);
    for (int i : order_) {
      const L& l = links_[i];
      const Mat3 Rr = l.rot.At(s);
      const Vec3 c = (1 - s) * l.c0 + s * l.c1;
      if (l.parent < 0) {
        R_[i] = Rr;
        P_[i] = c;
      } else {
        R_[i] = R_[l.parent] * Rr;
        P_[i] = P_[l.parent] + R_[l.parent] * c;
      }
      A[i] = P_[i] + R_[i] * l.a;
      B[i] = P_[i] + R_[i] * l.b;
    }
  }
  void Segment(int link, double s, Vec3* A, Vec3* B) const {
    std::vector<Vec3> a(num_links()), b(num_links());
    Segments(s, a.data(), b.data());
    *A = a[link];
    *B = b[link];
  }

 private:
  struct L {
    int parent = -1;
    Vec3 c0, c1, a, b;
    RefSlerp rot;
  };
  std::vector<L> links_;
  std::vector<int> order_;
  mutable std::vector<Mat3> R_;
  mutable std::vector<Vec3> P_;
};

// ---------------------------------------------------------------------------
// Scenes: the engine under test next to the brute-force reference.

struct Scene {
  Skeleton skeleton;
  std::vector<TriangleMesh> meshes;          // One object each.
  std::vector<std::pair<int, int>> ignored;  // (link, object), -1 = all.
};

struct RefTri {
  Vec3 a, b, c, lo, hi;
  int object;
  uint32_t id;
};

class SceneUnderTest {
 public:
  explicit SceneUnderTest(Scene scene) : scene_(std::move(scene)) {
    const int n = scene_.skeleton.num_links();
    const int m = static_cast<int>(scene_.meshes.size());
    for (int o = 0; o < m; ++o) env_.AddMesh(scene_.meshes[o], "object" + std::to_string(o));
    ignored_.assign(static_cast<size_t>(n) * m, 0);
    for (const auto& [link, object] : scene_.ignored) {
      for (int l = 0; l < n; ++l) {
        for (int o = 0; o < m; ++o) {
          if ((link < 0 || link == l) && (object < 0 || object == o)) ignored_[l * m + o] = 1;
        }
      }
    }
    if (scene_.ignored.empty()) {
      // The default filter (ignores nothing) is the common way to build one.
      engine_ = std::make_unique<CcdEngine>(scene_.skeleton, env_);
    } else {
      CollisionFilter filter(n, m);
      for (const auto& [link, object] : scene_.ignored) {
        filter.Ignore(LinkIndex(link), ObjectIndex(object));
      }
      engine_ = std::make_unique<CcdEngine>(scene_.skeleton, env_, std::move(filter));
    }
    // The backend under test; with an accelerator, the CPU engine answers
    // beside it and the two must agree.
    testing::AttachBackend(engine_.get());
    if (engine_->culler() != nullptr) {
      cpu_engine_ = std::make_unique<CcdEngine>(scene_.skeleton, env_, engine_->filter());
    }
    for (int o = 0; o < m; ++o) {
      const TriangleMesh& mesh = scene_.meshes[o];
      for (size_t t = 0; t < mesh.num_triangles(); ++t) {
        RefTri r;
        r.a = mesh.vertices[mesh.indices[3 * t]].cast<double>();
        r.b = mesh.vertices[mesh.indices[3 * t + 1]].cast<double>();
        r.c = mesh.vertices[mesh.indices[3 * t + 2]].cast<double>();
        r.lo = r.a.cwiseMin(r.b).cwiseMin(r.c);
        r.hi = r.a.cwiseMax(r.b).cwiseMax(r.c);
        r.object = o;
        r.id = static_cast<uint32_t>(t);
        tris_.push_back(r);
      }
    }
  }
  SceneUnderTest(const SceneUnderTest&) = delete;
  SceneUnderTest& operator=(const SceneUnderTest&) = delete;

  const Scene& scene() const { return scene_; }
  const Skeleton& skeleton() const { return scene_.skeleton; }
  const CcdEngine& engine() const { return *engine_; }
  /// The CPU engine beside an accelerated one; nullptr when testing the CPU.
  const CcdEngine* cpu_engine() const { return cpu_engine_.get(); }
  const std::vector<RefTri>& tris() const { return tris_; }
  int num_objects() const { return static_cast<int>(scene_.meshes.size()); }
  bool Ignored(int link, int object) const {
    return ignored_[static_cast<size_t>(link) * num_objects() + object] != 0;
  }
  bool filtered() const { return !scene_.ignored.empty(); }

  // Brute force over every unfiltered triangle; kFar * 1e6 when none.
  double ExactSeparation(int link, const Vec3& A, const Vec3& B,
                         const RefTri** best = nullptr) const {
    const double radius = scene_.skeleton.link(link).radius;
    double sep = kFar * 1e6;
    for (const RefTri& t : tris_) {
      if (Ignored(link, t.object)) continue;
      const double d = SegmentTriangleDistance(A, B, t.a, t.b, t.c).distance - radius;
      if (d < sep) {
        sep = d;
        if (best != nullptr) *best = &t;
      }
    }
    return sep;
  }

 private:
  Scene scene_;
  Environment env_;
  std::unique_ptr<CcdEngine> engine_;
  std::unique_ptr<CcdEngine> cpu_engine_;
  std::vector<RefTri> tris_;
  std::vector<char> ignored_;
};

// Separation of every link at every sample: sep[k * L + l].
struct RefSamples {
  std::vector<double> s;
  std::vector<double> sep;
  int L = 0;
  double Min(int k) const {
    double m = sep[static_cast<size_t>(k) * L];
    for (int l = 1; l < L; ++l) m = std::min(m, sep[static_cast<size_t>(k) * L + l]);
    return m;
  }
  double At(int k, int l) const { return sep[static_cast<size_t>(k) * L + l]; }
};

bool BoxesOverlap(const Vec3& lo1, const Vec3& hi1, const Vec3& lo2, const Vec3& hi2) {
  return (lo1.array() <= hi2.array()).all() && (lo2.array() <= hi1.array()).all();
}

RefSamples EvaluateSamples(const SceneUnderTest& sut, const RefMotion& motion,
                           std::vector<double> s) {
  std::sort(s.begin(), s.end());
  s.erase(std::unique(s.begin(), s.end()), s.end());
  RefSamples out;
  const int L = motion.num_links();
  const int n = static_cast<int>(s.size());
  out.s = s;
  out.L = L;
  out.sep.assign(static_cast<size_t>(n) * L, kFar);
  std::vector<Vec3> A(static_cast<size_t>(n) * L), B(static_cast<size_t>(n) * L);
  for (int k = 0; k < n; ++k)
    motion.Segments(s[k], &A[static_cast<size_t>(k) * L], &B[static_cast<size_t>(k) * L]);
  std::vector<const RefTri*> cand, near;
  constexpr int kChunk = 16;
  for (int l = 0; l < L; ++l) {
    const double grow = sut.skeleton().link(l).radius + kFar;
    // The triangles near the link's box over all samples (every chunk's box
    // lies inside it, so this drops only triangles no chunk would keep).
    Vec3 llo = Vec3::Constant(1e300), lhi = Vec3::Constant(-1e300);
    for (int k = 0; k < n; ++k) {
      llo = llo.cwiseMin(A[static_cast<size_t>(k) * L + l])
                .cwiseMin(B[static_cast<size_t>(k) * L + l]);
      lhi = lhi.cwiseMax(A[static_cast<size_t>(k) * L + l])
                .cwiseMax(B[static_cast<size_t>(k) * L + l]);
    }
    llo.array() -= grow;
    lhi.array() += grow;
    near.clear();
    for (const RefTri& t : sut.tris()) {
      if (!sut.Ignored(l, t.object) && BoxesOverlap(llo, lhi, t.lo, t.hi)) near.push_back(&t);
    }
    if (near.empty()) continue;
    for (int c0 = 0; c0 < n; c0 += kChunk) {
      const int c1 = std::min(n, c0 + kChunk);
      Vec3 lo = Vec3::Constant(1e300), hi = Vec3::Constant(-1e300);
      for (int k = c0; k < c1; ++k) {
        const Vec3& a = A[static_cast<size_t>(k) * L + l];
        const Vec3& b = B[static_cast<size_t>(k) * L + l];
        lo = lo.cwiseMin(a).cwiseMin(b);
        hi = hi.cwiseMax(a).cwiseMax(b);
      }
      lo.array() -= grow;
      hi.array() += grow;
      cand.clear();
      for (const RefTri* t : near) {
        if (BoxesOverlap(lo, hi, t->lo, t->hi)) cand.push_back(t);
      }
      if (cand.empty()) continue;
      const double radius = sut.skeleton().link(l).radius;
      for (int k = c0; k < c1; ++k) {
        const Vec3& a = A[static_cast<size_t>(k) * L + l];
        const Vec3& b = B[static_cast<size_t>(k) * L + l];
        const Vec3 slo = a.cwiseMin(b).array() - grow, shi = a.cwiseMax(b).array() + grow;
        double best = kFar;
        for (const RefTri* t : cand) {
          if (!BoxesOverlap(slo, shi, t->lo, t->hi)) continue;
          best = std::min(best, SegmentTriangleDistance(a, b, t->a, t->b, t->c).distance - radius);
        }
        out.sep[static_cast<size_t>(k) * L + l] = best;
      }
    }
  }
  return out;
}

double PointSegmentDistance(const Vec3& q, const Vec3& p0, const Vec3& p1) {
  const Vec3 d = p1 - p0;
  const double dd = d.squaredNorm();
  const double t = dd > 0 ? std::clamp((q - p0).dot(d) / dd, 0.0, 1.0) : 0.0;
  return (p0 + t * d - q).norm();
}

// ---------------------------------------------------------------------------
// Printing a case.

std::string V3(const Vec3& v) {
  char buf[96];
  std::snprintf(buf, sizeof(buf), "[%.17g, %.17g, %.17g]", v.x(), v.y(), v.z());
  return buf;
}

std::string DescribeResult(const QueryResult& r) {
  std::ostringstream os;
  os.precision(17);
  os << (r.contact ? "contact" : "free") << " initially_colliding=" << r.initially_colliding
     << " undecided=" << r.undecided << " s=[" << r.s_lo << ", " << r.s_hi << "]"
     << " intervals=" << r.stats.intervals;
  for (const ContactRecord& c : r.contacts) {
    os << "\n    contact link " << c.link << " object " << c.object << " triangle " << c.triangle
       << " s " << c.s << " point_link " << V3(c.point_link) << " point_env " << V3(c.point_env)
       << " normal " << V3(c.normal) << " separation " << c.separation;
  }
  for (const LinkBracket& b : r.links) {
    os << "\n    link " << b.link << " s=[" << b.s_lo << ", " << b.s_hi
       << "] initially_colliding=" << b.initially_colliding << " undecided=" << b.undecided;
    if (b.has_witness) os << " witness s " << b.witness.s << " sep " << b.witness.separation;
  }
  return os.str();
}

enum class Expect { kAny, kContact, kInitiallyColliding, kFree };

struct QuerySpec {
  Pose pose0, pose1;
  QueryOptions options;
  std::vector<double> hints;  // Extra reference samples (constructed contact times).
  Expect expect = Expect::kAny;
  std::string note;
  int uniform_samples = kUniformSamples;
};

std::string DescribeCase(const std::string& suite, uint64_t seed, int index,
                         const SceneUnderTest& sut, const QuerySpec& q) {
  std::ostringstream os;
  os.precision(17);
  os << "---- case: suite '" << suite << "' seed " << seed << " query " << index << " (" << q.note
     << ")\n";
  os << "motion " << MotionModelName(q.options.motion) << " eps_s " << q.options.eps_s
     << " delta_m " << q.options.delta_m << " per_link " << q.options.per_link << " max_intervals "
     << q.options.max_intervals << "\n";
  os << "skeleton " << SkeletonToJson(sut.skeleton()) << "\n";
  os << "pose0 " << PoseToJsonLine(q.pose0) << "\n";
  os << "pose1 " << PoseToJsonLine(q.pose1) << "\n";
  os << "ignored (link, object):";
  for (const auto& [l, o] : sut.scene().ignored) os << " (" << l << ", " << o << ")";
  os << "\n";
  for (const RefTri& t : sut.tris()) {
    char buf[256];
    std::snprintf(buf, sizeof(buf),
                  "tri %d %u [%.9g %.9g %.9g] [%.9g %.9g %.9g] [%.9g %.9g %.9g]\n", t.object, t.id,
                  t.a.x(), t.a.y(), t.a.z(), t.b.x(), t.b.y(), t.b.z(), t.c.x(), t.c.y(), t.c.z());
    os << buf;
  }
  return os.str();
}

// ---------------------------------------------------------------------------
// The checker.

struct Outcome {
  QueryResult result;
  bool ref_touches = false;  // Some sample has separation <= 0.
  double ref_first_touch = 2;
  double ref_min_sep = 1e300;
  bool failed = false;
};

class Suite {
 public:
  explicit Suite(std::string name) : name_(std::move(name)) {}

  Outcome Run(const SceneUnderTest& sut, const QuerySpec& q, uint64_t seed, int index);

  // Prints the tally; fails on too many undecided answers or too few queries.
  void Finish(int64_t min_queries, bool limit_undecided = true) {
    std::printf(
        "[%s, %s backend] queries %lld (per-link %lld, filtered %lld, independent %lld): contact "
        "%lld (initially colliding %lld), free %lld, undecided %lld; reference touched in %lld; "
        "failures %lld; engine %.2f s, reference %.2f s\n",
        name_.c_str(), testing::BackendName(), ll(queries_), ll(per_link_), ll(filtered_),
        ll(independent_), ll(contact_), ll(initially_), ll(free_), ll(undecided_), ll(touched_),
        ll(failures_), engine_s_, reference_s_);
    if (std::string(testing::BackendName()) != "cpu") {
      std::printf(
          "[%s, %s backend] culler: %lld round trips, %lld capsules, %lld intervals cleared\n",
          name_.c_str(), testing::BackendName(), ll(cull_round_trips_), ll(cull_capsules_),
          ll(cull_cleared_));
      // The accelerator must have been used (a fallback to the CPU would
      // otherwise pass unnoticed).
      EXPECT_GT(cull_round_trips_, 0) << name_ << ": the backend under test never ran";
    }
    // A scaled run (tests/common/test_scale.h) runs a prefix of the seeds:
    // its minimum and its undecided allowance are the full run's, scaled.
    EXPECT_GE(queries_, static_cast<int64_t>(min_queries * testing::TestScale())) << name_;
    EXPECT_EQ(failures_, 0) << name_ << ": " << failures_ << " of " << queries_
                            << " queries failed (the first ones are printed above)";
    if (limit_undecided) {
      EXPECT_LE(undecided_, static_cast<int64_t>(0.005 * queries_ / testing::TestScale()))
          << name_ << ": too many undecided answers";
    }
  }
  int64_t queries() const { return queries_; }

 private:
  static long long ll(int64_t v) { return static_cast<long long>(v); }
  void Report(const std::vector<std::string>& problems, const SceneUnderTest& sut,
              const QuerySpec& q, const QueryResult& r, uint64_t seed, int index) {
    ++failures_;
    std::ostringstream os;
    for (const std::string& p : problems) os << "  - " << p << "\n";
    if (failures_ <= 3) {
      ADD_FAILURE() << name_ << " seed " << seed << " query " << index << " (" << q.note << "):\n"
                    << os.str() << "  result: " << DescribeResult(r) << "\n"
                    << DescribeCase(name_, seed, index, sut, q);
    } else if (failures_ <= 20) {
      ADD_FAILURE() << name_ << " seed " << seed << " query " << index << " (" << q.note
                    << "): " << problems.front();
    }
  }

  std::string name_;
  int64_t queries_ = 0, per_link_ = 0, filtered_ = 0, independent_ = 0, contact_ = 0,
          initially_ = 0, free_ = 0, undecided_ = 0, touched_ = 0, failures_ = 0;
  int64_t cull_round_trips_ = 0, cull_capsules_ = 0, cull_cleared_ = 0;
  double engine_s_ = 0, reference_s_ = 0;
};

// Checks one witness record against the reference; appends problems.
void CheckWitness(const SceneUnderTest& sut, const RefMotion& motion, const ContactRecord& c,
                  const std::string& what, std::vector<std::string>* problems) {
  std::ostringstream os;
  os.precision(17);
  if (c.link < 0 || c.link >= sut.skeleton().num_links() || c.object < 0 ||
      c.object >= sut.num_objects() || c.triangle >= sut.scene().meshes[c.object].num_triangles()) {
    os << what << ": bad ids link " << c.link << " object " << c.object << " triangle "
       << c.triangle;
    problems->push_back(os.str());
    return;
  }
  if (sut.Ignored(c.link, c.object)) {
    os << what << ": witness on a filtered pair (link " << c.link << ", object " << c.object << ")";
    problems->push_back(os.str());
  }
  const RefTri* tri = nullptr;
  for (const RefTri& t : sut.tris()) {
    if (t.object == c.object && t.id == c.triangle) tri = &t;
  }
  Vec3 A, B;
  motion.Segment(c.link, c.s, &A, &B);
  const double radius = sut.skeleton().link(c.link).radius;
  const double on_segment = PointSegmentDistance(c.point_link, A, B);
  const double on_triangle =
      SegmentTriangleDistance(c.point_env, c.point_env, tri->a, tri->b, tri->c).distance;
  const double gap = (c.point_link - c.point_env).norm() - radius;
  const double tri_sep = SegmentTriangleDistance(A, B, tri->a, tri->b, tri->c).distance - radius;
  const double scale = 1 + std::max(A.cwiseAbs().maxCoeff(), B.cwiseAbs().maxCoeff());
  if (!(on_segment <= kTol * scale)) {
    os << what << ": point_link is " << on_segment << " m off the link's segment at s " << c.s;
    problems->push_back(os.str());
    os.str("");
  }
  if (!(on_triangle <= kTol * scale)) {
    os << what << ": point_env is " << on_triangle << " m off triangle " << c.triangle;
    problems->push_back(os.str());
    os.str("");
  }
  if (!(std::fabs(gap - c.separation) <= kTol * scale)) {
    os << what << ": |point_link - point_env| - radius = " << gap << " but separation "
       << c.separation;
    problems->push_back(os.str());
    os.str("");
  }
  if (!(std::fabs(tri_sep - c.separation) <= kTol * scale)) {
    os << what << ": separation " << c.separation << " but the named triangle is at " << tri_sep;
    problems->push_back(os.str());
    os.str("");
  }
  if (!(std::fabs(c.normal.norm() - 1) <= 1e-9)) {
    os << what << ": normal not unit, |n| = " << c.normal.norm();
    problems->push_back(os.str());
    os.str("");
  }
  const Vec3 d = c.point_link - c.point_env;
  if (d.norm() > 1e-6 && !(c.normal.dot(d.normalized()) >= 1 - 1e-6)) {
    os << what << ": normal " << V3(c.normal) << " does not point from the environment to the "
       << "link (" << V3(d.normalized()) << ")";
    problems->push_back(os.str());
  }
}

Outcome Suite::Run(const SceneUnderTest& sut, const QuerySpec& q, uint64_t seed, int index) {
  Outcome out;
  const auto t0 = std::chrono::steady_clock::now();
  const QueryResult r = sut.engine().Query(q.pose0, q.pose1, q.options);
  const auto t1 = std::chrono::steady_clock::now();
  out.result = r;

  const bool articulated = q.options.motion == MotionModel::kArticulated;
  const RefMotion motion(sut.skeleton(), q.pose0, q.pose1, articulated);
  const int L = sut.skeleton().num_links();
  const double dt_us = static_cast<double>(q.pose1.utime - q.pose0.utime);
  const double eps_us = q.options.eps_s * 1e6;

  // Samples: uniform, hints, and packed just below every reported s_lo.
  std::vector<double> s;
  for (int k = 0; k < q.uniform_samples; ++k) {
    s.push_back(static_cast<double>(k) / (q.uniform_samples - 1));
  }
  for (double h : q.hints) {
    if (h >= 0 && h <= 1) s.push_back(h);
  }
  auto below = [&](double lo, int n1, int n2) {
    for (int j = 1; j <= n1; ++j) s.push_back(lo - 1e-3 * j / n1);
    for (int j = 1; j <= n2; ++j) s.push_back(lo - 1e-6 * j / n2);
    s.push_back(std::nextafter(lo, -1.0));
  };
  if (r.contact) below(r.s_lo, 200, 50);
  for (const LinkBracket& b : r.links) below(b.s_lo, 50, 20);
  s.erase(std::remove_if(s.begin(), s.end(), [](double x) { return !(x >= 0 && x <= 1); }),
          s.end());
  const RefSamples ref = EvaluateSamples(sut, motion, s);
  const int n = static_cast<int>(ref.s.size());

  std::vector<std::string> problems;
  std::ostringstream os;
  os.precision(17);
  auto problem = [&]() {
    problems.push_back(os.str());
    os.str("");
  };

  // No miss and G1 over all links.
  int first_touch = -1;
  for (int k = 0; k < n; ++k) {
    const double sep = ref.Min(k);
    out.ref_min_sep = std::min(out.ref_min_sep, sep);
    if (sep <= 0 && first_touch < 0) first_touch = k;
  }
  out.ref_touches = first_touch >= 0;
  if (out.ref_touches) out.ref_first_touch = ref.s[first_touch];
  if (sut.cpu_engine() != nullptr) {
    const QueryResult cpu = sut.cpu_engine()->Query(q.pose0, q.pose1, q.options);
    if (!testing::SameAnswer(r, cpu)) {
      os << "BACKENDS DISAGREE: " << testing::BackendName() << ": " << DescribeResult(r)
         << "\n  cpu: " << DescribeResult(cpu);
      problem();
    }
  }
  if (out.ref_touches && !r.contact) {
    os << "MISS: answered free but the reference touches at s " << ref.s[first_touch]
       << " (separation " << ref.Min(first_touch) << ")";
    problem();
  }
  if (r.contact) {
    if (!(r.s_lo >= 0 && r.s_lo <= r.s_hi && r.s_hi <= 1)) {
      os << "bad bracket [" << r.s_lo << ", " << r.s_hi << "]";
      problem();
    }
    for (int k = 0; k < n && ref.s[k] < r.s_lo; ++k) {
      if (ref.Min(k) <= 0) {
        os << (ref.Min(k) < -kTol ? "G1 VIOLATION" : "touching (within 1e-9) before s_lo")
           << ": separation " << ref.Min(k) << " at s " << ref.s[k] << " < s_lo " << r.s_lo;
        problem();
        break;
      }
    }
  }

  // Initially colliding.
  const double sep0 = ref.Min(0);  // s[0] == 0.
  if (sep0 <= -kTol && !(r.contact && r.initially_colliding)) {
    os << "reference separation at s=0 is " << sep0 << " but initially_colliding is false";
    problem();
  }
  if (sep0 > kTol && r.initially_colliding) {
    os << "initially_colliding but the reference separation at s=0 is " << sep0;
    problem();
  }
  if (r.initially_colliding && r.s_lo != 0) {
    os << "initially_colliding with s_lo " << r.s_lo;
    problem();
  }

  // G2, G3 and the witnesses.
  if (r.contact && !r.undecided) {
    const double width_us = (r.s_hi - r.s_lo) * dt_us;
    if (!(width_us <= eps_us * (1 + 1e-9) + 1e-6)) {
      os << "G2: bracket is " << width_us << " us wide, eps is " << eps_us << " us";
      problem();
    }
    if (r.contacts.empty()) {
      os << "G3: no witness";
      problem();
    }
    for (size_t i = 0; i < r.contacts.size(); ++i) {
      const ContactRecord& c = r.contacts[i];
      if (!(c.s >= r.s_lo && c.s <= r.s_hi)) {
        os << "witness " << i << " at s " << c.s << " outside [" << r.s_lo << ", " << r.s_hi << "]";
        problem();
        continue;
      }
      CheckWitness(sut, motion, c, "witness " + std::to_string(i), &problems);
      if (c.link < 0 || c.link >= L) continue;
      Vec3 A, B;
      motion.Segment(c.link, c.s, &A, &B);
      const double exact = sut.ExactSeparation(c.link, A, B);
      if (!(exact <= q.options.delta_m + kTol)) {
        os << "G3: reference separation of link " << c.link << " at witness s " << c.s << " is "
           << exact << " > delta " << q.options.delta_m;
        problem();
      }
      if (!(c.separation >= exact - kTol)) {
        os << "witness separation " << c.separation << " below the reference minimum " << exact;
        problem();
      }
    }
  } else if (r.contact) {
    for (size_t i = 0; i < r.contacts.size(); ++i) {
      CheckWitness(sut, motion, r.contacts[i], "undecided witness " + std::to_string(i), &problems);
    }
  }

  // Per-link mode.
  if (q.options.per_link) {
    if (r.contact != !r.links.empty()) {
      os << "per-link: contact " << r.contact << " with " << r.links.size() << " link brackets";
      problem();
    }
    std::vector<const LinkBracket*> bracket(L, nullptr);
    double min_lo = 2;
    for (const LinkBracket& b : r.links) {
      if (b.link < 0 || b.link >= L || bracket[b.link] != nullptr) {
        os << "per-link: bad or repeated link " << b.link;
        problem();
        continue;
      }
      bracket[b.link] = &b;
      min_lo = std::min(min_lo, b.s_lo);
    }
    if (r.contact && !r.links.empty() && r.s_lo != min_lo) {
      os << "per-link: s_lo " << r.s_lo << " is not the earliest link bracket " << min_lo;
      problem();
    }
    for (int l = 0; l < L; ++l) {
      const LinkBracket* b = bracket[l];
      int first = -1;
      for (int k = 0; k < n && first < 0; ++k) {
        if (ref.At(k, l) <= 0) first = k;
      }
      if (first >= 0 && b == nullptr) {
        os << "per-link MISS: link " << l << " touches at s " << ref.s[first] << " (separation "
           << ref.At(first, l) << ") but has no bracket";
        problem();
      }
      if (b == nullptr) continue;
      if (first >= 0 && ref.s[first] < b->s_lo) {
        os << "per-link G1 " << (ref.At(first, l) < -kTol ? "VIOLATION" : "(within 1e-9)")
           << ": link " << l << " touches at s " << ref.s[first] << " (separation "
           << ref.At(first, l) << ") before its s_lo " << b->s_lo;
        problem();
      }
      const double sep_l0 = ref.At(0, l);
      if (sep_l0 <= -kTol && !b->initially_colliding) {
        os << "per-link: link " << l << " separation at s=0 is " << sep_l0
           << " but not initially_colliding";
        problem();
      }
      if (sep_l0 > kTol && b->initially_colliding) {
        os << "per-link: link " << l << " initially_colliding but separation at s=0 is " << sep_l0;
        problem();
      }
      if (b->undecided) continue;
      if (!((b->s_hi - b->s_lo) * dt_us <= eps_us * (1 + 1e-9) + 1e-6)) {
        os << "per-link G2: link " << l << " bracket is " << (b->s_hi - b->s_lo) * dt_us
           << " us wide";
        problem();
      }
      if (!b->has_witness || b->witness.link != l || !(b->witness.s >= b->s_lo) ||
          !(b->witness.s <= b->s_hi)) {
        os << "per-link G3: link " << l << " has no witness inside [" << b->s_lo << ", " << b->s_hi
           << "]";
        problem();
        continue;
      }
      CheckWitness(sut, motion, b->witness, "link " + std::to_string(l) + " witness", &problems);
      Vec3 A, B;
      motion.Segment(l, b->witness.s, &A, &B);
      const double exact = sut.ExactSeparation(l, A, B);
      if (!(exact <= q.options.delta_m + kTol)) {
        os << "per-link G3: link " << l << " reference separation at witness s " << b->witness.s
           << " is " << exact << " > delta";
        problem();
      }
    }
  }

  // What the generator built.
  switch (q.expect) {
    case Expect::kContact:
      if (!out.ref_touches) {
        os << "generator: expected a touch that the reference does not see (min separation "
           << out.ref_min_sep << ")";
        problem();
      }
      if (!r.contact) {
        os << "expected contact";
        problem();
      }
      break;
    case Expect::kInitiallyColliding:
      if (!(sep0 < 0)) {
        os << "generator: expected an initial collision, reference separation at 0 is " << sep0;
        problem();
      }
      if (!r.initially_colliding || r.s_lo != 0) {
        os << "expected initially_colliding with s_lo 0";
        problem();
      }
      break;
    case Expect::kFree:
      if (r.contact) {
        os << "expected free (the minimum separation exceeds delta)";
        problem();
      }
      break;
    case Expect::kAny:
      break;
  }
  const auto t2 = std::chrono::steady_clock::now();

  ++queries_;
  per_link_ += q.options.per_link;
  filtered_ += sut.filtered();
  independent_ += !articulated;
  contact_ += r.contact;
  initially_ += r.initially_colliding;
  free_ += !r.contact;
  undecided_ += r.undecided;
  touched_ += out.ref_touches;
  cull_round_trips_ += r.stats.cull_round_trips;
  cull_capsules_ += r.stats.cull_capsules;
  cull_cleared_ += r.stats.cull_cleared;
  engine_s_ += std::chrono::duration<double>(t1 - t0).count();
  reference_s_ += std::chrono::duration<double>(t2 - t1).count();
  if (!problems.empty()) {
    out.failed = true;
    Report(problems, sut, q, r, seed, index);
  }
  return out;
}

// ---------------------------------------------------------------------------
// Generators.

using testing::Rng;
using testing::ScaledCount;

Eigen::Vector3f F(const Vec3& v) {
  return Eigen::Vector3f(static_cast<float>(v.x()), static_cast<float>(v.y()),
                         static_cast<float>(v.z()));
}
// Through a volatile float: GCC 12.2 at -O2/-O3 compiles a double -> float ->
// double round trip of an Eigen 3-vector into a plain copy of two of the
// three coordinates (SLP vectorisation drops the cvtpd2ps/cvtps2pd pair).
Vec3 RoundToFloat(const Vec3& v) {
  Vec3 out;
  for (int k = 0; k < 3; ++k) {
    volatile float f = static_cast<float>(v[k]);
    out[k] = f;
  }
  return out;
}

void AddTri(TriangleMesh* m, const Vec3& a, const Vec3& b, const Vec3& c) {
  const uint32_t base = static_cast<uint32_t>(m->vertices.size());
  m->vertices.push_back(F(a));
  m->vertices.push_back(F(b));
  m->vertices.push_back(F(c));
  m->indices.insert(m->indices.end(), {base, base + 1, base + 2});
}
// Rectangle centre +- e1 +- e2 as two triangles.
void AddQuad(TriangleMesh* m, const Vec3& centre, const Vec3& e1, const Vec3& e2) {
  AddTri(m, centre - e1 - e2, centre + e1 - e2, centre + e1 + e2);
  AddTri(m, centre - e1 - e2, centre + e1 + e2, centre - e1 + e2);
}
// Box: centre, rotation, half extents; 12 triangles.
void AddBox(TriangleMesh* m, const Vec3& centre, const Mat3& R, const Vec3& half) {
  const Vec3 ex = R.col(0) * half.x(), ey = R.col(1) * half.y(), ez = R.col(2) * half.z();
  AddQuad(m, centre + ex, ey, ez);
  AddQuad(m, centre - ex, ez, ey);
  AddQuad(m, centre + ey, ez, ex);
  AddQuad(m, centre - ey, ex, ez);
  AddQuad(m, centre + ez, ex, ey);
  AddQuad(m, centre - ez, ey, ex);
}
void AddSoup(Rng& rng, TriangleMesh* m, int count, double half, double size_lo, double size_hi,
             const Vec3& origin = Vec3::Zero()) {
  for (int i = 0; i < count; ++i) {
    const Vec3 c = origin + rng.Box(half);
    const double size = rng.U(size_lo, size_hi);
    AddTri(m, c + size * rng.Box(1), c + size * rng.Box(1), c + size * rng.Box(1));
  }
}

// A skeleton and where each child's frame sits in its parent's frame.
struct Rig {
  Skeleton skeleton;
  std::vector<Vec3> offset;  // c_i, in the parent frame.
};

Rig RandomRig(Rng& rng, int n, int max_depth, double sphere_share, double len_lo = 0.05,
              double len_hi = 0.35, double r_lo = 0.01, double r_hi = 0.15) {
  std::vector<Link> links(n);
  std::vector<int> depth(n, 0);
  Rig rig;
  rig.offset.assign(n, Vec3::Zero());
  for (int i = 0; i < n; ++i) {
    Link& l = links[i];
    l.name = "link" + std::to_string(i);
    if (i > 0) {
      int p;
      do {
        p = rng.I(i);
      } while (depth[p] + 1 > max_depth);
      l.parent = p;
      depth[i] = depth[p] + 1;
      // At the parent's far end, sometimes off it.
      rig.offset[i] = links[p].b_L + (rng.P(0.3) ? rng.Box(0.05) : Vec3::Zero());
    }
    l.a_L = rng.P(0.5) ? Vec3::Zero() : rng.Box(0.05);
    l.b_L = rng.P(sphere_share) ? l.a_L : Vec3(l.a_L + rng.Dir() * rng.U(len_lo, len_hi));
    l.radius = rng.U(r_lo, r_hi);
  }
  rig.skeleton = Skeleton::FromLinks("random", links, "ccd_random_test");
  return rig;
}

// World poses from the root pose and each link's rotation in its parent frame.
std::vector<LinkPose> Fk(const Rig& rig, const LinkPose& root,
                         const std::vector<Eigen::Quaterniond>& local) {
  const Skeleton& sk = rig.skeleton;
  std::vector<LinkPose> world(sk.num_links());
  for (int i : sk.topological_order()) {
    const int k = sk.link(i).parent;
    if (k < 0) {
      world[i] = root;
    } else {
      world[i].q = (world[k].q * local[i]).normalized();
      world[i].p = world[k].p + world[k].q * rig.offset[i];
    }
  }
  return world;
}

Pose MakePose(int64_t utime, std::vector<LinkPose> links) {
  Pose p;
  p.utime = utime;
  p.links = std::move(links);
  const std::string error = ValidateAndNormalizePose(&p, static_cast<int>(p.links.size()));
  EXPECT_EQ(error, "");
  return p;
}

QueryOptions RandomOptions(Rng& rng, MotionModel model, double per_link_share) {
  QueryOptions o;
  o.motion = model;
  o.eps_s = rng.P(0.6) ? 1e-4 : std::pow(10.0, rng.U(-6, -2.5));
  o.delta_m = rng.P(0.6) ? 1e-3 : std::pow(10.0, rng.U(-4, -2));
  o.per_link = rng.P(per_link_share);
  // A small candidate cap drives the engine onto its BVH re-query paths.
  if (rng.P(0.15)) o.max_candidates = 1 + rng.I(32);
  return o;
}

MotionModel RandomModel(Rng& rng) {
  return rng.P(0.5) ? MotionModel::kArticulated : MotionModel::kIndependent;
}

void SetTimes(Rng& rng, QuerySpec* q, double dt_lo_us = 1e3, double dt_hi_us = 1e6) {
  // Half the pairs carry LCM-style epoch microseconds (~1.7e15: a double
  // holds them to 0.25 us), half small clocks.
  const int64_t t0 =
      rng.P(0.5) ? 1'700'000'000'000'000LL + static_cast<int64_t>(rng.g() % 100'000'000'000ULL)
                 : static_cast<int64_t>(rng.g() % 4'000'000'000ULL);
  const int64_t dt = std::max<int64_t>(
      1, static_cast<int64_t>(std::pow(10.0, rng.U(std::log10(dt_lo_us), std::log10(dt_hi_us)))));
  q->pose0.utime = t0;
  q->pose1.utime = t0 + dt;
}

// Reference separation of the avatar at a pose (s = 0 of any pair).
double PoseSeparation(const SceneUnderTest& sut, const std::vector<LinkPose>& world) {
  double sep = 1e300;
  for (int l = 0; l < sut.skeleton().num_links(); ++l) {
    const Mat3 R = Rot(ToRQ(world[l].q.normalized()));
    const Vec3 A = world[l].p + R * sut.skeleton().link(l).a_L;
    const Vec3 B = world[l].p + R * sut.skeleton().link(l).b_L;
    sep = std::min(sep, sut.ExactSeparation(l, A, B));
  }
  return sep;
}

// A random motion of a rig: root moves up to `reach` metres and turns up to
// `root_turn`, every joint turns up to `joint_turn`. Prefers a clear start.
QuerySpec RandomMotion(Rng& rng, const Rig& rig, const SceneUnderTest& sut, double start_half,
                       double reach, double root_turn, double joint_turn, double per_link_share,
                       bool prefer_clear_start, const Vec3& origin = Vec3::Zero()) {
  const int n = rig.skeleton.num_links();
  QuerySpec q;
  std::vector<LinkPose> w0;
  std::vector<Eigen::Quaterniond> local0(n);
  LinkPose root0;
  for (int attempt = 0; attempt < 12; ++attempt) {
    root0.p = origin + rng.Box(start_half);
    root0.q = rng.Quat();
    for (int i = 0; i < n; ++i) local0[i] = rng.Turn(rng.U(0, 1.5));
    w0 = Fk(rig, root0, local0);
    if (!prefer_clear_start || PoseSeparation(sut, w0) > 0) break;
  }
  LinkPose root1;
  root1.p = root0.p + rng.Dir() * std::pow(10.0, rng.U(-3, std::log10(reach)));
  root1.q = rng.Turn(rng.U(0, root_turn)) * root0.q;
  std::vector<Eigen::Quaterniond> local1(n);
  for (int i = 0; i < n; ++i) local1[i] = rng.Turn(rng.U(0, joint_turn)) * local0[i];
  q.options = RandomOptions(rng, RandomModel(rng), per_link_share);
  SetTimes(rng, &q);
  q.pose0 = MakePose(q.pose0.utime, w0);
  q.pose1 = MakePose(q.pose1.utime, Fk(rig, root1, local1));
  q.note = "random motion";
  return q;
}

// ---------------------------------------------------------------------------
// 1. Random skeletons near random triangle soups.

TEST(CcdRandomTest, RandomSkeletonsAndTriangleSoups) {
  Suite suite("random skeletons and soups");
  for (int scene_i = 0; scene_i < ScaledCount(180); ++scene_i) {
    const uint64_t seed = 0xA110000 + scene_i;
    Rng rng(seed);
    const Rig rig = RandomRig(rng, 1 + rng.I(16), 1 + rng.I(8), 0.1);
    Scene scene;
    scene.skeleton = rig.skeleton;
    const int objects = rng.P(0.3) ? 1 + rng.I(3) : 1;
    // One scene in five far from the origin (10 m to 1 km): rounding slack.
    const Vec3 origin =
        scene_i % 5 == 4 ? Vec3(rng.Dir() * std::pow(10.0, rng.U(1, 3))) : Vec3::Zero();
    for (int o = 0; o < objects; ++o) {
      TriangleMesh mesh;
      AddSoup(rng, &mesh, 10 + rng.I(120 / objects), 1.6, 0.05, 0.4, origin);
      scene.meshes.push_back(mesh);
    }
    SceneUnderTest sut(std::move(scene));
    for (int i = 0; i < 20; ++i) {
      QuerySpec q = RandomMotion(rng, rig, sut, 0.8, 3.0, kPi, 2.5, 0.3, rng.P(0.85), origin);
      if (origin.norm() > 0) q.note = "random motion " + std::to_string(origin.norm()) + " m out";
      suite.Run(sut, q, seed, i);
    }
  }
  suite.Finish(3600);
}

// ---------------------------------------------------------------------------
// 2. An arm clear at both poses that swings through an obstacle mid-way.

TEST(CcdRandomTest, ArmSwingsThroughObstacle) {
  Suite suite("arm swings through an obstacle");
  for (int i = 0; i < ScaledCount(800); ++i) {
    const uint64_t seed = 0xA2A0000 + i;
    Rng rng(seed);
    const double arm = rng.U(0.5, 0.9), radius = rng.U(0.02, 0.06);
    std::vector<Link> links(2);
    links[0].name = "shoulder";
    links[0].radius = 0.04;
    links[1].name = "arm";
    links[1].parent = 0;
    links[1].b_L = Vec3(arm, 0, 0);
    links[1].radius = radius;
    const bool forearm = rng.P(0.3);
    if (forearm) {  // A rigid forearm riding on the arm.
      Link f;
      f.name = "forearm";
      f.parent = 1;
      f.b_L = Vec3(0.25, 0, 0);
      f.radius = 0.03;
      links.push_back(f);
    }
    Rig rig;
    rig.skeleton = Skeleton::FromLinks("arm", links, "ccd_random_test");
    rig.offset = {Vec3::Zero(), Vec3::Zero(), Vec3(arm, 0, 0)};
    rig.offset.resize(links.size());

    // Swing by theta about n (world), from d0 to R(theta, n) d0.
    const Vec3 shoulder = rng.Box(0.5);
    const Vec3 nrm = rng.Dir();
    const Vec3 d0 = rng.Perp(nrm);
    const double theta = rng.U(90, 170) * kPi / 180;
    const Vec3 dmid = Eigen::AngleAxisd(theta / 2, nrm) * d0;
    const double rho = rng.U(0.25, arm - 0.05);  // The arm itself crosses it.
    Scene scene;
    scene.skeleton = rig.skeleton;
    TriangleMesh mesh;
    const Vec3 centre = shoulder + rho * dmid;
    Mat3 R;
    R.col(2) = nrm;  // The obstacle's long axis crosses the swing plane.
    R.col(0) = dmid;
    R.col(1) = nrm.cross(dmid);
    const bool pole = rng.P(0.5);
    const double w = rng.U(0.005, 0.03);
    AddBox(&mesh, centre, R,
           pole ? Vec3(w, w, 0.3) : Vec3(rng.U(0.01, 0.08), rng.U(0.01, 0.08), rng.U(0.05, 0.3)));
    if (rng.P(0.5)) AddSoup(rng, &mesh, 20, 2.0, 0.05, 0.2);  // Distractors (may touch too).
    scene.meshes.push_back(mesh);
    SceneUnderTest sut(std::move(scene));

    const Eigen::Quaterniond q_shoulder = rng.Quat();
    const Eigen::Quaterniond arm0 = Eigen::Quaterniond::FromTwoVectors(Vec3::UnitX(), d0);
    const Eigen::Quaterniond arm1 = Eigen::Quaterniond(Eigen::AngleAxisd(theta, nrm)) * arm0;
    auto world = [&](const Eigen::Quaterniond& arm_q) {
      std::vector<LinkPose> w(links.size());
      w[0].p = shoulder;
      w[0].q = q_shoulder;
      w[1].p = shoulder;
      w[1].q = arm_q;
      if (forearm) {
        w[2].p = shoulder + arm_q * Vec3(arm, 0, 0);
        w[2].q = arm_q;
      }
      return w;
    };
    QuerySpec q;
    q.options = RandomOptions(rng, RandomModel(rng), 0.3);
    SetTimes(rng, &q, 5e3, 5e5);
    q.pose0 = MakePose(q.pose0.utime, world(arm0));
    q.pose1 = MakePose(q.pose1.utime, world(arm1));
    for (int k = -200; k <= 200; ++k) q.hints.push_back(0.5 + 0.25 * k / 200.0);
    // Clear at both ends (the distractors may spoil it; then anything goes).
    const bool clear_ends =
        PoseSeparation(sut, world(arm0)) > 0 && PoseSeparation(sut, world(arm1)) > 0;
    q.expect = clear_ends && sut.tris().size() == 12 ? Expect::kContact : Expect::kAny;
    q.note = std::string(pole ? "pole" : "box") + (forearm ? " + forearm" : "") + " swing " +
             std::to_string(theta * 180 / kPi) + " deg";
    if (sut.tris().size() == 12) {
      EXPECT_TRUE(clear_ends) << "generator: the obstacle touches an end pose, seed " << seed;
    }
    suite.Run(sut, q, seed, i);
  }
  suite.Finish(800);
}

// ---------------------------------------------------------------------------
// 3. A fast translation through a thin wall.

TEST(CcdRandomTest, FastTranslationThroughThinWall) {
  Suite suite("fast translation through a thin wall");
  for (int i = 0; i < ScaledCount(800); ++i) {
    const uint64_t seed = 0xA3A0000 + i;
    Rng rng(seed);
    const Rig rig = RandomRig(rng, 1 + rng.I(3), 2, 0.3, 0.02, 0.15, 0.002, 0.05);
    const double dist = rng.U(2, 10);
    const Vec3 u = rng.Dir();
    const double s_star = rng.U(0.2, 0.8);
    const Vec3 start = rng.Box(0.5);
    const Vec3 wall_point = start + s_star * dist * u;
    // Oblique wall: normal within 60 degrees of the motion.
    const Vec3 wn = (Eigen::AngleAxisd(rng.U(0, 60) * kPi / 180, rng.Perp(u)) * u).normalized();
    Mat3 R;
    R.col(0) = wn;
    R.col(1) = rng.Perp(wn);
    R.col(2) = wn.cross(R.col(1));
    Scene scene;
    scene.skeleton = rig.skeleton;
    TriangleMesh mesh;
    const bool box = rng.P(0.5);
    if (box) {
      AddBox(&mesh, wall_point, R, Vec3(0.0005, 0.75, 0.75));  // 1 mm thick.
    } else {
      AddQuad(&mesh, wall_point, 0.75 * R.col(1), 0.75 * R.col(2));  // Two triangles.
    }
    scene.meshes.push_back(mesh);
    SceneUnderTest sut(std::move(scene));

    const int n = rig.skeleton.num_links();
    std::vector<Eigen::Quaterniond> local(n);
    for (int k = 0; k < n; ++k) local[k] = rng.Turn(rng.U(0, 1));
    LinkPose root0, root1;
    root0.p = start;
    root0.q = rng.Quat();
    root1.p = start + dist * u;
    root1.q = rng.P(0.5) ? root0.q : rng.Turn(rng.U(0, kPi)) * root0.q;
    QuerySpec q;
    q.options = RandomOptions(rng, RandomModel(rng), 0.3);
    SetTimes(rng, &q, 5e3, 2e4);  // 5-20 ms: metres per frame.
    q.pose0 = MakePose(q.pose0.utime, Fk(rig, root0, local));
    q.pose1 = MakePose(q.pose1.utime, Fk(rig, root1, local));
    const double window = 0.6 / dist;
    for (int k = -300; k <= 300; ++k) q.hints.push_back(s_star + window * k / 300.0);
    q.expect = Expect::kContact;
    q.note =
        std::string(box ? "1 mm box" : "two-triangle wall") + ", " + std::to_string(dist) + " m";
    suite.Run(sut, q, seed, i);
  }
  suite.Finish(800);
}

// ---------------------------------------------------------------------------
// 4. Grazing contact: the minimum separation over the motion is a known g.

// Hints around s_star down to 1e-10.
void GrazeHints(double s_star, std::vector<double>* hints) {
  hints->push_back(s_star);
  for (int e = 2; e <= 10; ++e) {
    hints->push_back(s_star - std::pow(10.0, -e));
    hints->push_back(s_star + std::pow(10.0, -e));
  }
  for (int k = -100; k <= 100; ++k) {
    hints->push_back(s_star + 1e-3 * k / 100.0);
    hints->push_back(s_star + 1e-5 * k / 100.0);
  }
}

double RandomGap(Rng& rng) {
  const int k = rng.I(10);
  if (k < 4) return rng.U(-1e-4, 1e-4);
  if (k < 8) return (rng.P(0.5) ? 1 : -1) * std::pow(10.0, rng.U(-9, -4));
  if (k == 8) return 0;
  return (rng.P(0.5) ? 1 : -1) * 1e-12;
}

// Sets the expectation and sometimes a delta below the gap (then: free).
void GrazeExpectation(Rng& rng, double g, QuerySpec* q) {
  if (g < -kTol) {
    q->expect = Expect::kContact;
  } else if (g > 1e-6 && rng.P(0.4)) {
    q->options.delta_m = g / rng.U(2, 10);
    q->expect = Expect::kFree;
  }
}

// Kinds of triangle at a grazed vertex V (the rest lies beyond V).
enum class VertexKind { kProper, kPoint, kCollinear, kRepeated };

// A link translating past vertex V of a triangle at closest distance r + g.
struct GrazeCase {
  Scene scene;
  QuerySpec q;
};
GrazeCase VertexGraze(Rng& rng, VertexKind kind, double g, bool sphere) {
  GrazeCase out;
  Link l;
  l.name = "link";
  l.a_L = rng.P(0.5) ? Vec3::Zero() : rng.Box(0.05);
  l.b_L = sphere ? l.a_L : Vec3(l.a_L + rng.Dir() * rng.U(0.1, 0.4));
  l.radius = rng.U(0.01, 0.1);
  out.scene.skeleton = Skeleton::FromLinks("graze", {l}, "ccd_random_test");
  const Eigen::Quaterniond q = rng.Quat();
  const Vec3 u = q * (l.b_L - l.a_L);
  Vec3 D, n;
  for (;;) {
    D = rng.Dir() * rng.U(0.3, 2);
    if (sphere) {
      n = rng.Perp(D.normalized());
      break;
    }
    const Vec3 c = u.cross(D);
    if (c.norm() > 0.3 * u.norm() * D.norm()) {
      n = c.normalized();
      break;
    }
  }
  const Vec3 V = RoundToFloat(rng.Box(1));
  const double s_star = rng.U(0.2, 0.8), t_star = sphere ? 0 : rng.U(0.2, 0.8);
  // The closest axis point at s_star, then the frame origin.
  const Vec3 X = V - (l.radius + g) * n;
  const Vec3 p_star = X - q * l.a_L - t_star * u;
  LinkPose x0, x1;
  x0.p = p_star - s_star * D;
  x1.p = x0.p + D;
  x0.q = q;
  x1.q = q;
  const Vec3 e1 = rng.Perp(n);
  const Vec3 e2 = Eigen::AngleAxisd(rng.U(60, 150) * kPi / 180, n) * e1;
  const Vec3 W1 = V + 0.25 * n + 0.3 * e1, W2 = V + 0.25 * n + 0.3 * e2;
  TriangleMesh mesh;
  switch (kind) {
    case VertexKind::kProper:
      AddTri(&mesh, V, W1, W2);
      break;
    case VertexKind::kPoint:
      AddTri(&mesh, V, V, V);
      break;
    case VertexKind::kCollinear:  // V, W1 and a point on segment V-W1 (in float).
      AddTri(&mesh, V, W1, V + 0.5 * (W1 - V));
      break;
    case VertexKind::kRepeated:
      AddTri(&mesh, V, W1, W1);
      break;
  }
  out.scene.meshes.push_back(mesh);
  out.q.options = RandomOptions(rng, RandomModel(rng), 0.3);
  SetTimes(rng, &out.q);
  out.q.pose0 = MakePose(out.q.pose0.utime, {x0});
  out.q.pose1 = MakePose(out.q.pose1.utime, {x1});
  GrazeHints(s_star, &out.q.hints);
  GrazeExpectation(rng, g, &out.q);
  std::ostringstream os;
  os.precision(3);
  os << "vertex graze g=" << g << (sphere ? " sphere" : " capsule") << " s*=" << s_star;
  out.q.note = os.str();
  return out;
}

// An arm swinging about a pivot whose lowest point passes g above a floor.
GrazeCase FloorGraze(Rng& rng, double g) {
  GrazeCase out;
  const double rho = rng.U(0.2, 0.8), r = rng.U(0.01, 0.1);
  std::vector<Link> links(2);
  links[0].name = "pivot";
  links[0].radius = 0.02;
  links[1].name = "arm";
  links[1].parent = 0;
  links[1].b_L = Vec3(rho, 0, 0);
  links[1].radius = r;
  out.scene.skeleton = Skeleton::FromLinks("pendulum", links, "ccd_random_test");
  TriangleMesh floor;
  AddQuad(&floor, Vec3(0, 0, 0), Vec3(3, 0, 0), Vec3(0, 3, 0));
  out.scene.meshes.push_back(floor);
  const Vec3 C(rng.U(-0.5, 0.5), rng.U(-0.5, 0.5), rho + r + g);
  const double yaw = rng.U(0, 2 * kPi), alpha = rng.U(20, 85) * kPi / 180;
  const Vec3 h(std::cos(yaw), std::sin(yaw), 0);
  const Eigen::Quaterniond down(Eigen::AngleAxisd(kPi / 2, Vec3::UnitY()));  // x -> -z.
  const Eigen::Quaterniond pivot_q = rng.Quat();
  auto world = [&](double phi) {
    std::vector<LinkPose> w(2);
    w[0].p = C;
    w[0].q = pivot_q;
    w[1].p = C;
    w[1].q = Eigen::Quaterniond(Eigen::AngleAxisd(phi, h)) * down;
    return w;
  };
  out.q.options = RandomOptions(rng, RandomModel(rng), 0.3);
  SetTimes(rng, &out.q);
  out.q.pose0 = MakePose(out.q.pose0.utime, world(-alpha));
  out.q.pose1 = MakePose(out.q.pose1.utime, world(alpha));
  GrazeHints(0.5, &out.q.hints);
  GrazeExpectation(rng, g, &out.q);
  std::ostringstream os;
  os.precision(3);
  os << "floor graze g=" << g;
  out.q.note = os.str();
  return out;
}

// A capsule sliding along a triangle edge at constant distance r + g.
GrazeCase EdgeGraze(Rng& rng, double g) {
  GrazeCase out;
  Link l;
  l.name = "link";
  const double len = rng.U(0.2, 0.6);
  l.b_L = Vec3(len, 0, 0);
  l.radius = rng.U(0.01, 0.1);
  out.scene.skeleton = Skeleton::FromLinks("edge", {l}, "ccd_random_test");
  const Vec3 V1 = RoundToFloat(rng.Box(0.5));
  const Vec3 V2 = RoundToFloat(V1 + rng.Dir() * rng.U(0.5, 1));
  const Vec3 e = V2 - V1, eh = e.normalized();
  Vec3 u;
  do {
    u = rng.Dir();
  } while (std::fabs(u.dot(eh)) > 0.9);
  const Vec3 m = u.cross(e).normalized();
  const double te = rng.U(0.3, 0.7), tu = rng.U(0.3, 0.7), s_star = rng.U(0.2, 0.8);
  const Vec3 Xa = V1 + te * e + (l.radius + g) * m;             // Closest axis point at s_star.
  const Vec3 D = rng.U(-0.3, 0.3) * u + rng.U(-0.3, 0.3) * eh;  // D . m == 0.
  const Eigen::Quaterniond q = Eigen::Quaterniond(Eigen::AngleAxisd(rng.U(0, 2 * kPi), u)) *
                               Eigen::Quaterniond::FromTwoVectors(Vec3::UnitX(), u);
  LinkPose x0, x1;
  x0.p = Xa - tu * len * u - s_star * D;
  x1.p = x0.p + D;
  x0.q = q;
  x1.q = q;
  const Vec3 V3 = 0.5 * (V1 + V2) - 0.3 * m + 0.2 * eh.cross(m);
  TriangleMesh mesh;
  AddTri(&mesh, V1, V2, V3);
  out.scene.meshes.push_back(mesh);
  out.q.options = RandomOptions(rng, RandomModel(rng), 0.3);
  SetTimes(rng, &out.q);
  out.q.pose0 = MakePose(out.q.pose0.utime, {x0});
  out.q.pose1 = MakePose(out.q.pose1.utime, {x1});
  GrazeHints(s_star, &out.q.hints);
  GrazeExpectation(rng, g, &out.q);
  std::ostringstream os;
  os.precision(3);
  os << "edge slide g=" << g;
  out.q.note = os.str();
  return out;
}

TEST(CcdRandomTest, GrazingContact) {
  Suite suite("grazing contact");
  for (int i = 0; i < ScaledCount(1200); ++i) {
    const uint64_t seed = 0xA4A0000 + i;
    Rng rng(seed);
    const double g = RandomGap(rng);
    GrazeCase c = i % 3 == 0   ? VertexGraze(rng, VertexKind::kProper, g, rng.P(0.4))
                  : i % 3 == 1 ? FloorGraze(rng, g)
                               : EdgeGraze(rng, g);
    SceneUnderTest sut(std::move(c.scene));
    suite.Run(sut, c.q, seed, i);
  }
  suite.Finish(1200);
}

// A deep articulated chain whose lowest point (along a random direction n)
// over the whole motion is found by dense sampling and golden refinement of
// the reference motion; a large quad perpendicular to n is then placed so
// that the minimum separation is g: a smooth tangency at an unknown-in-advance
// time, the hardest case for swept bounds of composed rotations.
GrazeCase ChainTangentToPlane(Rng& rng, double g) {
  GrazeCase out;
  const int n = 3 + rng.I(6);
  std::vector<Link> links(n);
  Rig rig;
  rig.offset.assign(n, Vec3::Zero());
  for (int i = 0; i < n; ++i) {
    links[i].name = "c" + std::to_string(i);
    links[i].parent = i - 1;
    links[i].a_L = Vec3::Zero();
    links[i].b_L = rng.P(0.15) ? Vec3::Zero() : Vec3(rng.Dir() * rng.U(0.1, 0.3));
    links[i].radius = rng.U(0.01, 0.08);
    if (i > 0) rig.offset[i] = links[i - 1].b_L;
  }
  rig.skeleton = Skeleton::FromLinks("chain", links, "ccd_random_test");
  out.scene.skeleton = rig.skeleton;
  std::vector<Eigen::Quaterniond> local0(n), local1(n);
  for (int i = 0; i < n; ++i) {
    local0[i] = rng.Turn(rng.U(0, 1.5));
    local1[i] = rng.Turn(rng.U(0, 2.5)) * local0[i];
  }
  LinkPose root0, root1;
  root0.p = rng.Box(0.3);
  root0.q = rng.Quat();
  root1.p = root0.p + rng.Dir() * rng.U(0, 1);
  root1.q = rng.Turn(rng.U(0, kPi)) * root0.q;
  out.q.options = RandomOptions(rng, RandomModel(rng), 0.3);
  SetTimes(rng, &out.q);
  out.q.pose0 = MakePose(out.q.pose0.utime, Fk(rig, root0, local0));
  out.q.pose1 = MakePose(out.q.pose1.utime, Fk(rig, root1, local1));
  const RefMotion motion(rig.skeleton, out.q.pose0, out.q.pose1,
                         out.q.options.motion == MotionModel::kArticulated);
  Vec3 dir;
  std::vector<Vec3> A(n), B(n);
  // Lowest point along dir over all links at s: its height and the point.
  auto lowest = [&](double s, Vec3* point) {
    motion.Segments(s, A.data(), B.data());
    double best = 1e300;
    for (int l = 0; l < n; ++l) {
      for (const Vec3* x : {&A[l], &B[l]}) {
        const double h = dir.dot(*x) - links[l].radius;
        if (h < best) {
          best = h;
          if (point != nullptr) *point = *x - links[l].radius * dir;
        }
      }
    }
    return best;
  };
  constexpr int kDense = 20001;
  int k_best = 0;
  double f_best = 1e300;
  auto scan = [&](int samples) {
    k_best = 0;
    f_best = 1e300;
    for (int k = 0; k < samples; ++k) {
      const double f = lowest(static_cast<double>(k) / (samples - 1), nullptr);
      if (f < f_best) {
        f_best = f;
        k_best = k;
      }
    }
  };
  for (int attempt = 0; attempt < 10; ++attempt) {  // Prefer a minimum inside (0, 1).
    dir = rng.Dir();
    scan(1001);
    if (k_best > 0 && k_best < 1000) break;
  }
  scan(kDense);  // Fine: a dip narrower than 5e-5 in s is at most ~3e-7 m deep here.
  double lo = std::max(0, k_best - 1) / double(kDense - 1);
  double hi = std::min(kDense - 1, k_best + 1) / double(kDense - 1);
  for (int it = 0; it < 100; ++it) {  // Golden section on the bracketing samples.
    const double m1 = hi - 0.6180339887498949 * (hi - lo), m2 = lo + 0.6180339887498949 * (hi - lo);
    if (lowest(m1, nullptr) <= lowest(m2, nullptr)) {
      hi = m2;
    } else {
      lo = m1;
    }
  }
  double s_min = 0.5 * (lo + hi);
  Vec3 P = Vec3::Zero();
  double f_min = lowest(s_min, &P);
  if (f_best < f_min) {  // An end sample (or a kink) is lower.
    s_min = static_cast<double>(k_best) / (kDense - 1);
    f_min = lowest(s_min, &P);
  }
  const double plane = f_min - g;  // The plane dir . x = plane.
  const Vec3 centre = P - (dir.dot(P) - plane) * dir;
  const Vec3 e1 = rng.Perp(dir), e2 = dir.cross(e1);
  TriangleMesh mesh;
  AddQuad(&mesh, centre, 2.0 * e1, 2.0 * e2);
  out.scene.meshes.push_back(mesh);
  GrazeHints(s_min, &out.q.hints);
  // The quad's float corners move the plane by ~2e-7 m: expectations only
  // where the gap is clearly larger.
  if (g < -1e-6) {
    out.q.expect = Expect::kContact;
  } else if (g > 1e-5 && rng.P(0.4)) {
    out.q.options.delta_m = g / rng.U(2, 10);
    out.q.expect = Expect::kFree;
  }
  std::ostringstream os;
  os.precision(3);
  os << "chain of " << n << " tangent to a plane, g=" << g << " at s=" << s_min;
  out.q.note = os.str();
  return out;
}

TEST(CcdRandomTest, DeepChainTangentToPlane) {
  Suite suite("deep chain tangent to a plane");
  for (int i = 0; i < ScaledCount(600); ++i) {
    const uint64_t seed = 0xA4B0000 + i;
    Rng rng(seed);
    const double g = RandomGap(rng);
    GrazeCase c = ChainTangentToPlane(rng, g);
    SceneUnderTest sut(std::move(c.scene));
    suite.Run(sut, c.q, seed, i);
  }
  suite.Finish(600);
}

// ---------------------------------------------------------------------------
// 5. Initially colliding.

TEST(CcdRandomTest, InitiallyColliding) {
  Suite suite("initially colliding");
  for (int scene_i = 0; scene_i < ScaledCount(60); ++scene_i) {
    const uint64_t seed = 0xA5A0000 + scene_i;
    Rng rng(seed);
    const Rig rig = RandomRig(rng, 1 + rng.I(8), 1 + rng.I(4), 0.2);
    const int n = rig.skeleton.num_links();
    for (int i = 0; i < 10; ++i) {
      // Pose 0 first, then a triangle through (or just into) one link there.
      LinkPose root;
      root.p = rng.Box(0.5);
      root.q = rng.Quat();
      std::vector<Eigen::Quaterniond> local(n);
      for (int k = 0; k < n; ++k) local[k] = rng.Turn(rng.U(0, 1.5));
      const std::vector<LinkPose> w0 = Fk(rig, root, local);
      const int l = rng.I(n);
      const Link& link = rig.skeleton.link(l);
      const Vec3 A = w0[l].p + w0[l].q * link.a_L, B = w0[l].p + w0[l].q * link.b_L;
      const Vec3 X = A + rng.U(0, 1) * (B - A);
      Scene scene;
      scene.skeleton = rig.skeleton;
      TriangleMesh mesh;
      const bool shallow = rng.P(0.4);
      double pen = 0;
      if (shallow) {
        // A face whose plane is radius - pen from the segment, normal across it.
        const Vec3 axis = (B - A).norm() > 0 ? Vec3((B - A).normalized()) : rng.Dir();
        const Vec3 nrm = rng.Perp(axis);
        pen = std::pow(10.0, rng.U(-5, -3));
        // Every point of the segment is at least as far from the plane as X.
        const Vec3 P = X + (link.radius - pen) * nrm;
        const Vec3 t1 = axis, t2 = nrm.cross(axis);
        AddQuad(&mesh, P, 0.5 * t1, 0.5 * t2);
      } else {
        const Vec3 nrm = rng.Dir(), e1 = rng.Perp(nrm), e2 = nrm.cross(e1);
        const double size = rng.U(0.02, 0.3), phase = rng.U(0, 2 * kPi);
        auto vert = [&](int k) {
          const double ang = phase + 2 * kPi * k / 3 + rng.U(-0.3, 0.3);
          return Vec3(X + size * (std::cos(ang) * e1 + std::sin(ang) * e2));
        };
        AddTri(&mesh, vert(0), vert(1), vert(2));
      }
      if (rng.P(0.5)) AddSoup(rng, &mesh, 30, 1.5, 0.05, 0.3);
      scene.meshes.push_back(mesh);
      SceneUnderTest sut(std::move(scene));
      LinkPose root1;
      root1.p = root.p + rng.Dir() * rng.U(0, 1);
      root1.q = rng.Turn(rng.U(0, 2)) * root.q;
      std::vector<Eigen::Quaterniond> local1(n);
      for (int k = 0; k < n; ++k) local1[k] = rng.Turn(rng.U(0, 1.5)) * local[k];
      QuerySpec q;
      q.options = RandomOptions(rng, RandomModel(rng), 0.4);
      SetTimes(rng, &q);
      q.pose0 = MakePose(q.pose0.utime, w0);
      q.pose1 = MakePose(q.pose1.utime, Fk(rig, root1, local1));
      // Float corners move the shallow quad's plane by ~1e-7 m, far less than
      // the penetration (>= 1e-5 m).
      q.expect = Expect::kInitiallyColliding;
      q.note = shallow ? "shallow initial penetration " + std::to_string(pen)
                       : "triangle through a link";
      suite.Run(sut, q, seed, i);
    }
  }
  suite.Finish(600);
}

// ---------------------------------------------------------------------------
// 6. Degenerate triangles.

void AddDegenerateSoup(Rng& rng, TriangleMesh* mesh, int count, double half) {
  for (int i = 0; i < count; ++i) {
    const Vec3 a = RoundToFloat(rng.Box(half));
    Vec3 b = a, c = a;
    switch (rng.I(4)) {
      case 0: {  // Exactly collinear: only one coordinate differs.
        const int axis = rng.I(3);
        b[axis] += rng.U(-0.4, 0.4);
        c[axis] += rng.U(-0.4, 0.4);
        break;
      }
      case 1:  // Repeated vertex.
        b = a + rng.Box(0.3);
        c = rng.P(0.5) ? a : b;
        break;
      case 2:  // A point.
        break;
      default:  // Collinear up to float rounding.
        b = a + rng.Box(0.4);
        c = a + rng.U(-1, 2) * (b - a);
        break;
    }
    AddTri(mesh, a, b, c);
  }
}

TEST(CcdRandomTest, DegenerateTriangles) {
  Suite suite("degenerate triangles");
  // Random motions through soups of zero-area triangles.
  for (int scene_i = 0; scene_i < ScaledCount(25); ++scene_i) {
    const uint64_t seed = 0xA6A0000 + scene_i;
    Rng rng(seed);
    const Rig rig = RandomRig(rng, 1 + rng.I(4), 3, 0.2);
    Scene scene;
    scene.skeleton = rig.skeleton;
    TriangleMesh mesh;
    AddDegenerateSoup(rng, &mesh, 40 + rng.I(80), 1.2);
    scene.meshes.push_back(mesh);
    SceneUnderTest sut(std::move(scene));
    for (int i = 0; i < 20; ++i) {
      QuerySpec q = RandomMotion(rng, rig, sut, 0.8, 2.0, kPi, 2.0, 0.3, rng.P(0.8));
      q.note = "degenerate soup";
      suite.Run(sut, q, seed, i);
    }
  }
  // Grazing a point, a segment-like or a repeated-vertex triangle at known gaps.
  for (int i = 0; i < ScaledCount(300); ++i) {
    const uint64_t seed = 0xA6B0000 + i;
    Rng rng(seed);
    const VertexKind kind = i % 3 == 0   ? VertexKind::kPoint
                            : i % 3 == 1 ? VertexKind::kCollinear
                                         : VertexKind::kRepeated;
    // Mostly clear penetrations (touching them must count), some grazes.
    const double g = rng.P(0.6) ? -rng.U(1e-4, 5e-3) : RandomGap(rng);
    GrazeCase c = VertexGraze(rng, kind, g, rng.P(0.5));
    c.q.note = "degenerate " + c.q.note;
    SceneUnderTest sut(std::move(c.scene));
    suite.Run(sut, c.q, seed, 1000 + i);
  }
  suite.Finish(800);
}

// ---------------------------------------------------------------------------
// 7. Zero-length links (spheres).

TEST(CcdRandomTest, ZeroLengthLinks) {
  Suite suite("zero-length links");
  for (int scene_i = 0; scene_i < ScaledCount(30); ++scene_i) {
    const uint64_t seed = 0xA7A0000 + scene_i;
    Rng rng(seed);
    const Rig rig = RandomRig(rng, 1 + rng.I(10), 1 + rng.I(6), scene_i % 3 == 0 ? 0.5 : 1.0);
    Scene scene;
    scene.skeleton = rig.skeleton;
    TriangleMesh mesh;
    AddSoup(rng, &mesh, 20 + rng.I(100), 1.5, 0.05, 0.4);
    if (rng.P(0.3)) AddDegenerateSoup(rng, &mesh, 20, 1.2);
    scene.meshes.push_back(mesh);
    SceneUnderTest sut(std::move(scene));
    for (int i = 0; i < 20; ++i) {
      QuerySpec q = RandomMotion(rng, rig, sut, 0.8, 3.0, kPi, 2.5, 0.3, rng.P(0.85));
      q.note = "spheres";
      suite.Run(sut, q, seed, i);
    }
  }
  suite.Finish(600);
}

// ---------------------------------------------------------------------------
// 8. Rotations near and at 180 degrees; q versus -q.

// A unit quaternion whose nonzero components are exactly those in `mask`
// (bits w, x, y, z): pairs with complementary masks have a dot product of
// exactly zero in any summation order (a 180-degree relative turn).
Eigen::Quaterniond SparseQuat(Rng& rng, int mask) {
  double c[4];
  for (int k = 0; k < 4; ++k) c[k] = (mask >> k & 1) ? rng.N() : 0.0;
  Eigen::Quaterniond q(c[0], c[1], c[2], c[3]);
  return q.normalized();
}
// A pair with dot(q0, q1) == eps (|eps| < 1).
std::pair<Eigen::Quaterniond, Eigen::Quaterniond> DotPair(Rng& rng, double eps) {
  const Eigen::Quaterniond q0 = rng.Quat();
  Eigen::Vector4d w(rng.N(), rng.N(), rng.N(), rng.N());
  w -= w.dot(q0.coeffs()) * q0.coeffs();
  w.normalize();
  Eigen::Quaterniond q1;
  q1.coeffs() = eps * q0.coeffs() + std::sqrt(1 - eps * eps) * w;
  return {q0, q1};
}
// Signed unit-axis quaternions (identity and the 180-degree turns about x, y,
// z): products with them permute components exactly.
Eigen::Quaterniond AxisQuat(Rng& rng) {
  double c[4] = {0, 0, 0, 0};
  c[rng.I(4)] = rng.P(0.5) ? 1 : -1;
  return Eigen::Quaterniond(c[0], c[1], c[2], c[3]);
}

// The same record (tests/common/same_record.h); *why names the first
// difference and describes both.
bool SameResult(const QueryResult& a, const QueryResult& b, std::string* why) {
  const std::string d = testing::RecordDifference(a, b);
  if (d.empty()) return true;
  *why = d + " differs:\n  first: " + DescribeResult(a) + "\n  second: " + DescribeResult(b);
  return false;
}

TEST(CcdRandomTest, RotationsNear180Degrees) {
  Suite suite("rotations near 180 degrees");
  int flips = 0, flip_failures = 0;
  for (int scene_i = 0; scene_i < ScaledCount(40); ++scene_i) {
    const uint64_t seed = 0xA8A0000 + scene_i;
    Rng rng(seed);
    const int n = 1 + rng.I(4);
    const bool chain = rng.P(0.5);  // Else a star: every link on the root.
    std::vector<Link> links(n);
    std::vector<bool> has_child(n, false);
    Rig rig;
    rig.offset.assign(n, Vec3::Zero());
    for (int i = 0; i < n; ++i) {
      links[i].name = "l" + std::to_string(i);
      links[i].parent = i == 0 ? -1 : (chain ? i - 1 : 0);
      if (i > 0) has_child[links[i].parent] = true;
      links[i].a_L = rng.P(0.5) ? Vec3::Zero() : rng.Box(0.05);
      links[i].b_L = links[i].a_L + rng.Dir() * rng.U(0.3, 0.8);
      links[i].radius = rng.U(0.02, 0.08);
      if (i > 0) rig.offset[i] = chain ? links[i - 1].b_L : rng.Box(0.2);
    }
    rig.skeleton = Skeleton::FromLinks(chain ? "chain" : "star", links, "ccd_random_test");
    Scene scene;
    scene.skeleton = rig.skeleton;
    TriangleMesh mesh;
    AddSoup(rng, &mesh, 40 + rng.I(60), 1.3, 0.05, 0.3);
    scene.meshes.push_back(mesh);
    SceneUnderTest sut(std::move(scene));
    for (int i = 0; i < 20; ++i) {
      QuerySpec q;
      q.options = RandomOptions(rng, RandomModel(rng), 0.3);
      SetTimes(rng, &q);
      const bool articulated = q.options.motion == MotionModel::kArticulated;
      const int mode = rng.I(3);  // 0: exact 180, 1: dot ~ +-1e-9..1e-3, 2: random.
      std::vector<LinkPose> w0(n), w1(n);
      const Vec3 p0 = rng.Box(0.4), p1 = p0 + rng.Dir() * rng.U(0, 0.5);
      // Rotation pairs: world pairs (independent, and the root) or relative
      // pairs for children (articulated). For exactly 180 under the
      // articulated model, links with children turn between signed
      // unit-axis quaternions, so that every product the engine and the
      // reference form is exact and the relative dot products stay exactly 0.
      std::vector<std::pair<Eigen::Quaterniond, Eigen::Quaterniond>> pairs(n);
      for (int l = 0; l < n; ++l) {
        if (mode == 0) {
          if (articulated && has_child[l]) {
            Eigen::Quaterniond a = AxisQuat(rng), b;
            do {
              b = AxisQuat(rng);
            } while (std::fabs(a.coeffs().dot(b.coeffs())) != 0);
            pairs[l] = {a, b};
          } else {
            const int mask = 1 + rng.I(14);  // Not 0, not 15.
            pairs[l] = {SparseQuat(rng, mask), SparseQuat(rng, 15 & ~mask)};
          }
        } else if (mode == 1) {
          pairs[l] = DotPair(rng, (rng.P(0.5) ? 1 : -1) * std::pow(10.0, rng.U(-9, -3)));
        } else {
          pairs[l] = {rng.Quat(), rng.Quat()};
        }
      }
      // Parents first (parent index < child index).
      for (int l = 0; l < n; ++l) {
        const int k = links[l].parent;
        if (k < 0) {
          w0[l].p = p0;
          w1[l].p = p1;
          w0[l].q = pairs[l].first;
          w1[l].q = pairs[l].second;
        } else if (articulated) {
          w0[l].q = w0[k].q * pairs[l].first;
          w1[l].q = w1[k].q * pairs[l].second;
          w0[l].p = w0[k].p + w0[k].q * rig.offset[l];
          w1[l].p = w1[k].p + w1[k].q * rig.offset[l];
        } else {
          w0[l].q = pairs[l].first;
          w1[l].q = pairs[l].second;
          w0[l].p = p0 + rig.offset[l];
          w1[l].p = p1 + rig.offset[l];
        }
      }
      q.pose0 = MakePose(q.pose0.utime, w0);
      q.pose1 = MakePose(q.pose1.utime, w1);
      q.note = mode == 0 ? "exactly 180" : mode == 1 ? "dot near 0" : "random turns";
      suite.Run(sut, q, seed, i);
      // q versus -q: the same motion, the same answer, bit for bit (not for
      // exactly 180, where -q1 reverses the turn: SPEC flips only when dot < 0).
      if (mode != 0) {
        QuerySpec f = q;
        for (int l = 0; l < n; ++l) {
          if (rng.P(0.5)) f.pose0.links[l].q.coeffs() *= -1;
          if (rng.P(0.5)) f.pose1.links[l].q.coeffs() *= -1;
        }
        const QueryResult a = sut.engine().Query(q.pose0, q.pose1, q.options);
        const QueryResult b = sut.engine().Query(f.pose0, f.pose1, f.options);
        std::string why;
        ++flips;
        if (!SameResult(a, b, &why)) {
          ++flip_failures;
          if (flip_failures <= 3) {
            ADD_FAILURE() << "q versus -q gives another answer, seed " << seed << " query " << i
                          << ":\n  " << why << "\n"
                          << DescribeCase("q vs -q (flipped poses)", seed, i, sut, f);
          }
        }
        suite.Run(sut, f, seed, 100 + i);  // The flipped inputs against the reference too.
      }
    }
  }
  std::printf("[q versus -q] %d comparisons, %d differ\n", flips, flip_failures);
  EXPECT_EQ(flip_failures, 0);
  suite.Finish(800);
}

// ---------------------------------------------------------------------------
// 9. A 16-link humanoid, articulated, in a furnished room.

struct Humanoid {
  Rig rig;
  int foot_l = -1, foot_r = -1;
  std::vector<double> limit;  // Joint turn limit per link, radians.
};

Humanoid MakeHumanoid() {
  struct Spec {
    const char* name;
    int parent;
    Vec3 offset, a, b;
    double radius, limit_deg;
  };
  const std::vector<Spec> specs = {
      {"pelvis", -1, {0, 0, 0}, {-0.1, 0, 0}, {0.1, 0, 0}, 0.12, 0},
      {"spine", 0, {0, 0.05, 0}, {0, 0, 0}, {0, 0.25, 0}, 0.11, 40},
      {"chest", 1, {0, 0.25, 0}, {0, 0, 0}, {0, 0.25, 0}, 0.13, 30},
      {"head", 2, {0, 0.3, 0}, {0, 0.05, 0}, {0, 0.2, 0}, 0.1, 60},
      {"upper_arm_l", 2, {0.2, 0.22, 0}, {0, 0, 0}, {0.28, 0, 0}, 0.05, 150},
      {"forearm_l", 4, {0.28, 0, 0}, {0, 0, 0}, {0.26, 0, 0}, 0.04, 130},
      {"hand_l", 5, {0.26, 0, 0}, {0, 0, 0}, {0.1, 0, 0}, 0.035, 80},
      {"upper_arm_r", 2, {-0.2, 0.22, 0}, {0, 0, 0}, {-0.28, 0, 0}, 0.05, 150},
      {"forearm_r", 7, {-0.28, 0, 0}, {0, 0, 0}, {-0.26, 0, 0}, 0.04, 130},
      {"hand_r", 8, {-0.26, 0, 0}, {0, 0, 0}, {-0.1, 0, 0}, 0.035, 80},
      {"thigh_l", 0, {0.1, -0.05, 0}, {0, 0, 0}, {0, -0.42, 0}, 0.07, 90},
      {"shin_l", 10, {0, -0.42, 0}, {0, 0, 0}, {0, -0.4, 0}, 0.05, 100},
      {"foot_l", 11, {0, -0.4, 0}, {0, -0.03, -0.05}, {0, -0.03, 0.15}, 0.04, 40},
      {"thigh_r", 0, {-0.1, -0.05, 0}, {0, 0, 0}, {0, -0.42, 0}, 0.07, 90},
      {"shin_r", 13, {0, -0.42, 0}, {0, 0, 0}, {0, -0.4, 0}, 0.05, 100},
      {"foot_r", 14, {0, -0.4, 0}, {0, -0.03, -0.05}, {0, -0.03, 0.15}, 0.04, 40},
  };
  Humanoid h;
  std::vector<Link> links;
  for (const Spec& s : specs) {
    Link l;
    l.name = s.name;
    l.parent = s.parent;
    l.a_L = s.a;
    l.b_L = s.b;
    l.radius = s.radius;
    links.push_back(l);
    h.rig.offset.push_back(s.offset);
    h.limit.push_back(s.limit_deg * kPi / 180);
  }
  h.rig.skeleton = Skeleton::FromLinks("humanoid", links, "ccd_random_test");
  h.foot_l = h.rig.skeleton.FindLink("foot_l");
  h.foot_r = h.rig.skeleton.FindLink("foot_r");
  return h;
}

TEST(CcdRandomTest, Humanoid16LinksArticulated) {
  Suite suite("16-link humanoid");
  const Humanoid hum = MakeHumanoid();
  ASSERT_EQ(hum.rig.skeleton.num_links(), 16);
  for (int scene_i = 0; scene_i < ScaledCount(40); ++scene_i) {
    const uint64_t seed = 0xA9A0000 + scene_i;
    Rng rng(seed);
    Scene scene;
    scene.skeleton = hum.rig.skeleton;
    TriangleMesh floor, furniture, clutter;
    AddQuad(&floor, Vec3(0, 0, 0), Vec3(3, 0, 0), Vec3(0, 0, 3));  // y = 0.
    AddBox(&furniture, Vec3(rng.U(0.3, 0.9), rng.U(0.6, 0.9), rng.U(-0.3, 0.5)),
           Mat3(Eigen::AngleAxisd(rng.U(0, kPi), Vec3::UnitY())), Vec3(0.4, 0.02, 0.3));
    AddQuad(&furniture, Vec3(0, 1.2, rng.U(-1.2, -0.6)), Vec3(1.5, 0, 0), Vec3(0, 1.2, 0));
    AddBox(&furniture, Vec3(rng.U(-0.9, -0.4), 1.0, rng.U(-0.3, 0.6)), Mat3::Identity(),
           Vec3(0.03, 1.0, 0.03));
    for (int k = 0; k < 50; ++k) {
      const Vec3 c(rng.U(-1.5, 1.5), rng.U(0, 2), rng.U(-1.5, 1.5));
      const double size = rng.U(0.05, 0.2);
      AddTri(&clutter, c + size * rng.Box(1), c + size * rng.Box(1), c + size * rng.Box(1));
    }
    scene.meshes = {floor, furniture, clutter};
    const bool feet_filter = scene_i % 3 != 0;
    if (feet_filter) scene.ignored = {{hum.foot_l, 0}, {hum.foot_r, 0}};
    if (scene_i % 5 == 4) scene.ignored.push_back({-1, 2});  // Nothing touches the clutter.
    SceneUnderTest sut(std::move(scene));
    for (int i = 0; i < 20; ++i) {
      std::vector<Eigen::Quaterniond> local0(16), local1(16);
      for (int l = 0; l < 16; ++l) {
        local0[l] = rng.Turn(rng.U(0, hum.limit[l]));
        local1[l] = rng.P(0.3) ? local0[l] : rng.Turn(rng.U(0, hum.limit[l]));
      }
      LinkPose root0, root1;
      const bool prefer_clear = rng.P(0.8);
      for (int attempt = 0; attempt < 10; ++attempt) {
        root0.p = Vec3(rng.U(-0.5, 0.5), rng.U(0.9, 1.05), rng.U(-0.5, 0.5));
        root0.q = Eigen::Quaterniond(Eigen::AngleAxisd(rng.U(0, 2 * kPi), Vec3::UnitY())) *
                  rng.Turn(rng.U(0, 0.3));
        if (!prefer_clear || PoseSeparation(sut, Fk(hum.rig, root0, local0)) > 0) break;
        for (int l = 0; l < 16; ++l) local0[l] = rng.Turn(rng.U(0, hum.limit[l]));
      }
      root1.p = root0.p + Vec3(rng.U(-0.4, 0.4), rng.U(-0.1, 0.1), rng.U(-0.4, 0.4));
      root1.q = Eigen::Quaterniond(Eigen::AngleAxisd(rng.U(-1.5, 1.5), Vec3::UnitY())) * root0.q;
      QuerySpec q;
      q.options = RandomOptions(
          rng, rng.P(0.85) ? MotionModel::kArticulated : MotionModel::kIndependent, 0.5);
      SetTimes(rng, &q, 5e3, 2e5);
      q.pose0 = MakePose(q.pose0.utime, Fk(hum.rig, root0, local0));
      q.pose1 = MakePose(q.pose1.utime, Fk(hum.rig, root1, local1));
      q.note = feet_filter ? "humanoid, feet ignore the floor" : "humanoid";
      suite.Run(sut, q, seed, i);
    }
  }
  suite.Finish(800);
}

// ---------------------------------------------------------------------------
// Fingers (issue 31): an XR_EXT_hand_tracking hand (25 links, --hands full)
// through the joint-set adapter, its joint frames built by a procedural hand
// (rigid palm, each finger a chain curling about the hand's lateral axis)
// and converted by JointSkeleton::Convert, reaching for a table edge or
// closing round a thin rod (4 mm square). Every pair is checked against the
// dense reference (G1-G3, no miss), so each finger capsule's contact is
// certified, with the link groups (link_groups.h) on (as by default from 32
// links; this hand has 25).

struct ProceduralHand {
  // Hand frame: x lateral (index to little), y along the fingers, z out of
  // the back of the hand (the fingers curl towards -z, the palm's side). Per finger (thumb first):
  // the metacarpal joint's offset from the wrist and the bone lengths from it (thumb: 3 bones,
  // others 4).
  struct Finger {
    const char* name;
    Vec3 base;
    std::vector<double> bones;
  };
  std::vector<Finger> fingers = {{"THUMB", Vec3(-0.02, 0.02, -0.01), {0.045, 0.035, 0.03}},
                                 {"INDEX", Vec3(-0.015, 0.01, 0), {0.065, 0.04, 0.025, 0.02}},
                                 {"MIDDLE", Vec3(0.0, 0.01, 0), {0.065, 0.045, 0.028, 0.02}},
                                 {"RING", Vec3(0.015, 0.01, 0), {0.06, 0.042, 0.026, 0.019}},
                                 {"LITTLE", Vec3(0.03, 0.01, 0), {0.055, 0.032, 0.02, 0.018}}};

  // The frame of set ext-hand: wrist pose (p, q), curl in [0, 1].
  JointFrame Frame(const JointSet& set, const Vec3& p, const Eigen::Quaterniond& q, double curl,
                   int64_t utime) const {
    JointFrame f;
    f.utime = utime;
    f.joints.resize(set.joints.size());
    for (JointSample& j : f.joints) {
      j.p = p;
      j.q = q;
    }
    auto at = [&](const std::string& name) -> JointSample& {
      const int j = set.FindJoint("XR_HAND_JOINT_" + name + "_EXT");
      EXPECT_GE(j, 0) << name;
      return f.joints[std::max(j, 0)];
    };
    at("WRIST").p = p;
    at("PALM").p = p + q * Vec3(0.005, 0.045, 0);
    static const char* kThumb[] = {"METACARPAL", "PROXIMAL", "DISTAL", "TIP"};
    static const char* kOther[] = {"METACARPAL", "PROXIMAL", "INTERMEDIATE", "DISTAL", "TIP"};
    for (const Finger& fi : fingers) {
      const bool thumb = std::string(fi.name) == "THUMB";
      Vec3 x = p + q * fi.base;
      at(std::string(fi.name) + "_" + (thumb ? kThumb[0] : kOther[0])).p = x;
      for (size_t k = 0; k < fi.bones.size(); ++k) {
        // The metacarpal bone stays in the palm; each later bone bends by
        // curl x 80 degrees more (thumb: about the palm normal, inwards).
        const double bend = k == 0 ? 0.0 : curl * 1.4 * static_cast<double>(k);
        const Vec3 axis = thumb ? Vec3(0, 0, 1) : Vec3(1, 0, 0);
        const Vec3 dir = q * (Eigen::AngleAxisd(thumb ? bend : -bend, axis) * Vec3(0, 1, 0));
        x += fi.bones[k] * dir;
        at(std::string(fi.name) + "_" + (thumb ? kThumb[k + 1] : kOther[k + 1])).p = x;
      }
    }
    return f;
  }
};

TEST(CcdRandomTest, FingersOnATableEdgeAndAThinRod) {
  Suite suite("fingers (ext-hand, 25 links)");
  const JointSet& set = FindJointSet("ext-hand");
  const ProceduralHand hand;
  JointSkeletonOptions so;
  const JointFrame cal = hand.Frame(set, Vec3::Zero(), Eigen::Quaterniond::Identity(), 0, 0);
  so.calibration = &cal;
  const JointSkeleton js = JointSkeleton::Build(set, so);
  ASSERT_EQ(js.skeleton().num_links(), 25);
  int64_t table_contacts = 0, rod_contacts = 0;
  for (int scene_i = 0; scene_i < ScaledCount(12); ++scene_i) {
    const uint64_t seed = 0xF1A0000 + scene_i;
    Rng rng(seed);
    Scene scene;
    scene.skeleton = js.skeleton();
    // Table top 1.0 x 0.6 x 0.04 m, its top at z = 0.75, edge along x at
    // y = 0.3; a rod along z at (rod_x, 0.45), from z = 0.75 to 1.75.
    TriangleMesh table, rod;
    AddBox(&table, Vec3(0, 0, 0.73), Mat3::Identity(), Vec3(0.5, 0.3, 0.02));
    const double rod_x = rng.U(-0.3, 0.3);
    AddBox(&rod, Vec3(rod_x, 0.45, 1.25), Mat3(Eigen::AngleAxisd(rng.U(0, kPi), Vec3::UnitZ())),
           Vec3(0.002, 0.002, 0.5));
    scene.meshes = {table, rod};
    SceneUnderTest sut(std::move(scene));
    for (int i = 0; i < 20; ++i) {
      // Reach: the hand comes in over the edge (fingers pointing -y, palm
      // down) and curls onto it; grasp: the open hand closes round the rod.
      const bool rod_case = rng.P(0.5);
      Vec3 p0, p1;
      Eigen::Quaterniond q0, q1;
      if (rod_case) {
        // The hand's lateral axis along the rod, fingers horizontal, the
        // rod on the palm's side (-z) of the proximal phalanges.
        const Eigen::Quaterniond face(Eigen::AngleAxisd(rng.U(0, 2 * kPi), Vec3::UnitZ()));
        Mat3 along;
        along.col(0) = Vec3::UnitZ();
        along.col(1) = Vec3::UnitX();
        along.col(2) = Vec3::UnitY();
        q0 = face * Eigen::Quaterniond(along) * rng.Turn(rng.U(0, 0.15));
        const Vec3 grip = Vec3(rod_x, 0.45, rng.U(0.9, 1.6));
        p0 = grip - q0 * Vec3(0, rng.U(0.085, 0.12), -rng.U(0.016, 0.04));
        p1 = p0 + rng.Box(0.01);
        q1 = q0 * rng.Turn(rng.U(0, 0.1));
      } else {
        q0 = Eigen::Quaterniond(Eigen::AngleAxisd(kPi, Vec3::UnitZ())) *
             Eigen::Quaterniond(Eigen::AngleAxisd(rng.U(-0.3, 0.3), Vec3::UnitX())) *
             rng.Turn(rng.U(0, 0.15));
        p0 = Vec3(rng.U(-0.4, 0.4), rng.U(0.35, 0.5), rng.U(0.77, 0.85));
        p1 = p0 + Vec3(rng.U(-0.02, 0.02), rng.U(-0.12, 0.0), rng.U(-0.06, 0.0));
        q1 = q0 * rng.Turn(rng.U(0, 0.2));
      }
      const double c0 = rng.U(0, 0.4), c1 = std::min(1.0, c0 + rng.U(0, 0.6));
      QuerySpec q;
      q.options = RandomOptions(
          rng, rng.P(0.85) ? MotionModel::kArticulated : MotionModel::kIndependent, 0.4);
      q.options.link_groups_min_links = 0;  // The 25-link hand with its groups.
      SetTimes(rng, &q, 5e3, 3e4);
      Pose x0, x1;
      ASSERT_EQ(js.Convert(hand.Frame(set, p0, q0, c0, q.pose0.utime), &x0), "");
      ASSERT_EQ(js.Convert(hand.Frame(set, p1, q1, c1, q.pose1.utime), &x1), "");
      ASSERT_EQ(ValidateAndNormalizePose(&x0, 25), "");
      ASSERT_EQ(ValidateAndNormalizePose(&x1, 25), "");
      q.pose0 = x0;
      q.pose1 = x1;
      q.note = rod_case ? "fingers close round a thin rod" : "fingers curl over a table edge";
      q.uniform_samples = 801;  // 25 links: the reference's time, not its rigour, is the cost.
      const Outcome out = suite.Run(sut, q, seed, i);
      for (const ContactRecord& c : out.result.contacts) {
        // A phalanx (not a carpal bone or the palm) made the contact.
        const std::string& name = js.skeleton().link(c.link.value()).name;
        const bool phalanx = name.find("PROXIMAL_EXT>") != std::string::npos ||
                             name.find("INTERMEDIATE_EXT>") != std::string::npos ||
                             name.find("DISTAL_EXT>") != std::string::npos;
        (c.object.value() == 1 ? rod_contacts : table_contacts) += phalanx;
      }
    }
  }
  suite.Finish(240);
  // The scenes do what they say: finger bones touch the edge and the rod.
  EXPECT_GT(table_contacts, static_cast<int64_t>(20 * testing::TestScale()));
  EXPECT_GT(rod_contacts, static_cast<int64_t>(20 * testing::TestScale()));
}

// ---------------------------------------------------------------------------
// Full bodies (issue 31) through the joint-set adapter, in the bundled
// rooms: the 81-link XR_META_body_tracking_full_body skeleton and the
// 67-link XR_FB_body_tracking one (no legs), both --hands full, calibrated
// on a CMU clip's first frame (its bone lengths), their joint frames built
// from the clip's 16 links with PROCEDURALLY ANIMATED fingers
// (mocap/full_body_frames.h) and converted by JointSkeleton::Convert. Each
// case: a random clip and frame, a step of 1 to 12 frames at 120 Hz (up to
// 0.1 s of motion), a random yaw and place in the Bitterli breakfast or grey
// & white room: standing on the floor near `sweptccd bench`'s spot, or (60 %)
// with a hand's knuckles a few centimetres off a random large furniture
// triangle 0.4-1.8 m above the floor, moving towards it; clear of the room at the start (up to 12
// placements), random finger curls at both ends. The room is cropped to the triangles whose boxes
// come within 0.3 m of the box of the pair's link segments (nothing farther can touch), and engine
// and dense reference see the same crop. Link groups on (the default from
// 32 links).

struct FullBodyRoom {
  const char* file;
  double floor;        // Y-up.
  Eigen::Vector2d at;  // (x, z) the avatars stand around (`sweptccd bench`'s placements).
};

const FullBodyRoom kRooms[2] = {{"bitterli_breakfast_room.ply.gz", -1.42, {-0.67, -1.9}},
                                {"bitterli_grey_white_room.ply.gz", 0.0, {2.3, -1.5}}};

const TriangleMesh& RoomMesh(int room) {
  static TriangleMesh meshes[2];
  if (meshes[room].num_triangles() == 0) {
    meshes[room] = LoadMeshFile(std::string(SWEPTCCD_DATA_DIR) + "/env/" + kRooms[room].file);
  }
  return meshes[room];
}

// The triangles of `mesh` whose boxes overlap [lo, hi].
TriangleMesh Crop(const TriangleMesh& mesh, const Vec3& lo, const Vec3& hi) {
  TriangleMesh out;
  for (size_t t = 0; t < mesh.num_triangles(); ++t) {
    Vec3 v[3];
    for (int k = 0; k < 3; ++k) v[k] = mesh.vertices[mesh.indices[3 * t + k]].cast<double>();
    const Vec3 tlo = v[0].cwiseMin(v[1]).cwiseMin(v[2]), thi = v[0].cwiseMax(v[1]).cwiseMax(v[2]);
    if (BoxesOverlap(lo, hi, tlo, thi)) AddTri(&out, v[0], v[1], v[2]);
  }
  return out;
}

// Where a hand reaches in a room: large triangles (20 cm^2 or more: a
// furniture surface, not a detail) 0.4-1.8 m above the floor within 1.5 m
// of the spot, with at most 300 triangles within 0.25 m (a finely meshed
// detail nearby costs the dense reference seconds a query).
struct ReachTarget {
  Vec3 centroid, normal;
};

const std::vector<ReachTarget>& ReachTargets(int room) {
  static std::vector<ReachTarget> targets[2];
  if (!targets[room].empty()) return targets[room];
  const TriangleMesh& mesh = RoomMesh(room);
  const FullBodyRoom& r = kRooms[room];
  const auto vertex = [&](size_t t, int c) -> Vec3 {
    return mesh.vertices[mesh.indices[3 * t + c]].cast<double>();
  };
  for (size_t t = 0; t < mesh.num_triangles(); ++t) {
    const Vec3 centroid = (vertex(t, 0) + vertex(t, 1) + vertex(t, 2)) / 3;
    const Vec3 n = (vertex(t, 1) - vertex(t, 0)).cross(vertex(t, 2) - vertex(t, 0));
    const double height = centroid.y() - r.floor;
    if (n.norm() < 2 * 20e-4 || height < 0.4 || height > 1.8 ||
        std::fabs(centroid.x() - r.at.x()) > 1.5 || std::fabs(centroid.z() - r.at.y()) > 1.5) {
      continue;
    }
    int close = 0;
    for (size_t u = 0; u < mesh.num_triangles() && close <= 300; ++u) {
      close += (vertex(u, 0) - centroid).norm() < 0.25;
    }
    if (close <= 300) targets[room].push_back({centroid, n.normalized()});
  }
  std::printf("[full bodies] room %d: %zu reach targets\n", room, targets[room].size());
  EXPECT_GE(targets[room].size(), 20u) << "room " << room;
  if (targets[room].empty())
    targets[room].push_back({Vec3(r.at.x(), r.floor + 1, r.at.y()), Vec3::UnitY()});
  return targets[room];
}

struct FullBodyClip {
  MocapClip clip;
  JointFrame first;  // Its first frame as meta-full-body joints (the calibration).
};

const FullBodyClip& FullBodyClipAt(int i) {
  static const char* kFiles[3] = {"cmu_13_10_jump_grab_reach_tiptoe.bvh.gz", "boxing_toes.bvh.gz",
                                  "cmu_02_01_walk.bvh.gz"};
  static std::unique_ptr<FullBodyClip> clips[3];
  if (!clips[i]) {
    clips[i] = std::make_unique<FullBodyClip>();
    MocapImportOptions mo;
    mo.up_axis = 'y';
    clips[i]->clip = ImportBvhFile(std::string(SWEPTCCD_DATA_DIR) + "/mocap/" + kFiles[i], mo);
    const full_body::FrameBuilder fb(FindJointSet("meta-full-body"), clips[i]->clip.skeleton);
    clips[i]->first = fb.Build(clips[i]->clip.poses[0], 0, 0);
  }
  return *clips[i];
}

// The first 70 joints of a meta-full-body frame are XR_FB_body_tracking's,
// same order and meaning (docs/SKELETONS.md).
JointFrame AsFbBody(JointFrame f) {
  f.joints.resize(FindJointSet("fb-body").num_joints());
  return f;
}

void FullBodySuite(const std::string& set_id, int links, uint64_t seed0, int scenes,
                   int64_t min_queries) {
  Suite suite(set_id + " (" + std::to_string(links) + " links) in the bundled rooms");
  const JointSet& meta = FindJointSet("meta-full-body");
  const JointSet& set = FindJointSet(set_id);
  const bool fb = set_id == "fb-body";
  int64_t finger_contacts = 0, refused = 0, contacts = 0;
  for (int scene_i = 0; scene_i < ScaledCount(scenes); ++scene_i) {
    const uint64_t seed = seed0 + scene_i;
    Rng rng(seed);
    const int clip_i = rng.I(3), room = rng.I(2);
    const FullBodyClip& fc = FullBodyClipAt(clip_i);
    JointSkeletonOptions so;
    const JointFrame cal = fb ? AsFbBody(fc.first) : fc.first;
    so.calibration = &cal;
    so.length_tolerance_m = 0.05;  // The clip's clavicles move a little (as the bench).
    so.length_tolerance_fraction = 0.25;
    const JointSkeleton js = JointSkeleton::Build(set, so);
    ASSERT_EQ(js.skeleton().num_links(), links);
    const full_body::FrameBuilder builder(meta, fc.clip.skeleton);
    const std::vector<Pose>& poses = fc.clip.poses;
    for (int i = 0; i < 6; ++i) {
      // A pair of the clip, turned about the vertical and stood near the
      // room's spot (its lowest point 0-3 cm above the floor at the start).
      const int step = 1 + rng.I(12);
      const int k = rng.I(static_cast<int>(poses.size()) - step);
      QuerySpec q;
      q.options = RandomOptions(
          rng, rng.P(0.85) ? MotionModel::kArticulated : MotionModel::kIndependent, 0.3);
      SetTimes(rng, &q, 8e3 * step, 8.4e3 * step);
      const double curls[4] = {rng.U(0, 1), rng.U(0, 1), rng.U(0, 1), rng.U(0, 1)};
      const bool reach = rng.P(0.6);
      // Up to 12 placements until the start pose touches nothing (a body
      // deep inside a dense mesh at s = 0 costs the reference seconds;
      // starting inside is the InitiallyColliding suite's).
      std::unique_ptr<SceneUnderTest> sut;
      Pose x0, x1;
      bool refused_frames = false;
      for (int attempt = 0; attempt < 12; ++attempt) {
        Pose m0 = poses[k], m1 = poses[k + step];
        Eigen::Quaterniond yaw(Eigen::AngleAxisd(rng.U(0, 2 * kPi), Vec3::UnitY()));
        const Vec3 root = m0.links[0].p;
        double lowest = 1e300;
        for (int l = 0; l < fc.clip.skeleton.num_links(); ++l) {
          const Link& link = fc.clip.skeleton.link(l);
          for (const Vec3& e : {link.a_L, link.b_L}) {
            lowest = std::min(lowest,
                              (yaw * (m0.links[l].p + m0.links[l].q * e - root)).y() - link.radius);
          }
        }
        const FullBodyRoom& r = kRooms[room];
        Vec3 place(r.at.x() + rng.U(-0.8, 0.8), r.floor - lowest + rng.U(0.01, 0.05),
                   r.at.y() + rng.U(-0.8, 0.8));
        Vec3 approach = Vec3::Zero();  // The body's move over the pair, on top of the clip's.
        if (reach) {
          // A hand reaching for the furniture: the hand link's far end (the
          // knuckles) 2-12 cm off a large triangle 0.4-1.8 m above the floor near
          // the spot, on a random side of it, the body turned to stand back
          // on that side (the floor wherever that puts it) and moving 3-15 cm
          // towards it over the pair.
          const std::vector<ReachTarget>& targets = ReachTargets(room);
          const int hand = fc.clip.skeleton.FindLink(rng.P(0.5) ? "hand_l" : "hand_r");
          const Vec3 knuckles =
              m0.links[hand].p + m0.links[hand].q * fc.clip.skeleton.link(hand).b_L - root;
          // A body with legs stays on the floor: a target at its standing
          // knuckles' height (within 20 cm), or none this time.
          std::vector<const ReachTarget*> fit;
          for (const ReachTarget& t : targets) {
            if (fb || std::fabs(t.centroid.y() - (place.y() + knuckles.y())) < 0.2) {
              fit.push_back(&t);
            }
          }
          if (fit.empty()) continue;
          const ReachTarget& t = *fit[rng.I(static_cast<int>(fit.size()))];
          const Vec3 side = t.normal * (rng.P(0.5) ? 1.0 : -1.0);
          // Yaw about +Y taking the root-to-knuckles direction onto -side
          // (horizontally), when both have a horizontal direction.
          const double hk = std::hypot(knuckles.x(), knuckles.z());
          const double hs = std::hypot(side.x(), side.z());
          if (hk > 0.05 && hs > 0.3) {
            yaw = Eigen::AngleAxisd(
                std::atan2(-side.x(), -side.z()) - std::atan2(knuckles.x(), knuckles.z()),
                Vec3::UnitY());
          }
          const double stand_y = place.y();
          place = t.centroid + side * rng.U(0.02, 0.12) - yaw * knuckles;
          approach = -side * rng.U(0.03, 0.15);
          if (!fb) {
            place.y() = stand_y;
            approach.y() = 0;
          }
        }
        for (Pose* m : {&m0, &m1}) {
          for (LinkPose& x : m->links) {
            x.p = place + (m == &m1 ? approach : Vec3::Zero()) + yaw * (x.p - root);
            x.q = yaw * x.q;
          }
        }
        m0.utime = q.pose0.utime;
        m1.utime = q.pose1.utime;
        JointFrame f0 = builder.Build(m0, curls[0], curls[1]);
        JointFrame f1 = builder.Build(m1, curls[2], curls[3]);
        if (fb) {
          f0 = AsFbBody(f0);
          f1 = AsFbBody(f1);
        }
        refused_frames = !js.Convert(f0, &x0).empty() || !js.Convert(f1, &x1).empty();
        if (refused_frames) break;  // The frames, not the place, are beyond the tolerance.
        // The room within 0.3 m of the box of the pair's link segments
        // (both motion models, 33 times each); no link reaches farther.
        const RefMotion motion(js.skeleton(), x0, x1, true), motion_i(js.skeleton(), x0, x1, false);
        Vec3 lo = Vec3::Constant(1e300), hi = Vec3::Constant(-1e300);
        std::vector<Vec3> A(links), B(links);
        for (const RefMotion* mo : {&motion, &motion_i}) {
          for (int j = 0; j <= 32; ++j) {
            mo->Segments(j / 32.0, A.data(), B.data());
            for (int l = 0; l < links; ++l) {
              lo = lo.cwiseMin(A[l]).cwiseMin(B[l]);
              hi = hi.cwiseMax(A[l]).cwiseMax(B[l]);
            }
          }
        }
        Scene scene;
        scene.skeleton = js.skeleton();
        scene.meshes = {Crop(RoomMesh(room), lo.array() - 0.3, hi.array() + 0.3)};
        if (scene.meshes[0].num_triangles() == 0) continue;  // Nothing within reach.
        sut = std::make_unique<SceneUnderTest>(std::move(scene));
        Pose still = x0;
        still.utime = x0.utime + 1;
        if (!sut->engine().Query(x0, still, QueryOptions()).contact) break;
        sut.reset();
      }
      if (refused_frames) {
        ++refused;  // Beyond the length tolerance: the adapter's refusal, not a query.
        continue;
      }
      // No clear placement with the room within reach in 12 tries (Finish
      // counts the queries against its minimum).
      if (!sut) continue;
      ASSERT_EQ(ValidateAndNormalizePose(&x0, links), "");
      ASSERT_EQ(ValidateAndNormalizePose(&x1, links), "");
      q.pose0 = x0;
      q.pose1 = x1;
      q.note = set_id + " in room " + std::to_string(room) + ", clip " + std::to_string(clip_i) +
               " frame " + std::to_string(k) + " step " + std::to_string(step);
      q.uniform_samples = 301;  // Many links and triangles: the reference's time is the cost.
      const Outcome out = suite.Run(*sut, q, seed, i);
      contacts += out.result.contact;
      for (const ContactRecord& c : out.result.contacts) {
        finger_contacts +=
            js.skeleton().link(c.link.value()).name.find("HAND_") != std::string::npos;
      }
    }
  }
  std::printf("[%s] %lld refused pairs, %lld contacts, %lld witnesses on hand links\n",
              set_id.c_str(), static_cast<long long>(refused), static_cast<long long>(contacts),
              static_cast<long long>(finger_contacts));
  suite.Finish(min_queries);
  EXPECT_LE(refused, static_cast<int64_t>(suite.queries() / 10)) << "the adapter refused too many";
  // The cases do what they say: the room is touched, by hands among others.
  EXPECT_GE(contacts, testing::ScaledMinimum(5)) << set_id;
  EXPECT_GE(finger_contacts, testing::ScaledMinimum(2)) << set_id;
}

TEST(CcdRandomTest, MetaFullBody81LinksInBundledRooms) {
  FullBodySuite("meta-full-body", 81, 0xFB810000, 12, 36);
}

TEST(CcdRandomTest, FbBody67LinksInBundledRooms) {
  FullBodySuite("fb-body", 67, 0xFB670000, 10, 24);
}

// ---------------------------------------------------------------------------
// Dense meshes (thousands of triangles): candidate lists overflow their cap
// and the engine re-queries its BVHs; the reference still checks every
// triangle.

// A (rows + 1) x (cols + 1) vertex grid, each cell split into two triangles;
// vertex(i, j) places grid point (i, j) (stored as floats, like the loaders).
template <class VertexAt>
TriangleMesh GridMesh(int rows, int cols, VertexAt vertex) {
  TriangleMesh mesh;
  for (int i = 0; i <= rows; ++i) {
    for (int j = 0; j <= cols; ++j) mesh.vertices.push_back(F(vertex(i, j)));
  }
  for (int i = 0; i < rows; ++i) {
    for (int j = 0; j < cols; ++j) {
      const uint32_t v00 = i * (cols + 1) + j, v10 = v00 + cols + 1;
      mesh.indices.insert(mesh.indices.end(), {v00, v10, v10 + 1, v00, v10 + 1, v00 + 1});
    }
  }
  return mesh;
}

TEST(CcdRandomTest, DenseMeshes) {
  Suite suite("dense meshes");
  for (int scene_i = 0; scene_i < ScaledCount(10); ++scene_i) {
    const uint64_t seed = 0xADA0000 + scene_i;
    Rng rng(seed);
    const Rig rig = RandomRig(rng, 1 + rng.I(6), 1 + rng.I(4), 0.15);
    Scene scene;
    scene.skeleton = rig.skeleton;
    // A bumpy height field, 30 x 30 cells (1800 triangles) over 3 x 3 m.
    const int cells = 30;
    const double fx = rng.U(1, 4), fy = rng.U(1, 4), amp = rng.U(0.02, 0.15);
    const TriangleMesh terrain = GridMesh(cells, cells, [&](int i, int j) {
      const double x = -1.5 + 3.0 * i / cells, y = -1.5 + 3.0 * j / cells;
      return Vec3(x, y, amp * std::sin(fx * x) * std::cos(fy * y));
    });
    // A UV sphere (16 x 32: 1024 triangles, degenerate ones at the poles kept).
    const Vec3 centre(rng.U(-0.8, 0.8), rng.U(-0.8, 0.8), rng.U(0.4, 0.8));
    const double radius = rng.U(0.2, 0.45);
    const int rings = 16, segs = 32;
    const TriangleMesh ball = GridMesh(rings, segs, [&](int i, int j) {
      const double th = kPi * i / rings, ph = 2 * kPi * j / segs;
      return Vec3(centre + radius * Vec3(std::sin(th) * std::cos(ph), std::sin(th) * std::sin(ph),
                                         std::cos(th)));
    });
    scene.meshes = {terrain, ball};
    SceneUnderTest sut(std::move(scene));
    for (int i = 0; i < 20; ++i) {
      QuerySpec q = RandomMotion(rng, rig, sut, 0.6, 1.5, kPi, 2.0, 0.3, rng.P(0.8),
                                 Vec3(centre.x() * rng.U(0, 1), centre.y() * rng.U(0, 1), 0.3));
      q.note = "dense meshes";
      q.uniform_samples = 1001;  // The brute force is costly here.
      suite.Run(sut, q, seed, i);
    }
  }
  suite.Finish(200);
}

// ---------------------------------------------------------------------------
// Collision filters over three objects.

TEST(CcdRandomTest, CollisionFilters) {
  Suite suite("collision filters");
  for (int scene_i = 0; scene_i < ScaledCount(30); ++scene_i) {
    const uint64_t seed = 0xAAA0000 + scene_i;
    Rng rng(seed);
    const Rig rig = RandomRig(rng, 2 + rng.I(9), 1 + rng.I(5), 0.1);
    const int n = rig.skeleton.num_links();
    Scene scene;
    scene.skeleton = rig.skeleton;
    for (int o = 0; o < 3; ++o) {
      TriangleMesh mesh;
      AddSoup(rng, &mesh, 15 + rng.I(45), 1.5, 0.05, 0.4);
      scene.meshes.push_back(mesh);
    }
    const int rules = 1 + rng.I(6);
    for (int k = 0; k < rules; ++k) {
      scene.ignored.push_back({rng.P(0.15) ? -1 : rng.I(n), rng.P(0.15) ? -1 : rng.I(3)});
    }
    SceneUnderTest sut(std::move(scene));
    for (int i = 0; i < 20; ++i) {
      QuerySpec q = RandomMotion(rng, rig, sut, 0.8, 3.0, kPi, 2.5, 0.4, rng.P(0.85));
      q.note = "filtered";
      suite.Run(sut, q, seed, i);
    }
  }
  suite.Finish(600);
}

// ---------------------------------------------------------------------------
// Determinism, work limits, filters.

TEST(CcdRandomTest, SameAnswerTwice) {
  int compared = 0;
  for (int scene_i = 0; scene_i < ScaledCount(10); ++scene_i) {
    const uint64_t seed = 0xABA0000 + scene_i;
    Rng rng(seed);
    const Rig rig = RandomRig(rng, 1 + rng.I(16), 1 + rng.I(8), 0.1);
    Scene scene;
    scene.skeleton = rig.skeleton;
    TriangleMesh mesh;
    AddSoup(rng, &mesh, 30 + rng.I(100), 1.6, 0.05, 0.4);
    scene.meshes.push_back(mesh);
    SceneUnderTest sut(scene);
    SceneUnderTest twin(scene);  // A second engine over a copy.
    for (int i = 0; i < 20; ++i) {
      const QuerySpec q = RandomMotion(rng, rig, sut, 0.8, 3.0, kPi, 2.5, 0.5, rng.P(0.8));
      const QueryResult a = sut.engine().Query(q.pose0, q.pose1, q.options);
      const QueryResult b = sut.engine().Query(q.pose0, q.pose1, q.options);
      const QueryResult c = twin.engine().Query(q.pose0, q.pose1, q.options);
      std::string why;
      EXPECT_TRUE(SameResult(a, b, &why)) << "seed " << seed << " query " << i << ": " << why;
      EXPECT_TRUE(SameResult(a, c, &why)) << "seed " << seed << " query " << i << ": " << why;
      EXPECT_EQ(a.stats.intervals, b.stats.intervals);
      EXPECT_EQ(a.stats.triangle_tests, c.stats.triangle_tests);
      ++compared;
    }
  }
  std::printf("[determinism] %d queries answered three times\n", compared);
}

TEST(CcdRandomTest, SmallWorkLimitIsUndecidedButKeepsG1) {
  Suite suite("small max_intervals");
  int touching = 0, undecided_touching = 0;
  for (int scene_i = 0; scene_i < ScaledCount(20); ++scene_i) {
    const uint64_t seed = 0xACA0000 + scene_i;
    Rng rng(seed);
    const Rig rig = RandomRig(rng, 1 + rng.I(10), 1 + rng.I(6), 0.1);
    Scene scene;
    scene.skeleton = rig.skeleton;
    TriangleMesh mesh;
    AddSoup(rng, &mesh, 40 + rng.I(80), 1.5, 0.05, 0.4);
    scene.meshes.push_back(mesh);
    SceneUnderTest sut(std::move(scene));
    for (int i = 0; i < 10; ++i) {
      QuerySpec q = RandomMotion(rng, rig, sut, 0.8, 3.0, kPi, 2.5, 0.5, true);
      q.options.max_intervals = 1 + rng.I(4);
      q.options.eps_s = 1e-5;
      q.pose1.utime = q.pose0.utime + 1'000'000;  // 1 s: brackets of 1e-5 need ~17 halvings.
      q.note = "max_intervals " + std::to_string(q.options.max_intervals);
      const Outcome o = suite.Run(sut, q, seed, i);
      if (o.ref_touches) {
        ++touching;
        undecided_touching += o.result.contact && o.result.undecided;
        EXPECT_TRUE(o.result.contact && o.result.undecided)
            << "seed " << seed << " query " << i << ": the reference touches at s "
            << o.ref_first_touch << ", expected contact + undecided, got "
            << DescribeResult(o.result);
      }
    }
  }
  std::printf("[small max_intervals] %d queries touch, %d answered contact+undecided\n", touching,
              undecided_touching);
  EXPECT_GT(touching, testing::ScaledMinimum(50));
  suite.Finish(200, /*limit_undecided=*/false);
}

// A query of one of the small regression scenes below on the backend under
// test. With the GPU, the culler must have been asked (unless the link touched
// at s = 0, answered before any swept test) and the CPU engine must give the
// same answer.
QueryResult QueryOnBackend(const Skeleton& sk, const Environment& env, const Pose& p0,
                           const Pose& p1) {
  CcdEngine engine(sk, env);
  testing::AttachBackend(&engine);
  const QueryResult r = engine.Query(p0, p1, QueryOptions());
  if (std::string(testing::BackendName()) == "gpu") {
    EXPECT_TRUE(engine.culler() != nullptr);
    if (!r.initially_colliding) {
      EXPECT_GT(r.stats.cull_round_trips, 0) << "the GPU never ran";
    }
    const CcdEngine cpu(sk, env);
    EXPECT_TRUE(testing::SameAnswer(r, cpu.Query(p0, p1, QueryOptions())))
        << "GPU and CPU answers differ";
  }
  return r;
}

TEST(CcdRandomTest, DefaultFilterIgnoresNothing) {
  // A default-constructed CollisionFilter must not make every link skip.
  Link l;
  l.name = "ball";
  l.radius = 0.05;
  const Skeleton sk = Skeleton::FromLinks("ball", {l}, "ccd_random_test");
  TriangleMesh mesh;
  AddTri(&mesh, Vec3(-1, -1, 0), Vec3(1, -1, 0), Vec3(0, 1, 0));
  Environment env;
  env.AddMesh(mesh, "tri");
  LinkPose x0, x1;
  x0.p = Vec3(0, 0, 1);
  x1.p = Vec3(0, 0, -1);
  // Touches at s = 0.475 (z = 0.05); 1 s with eps 1e-4 s: a bracket <= 1e-4 wide.
  const QueryResult r = QueryOnBackend(sk, env, MakePose(0, {x0}), MakePose(1'000'000, {x1}));
  ASSERT_TRUE(r.contact);
  EXPECT_LE(r.s_lo, 0.475);
  EXPECT_GE(r.s_lo, 0.475 - 1e-3);
  EXPECT_LE(r.s_hi - r.s_lo, 1e-4 + 1e-12);
}

// Regression, G2 with epoch utimes (LCM: microseconds since 1970, ~1.7e15,
// where a double is 0.25 us coarse). The engine compared
// (utime0 + s1 dt) - (utime0 + s0 dt) with eps: the rounding of the two large
// times accepted a bracket 100.109375 us wide for eps = 100 us. The width is
// (s1 - s0) * dt.
TEST(CcdRandomTest, EpochUtimesKeepG2) {
  Link l;
  l.name = "ball";
  l.radius = 0.05;
  const Skeleton sk = Skeleton::FromLinks("ball", {l}, "ccd_random_test");
  TriangleMesh mesh;
  AddTri(&mesh, Vec3(-1, -1, -0.06), Vec3(1, -1, -0.06), Vec3(0, 1, -0.06));
  Environment env;
  env.AddMesh(mesh, "tri");
  LinkPose x0, x1;
  x0.p = Vec3(0, 0, 1);
  x1.p = Vec3(0, 0, -1);  // Touches at s = 0.505.
  const int64_t utime0 = 1700087249186542, dt = 6407;
  const QueryResult r =
      QueryOnBackend(sk, env, MakePose(utime0, {x0}), MakePose(utime0 + dt, {x1}));
  ASSERT_TRUE(r.contact);
  EXPECT_FALSE(r.undecided);
  EXPECT_LE((r.s_hi - r.s_lo) * dt, 100.0) << "bracket [" << r.s_lo << ", " << r.s_hi << "] is "
                                           << (r.s_hi - r.s_lo) * dt << " us wide, eps is 100 us";
}

// Regression, core/distance.h: ClosestPointOnTriangle is off by up to ~5e-7 m
// on a 1 m sliver of height 3.8e-6 m (ill-conditioned barycentrics), above the
// environment's coordinate tolerance (1.2e-7 m here). A sphere of radius 1e-7
// lying on the sliver (distance 0) is then answered `free`: a miss. Radii this
// small are legal (SPEC: radius > 0) but unusual; with radius >> 1e-6 the
// error enters only to second order (e^2 / 2r) and cannot cause a miss.
TEST(CcdRandomTest, TinySphereOnSliverTriangle) {
  TriangleMesh mesh;
  mesh.vertices = {Eigen::Vector3f(0, 0, 0), Eigen::Vector3f(1, 0, 0),
                   Eigen::Vector3f(0.5f, std::ldexp(1.0f, -18), 0)};
  mesh.indices = {0, 1, 2};
  Environment env;
  env.AddMesh(mesh, "sliver");
  Link l;
  l.name = "ball";
  l.radius = 1e-7;
  const Skeleton sk = Skeleton::FromLinks("ball", {l}, "ccd_random_test");
  LinkPose x;
  x.p = Vec3(0.201, 5.7506561279296873e-07, 0);  // Inside the sliver, on its plane.
  const Vec3 a(0, 0, 0), b(1, 0, 0), c(0.5, std::ldexp(1.0, -18), 0);
  // The point is inside: on the same side of all three edges.
  ASSERT_GT((b - a).cross(x.p - a).z(), 0);
  ASSERT_GT((c - b).cross(x.p - b).z(), 0);
  ASSERT_GT((a - c).cross(x.p - c).z(), 0);
  const QueryResult r = QueryOnBackend(sk, env, MakePose(0, {x}), MakePose(1000, {x}));
  EXPECT_TRUE(r.contact && r.initially_colliding)
      << "a sphere lying on the triangle is not seen; SegmentTriangleDistance says "
      << SegmentTriangleDistance(x.p, x.p, a, b, c).distance << " (exact: 0), tolerance "
      << env.coordinate_tolerance();
}

}  // namespace
}  // namespace sweptccd
