// Randomised tests for core/motion.h against brute-force twins written here
// from SPEC section 3: slerp through the axis-angle form
// q0 * exp(s * log(conj(q0) * q1')), the articulated model composed root-down
// with rotation matrices, all in long double.

#include "core/avatar/motion.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <limits>
#include <numeric>
#include <random>
#include <sstream>
#include <string>
#include <vector>

#include "core/avatar/pose.h"
#include "core/avatar/skeleton.h"
#include "core/geometry/interval.h"
#include "tests/common/test_scale.h"
#include "tests/common/twin_motion.h"

namespace sweptccd {
namespace {

using namespace sweptccd::twin;  // NOLINT: the twin's small vocabulary (QL, Mul, ...).

constexpr double kPi = 3.14159265358979323846;

LD MaxDiff(const Mat3L& a, const Mat3L& b) { return (a - b).cwiseAbs().maxCoeff(); }
LD MaxDiff(const Vec3L& a, const Vec3L& b) { return (a - b).cwiseAbs().maxCoeff(); }

// ---------------------------------------------------------------------------
// Random quaternions, skeletons and poses.

Eigen::Quaterniond RandomUnitQuat(std::mt19937_64& g) {
  std::normal_distribution<double> n(0, 1);
  Eigen::Quaterniond q(n(g), n(g), n(g), n(g));
  return q.normalized();
}

Eigen::Vector3d RandomUnitVector(std::mt19937_64& g) {
  std::normal_distribution<double> n(0, 1);
  Eigen::Vector3d v(n(g), n(g), n(g));
  return v.normalized();
}

// The bits of a double, for bit-for-bit comparisons.
uint64_t Bits(double v) {
  uint64_t b;
  std::memcpy(&b, &v, sizeof b);
  return b;
}

double LogUniform(std::mt19937_64& g, double lo_exp, double hi_exp) {
  return std::pow(10.0, std::uniform_real_distribution<double>(lo_exp, hi_exp)(g));
}

Eigen::Quaterniond AxisAngleQuat(const Eigen::Vector3d& axis, double angle) {
  return Eigen::Quaterniond(Eigen::AngleAxisd(angle, axis));
}

// A second orientation related to q0 in one of several ways: unrelated,
// nearly the same, nearly 180 degrees away, exactly 180 degrees away about a
// random axis, the same rotation with the opposite sign, or a random sign.
// `min_offset` keeps |dot| away from 0 for twins whose sign decision must
// agree with the core's.
Eigen::Quaterniond RelatedQuat(std::mt19937_64& g, const Eigen::Quaterniond& q0,
                               double min_offset_exp) {
  std::uniform_int_distribution<int> kind(0, 5);
  Eigen::Quaterniond q;
  switch (kind(g)) {
    case 0:
      q = RandomUnitQuat(g);
      break;
    case 1:  // Nearly the same (angles from 1e-12 to 1e-2 rad: the nlerp fallback and beyond).
      q = q0 * AxisAngleQuat(RandomUnitVector(g), LogUniform(g, -12, -2));
      break;
    case 2:  // Nearly 180 degrees apart: dot ~ 0.
      q = q0 * AxisAngleQuat(RandomUnitVector(g), kPi - LogUniform(g, min_offset_exp, -1));
      break;
    case 3:  // Just over 180 degrees: the shortest arc goes the other way.
      q = q0 * AxisAngleQuat(RandomUnitVector(g), kPi + LogUniform(g, min_offset_exp, -1));
      break;
    case 4:  // The same rotation, written with the opposite sign.
      q.coeffs() = -q0.coeffs();
      break;
    default:
      q = q0 *
          AxisAngleQuat(RandomUnitVector(g), std::uniform_real_distribution<double>(0, 2 * kPi)(g));
      break;
  }
  if (std::uniform_int_distribution<int>(0, 1)(g)) q.coeffs() = -q.coeffs();
  return q.normalized();
}

enum class Shape { kRandomTree, kChain, kStar };

struct Rig {
  Skeleton skeleton;
  Pose pose0, pose1;
};

// Parent indices of a random tree of n links, then relabelled by a random
// permutation so that children may come before their parents.
std::vector<int> RandomParents(std::mt19937_64& g, int n, Shape shape) {
  std::vector<int> parent(n, -1);
  for (int i = 1; i < n; ++i) {
    switch (shape) {
      case Shape::kChain:
        parent[i] = i - 1;
        break;
      case Shape::kStar:
        parent[i] = 0;
        break;
      default:
        parent[i] = std::uniform_int_distribution<int>(0, i - 1)(g);
        break;
    }
  }
  std::vector<int> perm(n);  // perm[old] = new index.
  std::iota(perm.begin(), perm.end(), 0);
  std::shuffle(perm.begin(), perm.end(), g);
  std::vector<int> out(n, -1);
  for (int i = 0; i < n; ++i) out[perm[i]] = parent[i] < 0 ? -1 : perm[parent[i]];
  return out;
}

Skeleton MakeSkeleton(std::mt19937_64& g, const std::vector<int>& parent, bool connected) {
  std::uniform_real_distribution<double> coord(-0.5, 0.5), radius(0.01, 0.2);
  std::vector<Link> links(parent.size());
  for (size_t i = 0; i < parent.size(); ++i) {
    links[i].name = "link" + std::to_string(i);
    links[i].parent = parent[i];
    links[i].a_L =
        connected ? Eigen::Vector3d::Zero() : Eigen::Vector3d(coord(g), coord(g), coord(g));
    links[i].b_L = Eigen::Vector3d(coord(g), coord(g), coord(g));
    if (std::uniform_int_distribution<int>(0, 9)(g) == 0) links[i].b_L = links[i].a_L;  // A sphere.
    links[i].radius = radius(g);
  }
  return Skeleton::FromLinks("random", std::move(links), "random skeleton");
}

// World poses by forward kinematics: each child's origin sits at its parent's
// b end (when `connected`) or at a random offset in the parent frame.
Pose FkPose(const Skeleton& skel, const std::vector<Eigen::Quaterniond>& rel,
            const Eigen::Vector3d& root_p, const Eigen::Quaterniond& root_q,
            const std::vector<Eigen::Vector3d>& offsets) {
  Pose pose;
  pose.links.resize(skel.num_links());
  for (int i : skel.topological_order()) {
    const int k = skel.link(i).parent;
    if (k < 0) {
      pose.links[i].p = root_p;
      pose.links[i].q = root_q;
    } else {
      const LinkPose& X = pose.links[k];
      pose.links[i].q = (X.q * rel[i]).normalized();
      pose.links[i].p = X.p + X.q.toRotationMatrix() * offsets[i];
    }
  }
  return pose;
}

// A random rig: skeleton of 1-30 links (chains up to depth 20), and two poses.
// With `connected`, both poses are built by FK with the child origins at the
// parent's b end. `min_offset_exp` bounds how close to 180 degrees related
// rotations get (see RelatedQuat).
Rig MakeRig(std::mt19937_64& g, bool connected, double min_offset_exp) {
  std::uniform_int_distribution<int> shape_pick(0, 3);
  const int shape_kind = shape_pick(g);
  const Shape shape = shape_kind == 0   ? Shape::kChain
                      : shape_kind == 1 ? Shape::kStar
                                        : Shape::kRandomTree;
  const int n = shape == Shape::kChain ? std::uniform_int_distribution<int>(1, 20)(g)
                                       : std::uniform_int_distribution<int>(1, 30)(g);
  Rig rig;
  rig.skeleton = MakeSkeleton(g, RandomParents(g, n, shape), connected);
  const Skeleton& skel = rig.skeleton;
  // Translation scale: small, human, or large.
  const double scale =
      std::vector<double>{0.01, 1.0, 50.0, 1000.0}[std::uniform_int_distribution<int>(0, 3)(g)];
  std::uniform_real_distribution<double> coord(-1, 1);
  auto random_vec = [&](double sc) -> Eigen::Vector3d {
    return Eigen::Vector3d(coord(g), coord(g), coord(g)) * sc;
  };
  const bool near_motion = std::uniform_int_distribution<int>(0, 2)(g) == 0;
  const double travel = near_motion ? LogUniform(g, -9, -2) : scale;
  if (connected) {
    std::vector<Eigen::Vector3d> offsets(n);
    std::vector<Eigen::Quaterniond> rel0(n), rel1(n);
    for (int i = 0; i < n; ++i) {
      const int k = skel.link(i).parent;
      offsets[i] = k < 0 ? Eigen::Vector3d::Zero() : skel.link(k).b_L;
      rel0[i] = RandomUnitQuat(g);
      rel1[i] = RelatedQuat(g, rel0[i], min_offset_exp);
    }
    const Eigen::Vector3d p0 = random_vec(scale);
    const Eigen::Quaterniond q0 = RandomUnitQuat(g);
    rig.pose0 = FkPose(skel, rel0, p0, q0, offsets);
    rig.pose1 =
        FkPose(skel, rel1, p0 + random_vec(travel), RelatedQuat(g, q0, min_offset_exp), offsets);
  } else {
    rig.pose0.links.resize(n);
    rig.pose1.links.resize(n);
    for (int i = 0; i < n; ++i) {
      rig.pose0.links[i].p = random_vec(scale);
      rig.pose0.links[i].q = RandomUnitQuat(g);
      rig.pose1.links[i].p = rig.pose0.links[i].p + random_vec(travel);
      rig.pose1.links[i].q = RelatedQuat(g, rig.pose0.links[i].q, min_offset_exp);
    }
  }
  rig.pose0.utime = 1000000;
  rig.pose1.utime = 1011111;
  EXPECT_EQ(ValidateAndNormalizePose(&rig.pose0, n), "");
  EXPECT_EQ(ValidateAndNormalizePose(&rig.pose1, n), "");
  return rig;
}

MotionModel RandomModel(std::mt19937_64& g) {
  return std::uniform_int_distribution<int>(0, 1)(g) ? MotionModel::kArticulated
                                                     : MotionModel::kIndependent;
}

Mat3L RotOf(const Eigen::Quaterniond& q) { return q.toRotationMatrix().cast<LD>(); }

std::string RigSummary(const Rig& rig, MotionModel model) {
  std::ostringstream s;
  s << rig.skeleton.num_links() << " links, model " << MotionModelName(model);
  return s.str();
}

// ---------------------------------------------------------------------------
// Slerp and SlerpAngle.

// internal::DotSign against answers known exactly and against a binary128
// twin: a quaternion and itself turned by exactly 180 degrees (q times a unit
// axis quaternion: components permuted and negated, no rounding) have a dot
// of exactly 0; moving one component of the turned one by one ulp makes the
// exact dot that component's step times the other's matching component.
TEST(MotionTest, DotSignIsExactNearZero) {
  std::mt19937_64 g(0x40710D07);
  int zero = 0, by_ulp = 0, rounded_wrong = 0, by_twin = 0;
  for (int c = 0; c < 20000; ++c) {
    const Eigen::Quaterniond q = RandomUnitQuat(g);
    const Eigen::Quaterniond axes[3] = {{0, 1, 0, 0}, {0, 0, 1, 0}, {0, 0, 0, 1}};
    const Eigen::Quaterniond t = q * axes[c % 3];
    double a[4], b[4];
    for (int k = 0; k < 4; ++k) {
      a[k] = q.coeffs()[k];
      b[k] = t.coeffs()[k];
    }
    ASSERT_EQ(internal::DotSign(a, b), 0) << "case " << c;
    ++zero;
    const int k = std::uniform_int_distribution<int>(0, 3)(g);
    if (a[k] == 0 || b[k] == 0) continue;
    const double step_to = (g() & 1) ? 2.0 : -2.0;
    b[k] = std::nextafter(b[k], step_to);
    const int want = (a[k] > 0) == (step_to > 0) ? 1 : -1;
    ASSERT_EQ(internal::DotSign(a, b), want) << "case " << c;
    ++by_ulp;
    // The plain rounded sum gets many of these wrong: the reason for DotSign.
    const double rounded = a[0] * b[0] + a[1] * b[1] + a[2] * b[2] + a[3] * b[3];
    rounded_wrong += (rounded > 0 ? 1 : rounded < 0 ? -1 : 0) != want;
  }
  // Random pairs, near-orthogonal ones among them, against __float128 (the
  // products exact, the sum rounded at 2^-113): where the twin's sum is far
  // above its own rounding, the signs agree.
  for (int c = 0; c < 20000; ++c) {
    const Eigen::Vector4d u = RandomUnitQuat(g).coeffs();
    Eigen::Vector4d v = RandomUnitQuat(g).coeffs();
    if (c % 2 == 0) v = (v - v.dot(u) * u).normalized();  // Dot near 0.
    const int want = Binary128DotSign(u.data(), v.data());
    if (want == 0) continue;  // Within the twin's own rounding.
    ASSERT_EQ(internal::DotSign(u.data(), v.data()), want) << "case " << c;
    ++by_twin;
  }
  // Components spanning every magnitude down to subnormals (found by a
  // review: products that underflow broke the expansion), as validation
  // leaves them: normalised, then tiny components flushed to 0. Against
  // the binary128 twin, which holds these products exactly.
  int tiny_cases = 0;
  for (int c = 0; c < 20000; ++c) {
    Pose p;
    p.links.resize(2);
    for (LinkPose& l : p.links) {
      for (int k = 0; k < 4; ++k) {
        const double e = std::uniform_real_distribution<double>(-1100, 1)(g);
        const double sign = (g() & 1) ? 1.0 : -1.0;
        l.q.coeffs()[k] = (g() % 3 == 0) ? sign * std::ldexp(1.0, static_cast<int>(e))
                                         : sign * std::uniform_real_distribution<double>(0, 1)(g);
      }
      if (l.q.coeffs().cwiseAbs().maxCoeff() < 1e-5) l.q.coeffs()[c % 4] = 1;
    }
    // The second as the first turned by 180 degrees and nudged, half the time.
    if (c % 2 == 0) {
      p.links[1].q = p.links[0].q * Eigen::Quaterniond(0, 0, 0, 1);
      const int k = static_cast<int>(g() % 4);
      p.links[1].q.coeffs()[k] = std::nextafter(p.links[1].q.coeffs()[k], (g() & 1) ? 2.0 : -2.0);
    }
    ASSERT_EQ(ValidateAndNormalizePose(&p, 2), "") << "case " << c;
    const double* u = p.links[0].q.coeffs().data();
    const double* v = p.links[1].q.coeffs().data();
    for (int k = 0; k < 4; ++k) {
      ASSERT_TRUE(u[k] == 0 || std::fabs(u[k]) >= kTinyQuaternionComponent);
      ASSERT_TRUE(v[k] == 0 || std::fabs(v[k]) >= kTinyQuaternionComponent);
    }
    const int want = Binary128DotSign(u, v);
    // Within the twin's own rounding (an exact 0 among them: its sum can
    // round a nonzero dot to 0 too), the twin does not know.
    if (want == 0) continue;
    ASSERT_EQ(internal::DotSign(u, v), want)
        << "case " << c << ": " << std::hexfloat << u[0] << " " << u[1] << " " << u[2] << " "
        << u[3] << " / " << v[0] << " " << v[1] << " " << v[2] << " " << v[3];
    ++tiny_cases;
  }
  std::printf(
      "DotSign: %d exact zeros, %d one-ulp steps (rounded sum wrong on %d), %d by twin, %d with "
      "tiny components\n",
      zero, by_ulp, rounded_wrong, by_twin, tiny_cases);
  EXPECT_GT(tiny_cases, 15000);
  EXPECT_GT(by_ulp, 10000);
  EXPECT_GT(rounded_wrong, 100);
  EXPECT_GT(by_twin, 19000);
}

TEST(MotionTest, SlerpMatchesAxisAngleTwin) {
  std::mt19937_64 g(0x40710001);
  std::uniform_real_distribution<double> u01(0, 1);
  int64_t compared = 0, skipped = 0;
  for (int c = 0; c < 100000; ++c) {
    const Eigen::Quaterniond q0 = RandomUnitQuat(g);
    const Eigen::Quaterniond q1 = RelatedQuat(g, q0, -9);
    const QL l0 = ToQL(q0), l1 = ToQL(q1);
    if (std::fabs(Dot(l0, l1)) < 1e-12) {
      ++skipped;  // The sign decision is a coin toss of rounding; see ExactHalfTurn.
      continue;
    }
    const double angle = SlerpAngle(q0, q1);
    ASSERT_NEAR(angle, static_cast<double>(TwinAngle(l0, l1)), 1e-12) << "case " << c;
    ASSERT_GE(angle, 0.0);
    ASSERT_LE(angle, kPi);
    for (double s : {0.0, 1.0, u01(g), u01(g), 0.5}) {
      const Eigen::Quaterniond q = Slerp(q0, q1, s);
      const QL t = TwinSlerp(l0, l1, s);
      ++compared;
      ASSERT_NEAR(q.norm(), 1.0, 1e-14);
      // Same sign too: both start at q0 and follow the shortest arc.
      ASSERT_NEAR(q.w(), static_cast<double>(t.w), 1e-12) << "case " << c << " s=" << s;
      ASSERT_NEAR(q.x(), static_cast<double>(t.x), 1e-12) << "case " << c << " s=" << s;
      ASSERT_NEAR(q.y(), static_cast<double>(t.y), 1e-12) << "case " << c << " s=" << s;
      ASSERT_NEAR(q.z(), static_cast<double>(t.z), 1e-12) << "case " << c << " s=" << s;
    }
    // Ends: q0 itself, and q1's rotation.
    EXPECT_LT(MaxDiff(RotOf(Slerp(q0, q1, 0)), RotOf(q0)), 1e-12L);
    EXPECT_LT(MaxDiff(RotOf(Slerp(q0, q1, 1)), RotOf(q1)), 1e-12L);
  }
  EXPECT_GT(compared, 400000);
  EXPECT_LT(skipped, 100);
}

// q and -q are the same rotation: slerp between them stands still, and
// negating either input does not change the rotations along the way.
TEST(MotionTest, SlerpIgnoresQuaternionSigns) {
  std::mt19937_64 g(0x40710002);
  std::uniform_real_distribution<double> u01(0, 1);
  for (int c = 0; c < 20000; ++c) {
    const Eigen::Quaterniond q0 = RandomUnitQuat(g);
    Eigen::Quaterniond m0;
    m0.coeffs() = -q0.coeffs();
    EXPECT_EQ(SlerpAngle(q0, m0), 0.0);
    const double s = u01(g);
    EXPECT_LT(MaxDiff(RotOf(Slerp(q0, m0, s)), RotOf(q0)), 1e-14L);
    const Eigen::Quaterniond q1 = RelatedQuat(g, q0, -12);
    if (q0.coeffs().dot(q1.coeffs()) == 0) continue;  // Exactly 180 degrees: see below.
    Eigen::Quaterniond m1;
    m1.coeffs() = -q1.coeffs();
    const Mat3L R = RotOf(Slerp(q0, q1, s));
    EXPECT_LT(MaxDiff(RotOf(Slerp(q0, m1, s)), R), 1e-12L) << "case " << c;
    EXPECT_LT(MaxDiff(RotOf(Slerp(m0, q1, s)), R), 1e-12L) << "case " << c;
    EXPECT_LT(MaxDiff(RotOf(Slerp(m0, m1, s)), R), 1e-12L) << "case " << c;
    EXPECT_NEAR(SlerpAngle(q0, m1), SlerpAngle(q0, q1), 1e-12);
  }
}

// dot(q0, q1) == 0 exactly: the SPEC's rule flips only when dot < 0, so the
// slerp goes to q1 as given.
TEST(MotionTest, ExactHalfTurn) {
  const Eigen::Quaterniond q0(1, 0, 0, 0), q1(0, 1, 0, 0);
  EXPECT_NEAR(SlerpAngle(q0, q1), kPi, 1e-15);
  const Eigen::Quaterniond h = Slerp(q0, q1, 0.5);
  const Eigen::Quaterniond want(Eigen::AngleAxisd(kPi / 2, Eigen::Vector3d::UnitX()));
  EXPECT_NEAR(h.w(), want.w(), 1e-15);
  EXPECT_NEAR(h.x(), want.x(), 1e-15);
  EXPECT_NEAR(h.y(), 0, 1e-15);
  EXPECT_NEAR(h.z(), 0, 1e-15);
  const Eigen::Quaterniond q2(0, -1, 0, 0);  // dot = -0.0: not < 0 either.
  EXPECT_NEAR(Slerp(q0, q2, 0.5).x(), -want.x(), 1e-15);
  // Just past 180 degrees the arc turns the other way.
  const Eigen::Quaterniond q3(-1e-9, 1, 0, 0);
  EXPECT_NEAR(Slerp(q0, q3.normalized(), 0.5).x(), -want.x(), 1e-8);
  EXPECT_NEAR(SlerpAngle(q0, q3.normalized()), kPi - 2e-9, 1e-14);
}

TEST(MotionTest, ParseMotionModel) {
  EXPECT_EQ(ParseMotionModel("articulated"), MotionModel::kArticulated);
  EXPECT_EQ(ParseMotionModel("independent"), MotionModel::kIndependent);
  EXPECT_FALSE(ParseMotionModel("Articulated").has_value());
  EXPECT_FALSE(ParseMotionModel("").has_value());
  EXPECT_STREQ(MotionModelName(MotionModel::kArticulated), "articulated");
  EXPECT_STREQ(MotionModelName(MotionModel::kIndependent), "independent");
}

// ---------------------------------------------------------------------------
// PairMotion.

TEST(MotionTest, BothModelsReproduceTheGivenPoses) {
  std::mt19937_64 g(0x40710003);
  int64_t links_checked = 0;
  for (int c = 0; c < 2000; ++c) {
    const Rig rig = MakeRig(g, c % 2 == 0, -12);
    for (MotionModel model : {MotionModel::kArticulated, MotionModel::kIndependent}) {
      const PairMotion motion(rig.skeleton, rig.pose0, rig.pose1, model);
      ASSERT_EQ(motion.num_links(), rig.skeleton.num_links());
      EXPECT_EQ(motion.model(), model);
      std::vector<LinkPose> at0, at1;
      motion.PosesAt(0.0, &at0);
      motion.PosesAt(1.0, &at1);
      for (LinkIndex i(0); i < motion.num_links(); ++i) {
        ++links_checked;
        const Pose* given[2] = {&rig.pose0, &rig.pose1};
        const std::vector<LinkPose>* got[2] = {&at0, &at1};
        for (int e = 0; e < 2; ++e) {
          const LinkPose& want = given[e]->links[i];
          const LinkPose one = motion.PoseAt(i, e);
          for (const LinkPose* x : {&(*got[e])[i], &one}) {
            EXPECT_LT(MaxDiff(ToL(x->p), ToL(want.p)), 1e-9L)
                << RigSummary(rig, model) << " link " << i << " s=" << e;
            EXPECT_LT(MaxDiff(RotOf(x->q), RotOf(want.q)), 1e-9L)
                << RigSummary(rig, model) << " link " << i << " s=" << e;
          }
        }
      }
    }
  }
  RecordProperty("links_checked", std::to_string(links_checked));
  EXPECT_GT(links_checked, 20000);
}

TEST(MotionTest, ArticulatedConnectedSkeletonStaysConnected) {
  std::mt19937_64 g(0x40710004);
  int64_t joints_checked = 0;
  for (int c = 0; c < 600; ++c) {
    const Rig rig = MakeRig(g, /*connected=*/true, -12);
    const PairMotion motion(rig.skeleton, rig.pose0, rig.pose1, MotionModel::kArticulated);
    for (int j = 0; j <= 99; ++j) {
      const double s = j / 99.0;
      for (LinkIndex i(0); i < motion.num_links(); ++i) {
        const int k = rig.skeleton.link(i).parent;
        if (k < 0) continue;
        Eigen::Vector3d child_a, child_b, parent_a, parent_b;
        motion.SegmentAt(i, s, &child_a, &child_b);
        motion.SegmentAt(LinkIndex(k), s, &parent_a, &parent_b);
        ++joints_checked;
        ASSERT_LT((child_a - parent_b).cwiseAbs().maxCoeff(), 1e-9)
            << RigSummary(rig, MotionModel::kArticulated) << " link " << i << " parent " << k
            << " s=" << s;
      }
    }
    // The bones do separate in the independent model (so the check above
    // could fail), unless nothing moves.
  }
  RecordProperty("joints_checked", std::to_string(joints_checked));
  EXPECT_GT(joints_checked, 500000);
}

TEST(MotionTest, IndependentLinksMoveOnTheirOwn) {
  std::mt19937_64 g(0x40710005);
  std::uniform_real_distribution<double> u01(0, 1);
  int64_t compared = 0;
  for (int c = 0; c < 1000; ++c) {
    const Rig rig = MakeRig(g, c % 2 == 0, -9);
    const PairMotion motion(rig.skeleton, rig.pose0, rig.pose1, MotionModel::kIndependent);
    std::vector<LinkPose> all;
    for (int j = 0; j < 10; ++j) {
      const double s = u01(g);
      motion.PosesAt(s, &all);
      for (LinkIndex i(0); i < motion.num_links(); ++i) {
        const LinkPose& X0 = rig.pose0.links[i];
        const LinkPose& X1 = rig.pose1.links[i];
        const QL q0 = ToQL(X0.q), q1 = ToQL(X1.q);
        if (std::fabs(Dot(q0, q1)) < 1e-9) continue;
        const Vec3L p = (1 - LD(s)) * ToL(X0.p) + LD(s) * ToL(X1.p);
        const Mat3L R = RotL(TwinSlerp(q0, q1, s));
        const LinkPose one = motion.PoseAt(i, s);
        ++compared;
        EXPECT_LT(MaxDiff(ToL(all[i].p), p), 1e-9L) << "link " << i << " s=" << s;
        EXPECT_LT(MaxDiff(RotOf(all[i].q), R), 1e-9L) << "link " << i << " s=" << s;
        EXPECT_LT(MaxDiff(ToL(one.p), p), 1e-9L) << "link " << i << " s=" << s;
        EXPECT_LT(MaxDiff(RotOf(one.q), R), 1e-9L) << "link " << i << " s=" << s;
      }
    }
  }
  EXPECT_GT(compared, 50000);
}

TEST(MotionTest, ArticulatedMatchesSpecTwin) {
  std::mt19937_64 g(0x40710006);
  std::uniform_real_distribution<double> u01(0, 1);
  int64_t compared = 0, rigs_skipped = 0;
  for (int c = 0; c < 1500; ++c) {
    const Rig rig = MakeRig(g, c % 3 == 0, -7);
    for (MotionModel model : {MotionModel::kArticulated, MotionModel::kIndependent}) {
      const TwinMotion twin(rig.skeleton, rig.pose0, rig.pose1, model);
      if (!twin.Unambiguous()) {
        ++rigs_skipped;
        continue;
      }
      const PairMotion motion(rig.skeleton, rig.pose0, rig.pose1, model);
      std::vector<LinkPose> all;
      for (double s : {0.0, 1.0, u01(g), u01(g), u01(g), u01(g), u01(g)}) {
        const std::vector<TwinPose> want = twin.PosesAt(s);
        motion.PosesAt(s, &all);
        for (LinkIndex i(0); i < motion.num_links(); ++i) {
          const Mat3L R = RotL(want[i].q);
          const LinkPose one = motion.PoseAt(i, s);
          Eigen::Vector3d A, B;
          motion.SegmentAt(i, s, &A, &B);
          const Vec3L want_a = want[i].p + R * ToL(rig.skeleton.link(i).a_L);
          const Vec3L want_b = want[i].p + R * ToL(rig.skeleton.link(i).b_L);
          ++compared;
          const std::string where =
              RigSummary(rig, model) + " link " + std::to_string(i) + " s=" + std::to_string(s);
          ASSERT_LT(MaxDiff(ToL(all[i].p), want[i].p), 1e-9L) << where;
          ASSERT_LT(MaxDiff(RotOf(all[i].q), R), 1e-9L) << where;
          ASSERT_LT(MaxDiff(ToL(one.p), want[i].p), 1e-9L) << where;
          ASSERT_LT(MaxDiff(RotOf(one.q), R), 1e-9L) << where;
          ASSERT_LT(MaxDiff(ToL(A), want_a), 1e-9L) << where;
          ASSERT_LT(MaxDiff(ToL(B), want_b), 1e-9L) << where;
        }
      }
    }
  }
  RecordProperty("compared", std::to_string(compared));
  RecordProperty("rigs_skipped", std::to_string(rigs_skipped));
  EXPECT_GT(compared, 100000);
  EXPECT_LT(rigs_skipped, 30);
}

TEST(MotionTest, NegatedQuaternionsGiveTheSameSegments) {
  std::mt19937_64 g(0x40710007);
  std::uniform_real_distribution<double> u01(0, 1);
  int64_t compared = 0;
  for (int c = 0; c < 1000; ++c) {
    const Rig rig = MakeRig(g, c % 2 == 0, -12);
    Pose n0 = rig.pose0, n1 = rig.pose1;
    int negated = 0;
    for (Pose* p : {&n0, &n1}) {
      for (LinkPose& x : p->links) {
        if (u01(g) < 0.5) {
          x.q.coeffs() = -x.q.coeffs();
          ++negated;
        }
      }
    }
    for (MotionModel model : {MotionModel::kArticulated, MotionModel::kIndependent}) {
      const PairMotion a(rig.skeleton, rig.pose0, rig.pose1, model);
      const PairMotion b(rig.skeleton, n0, n1, model);
      for (int j = 0; j < 12; ++j) {
        const double s = j < 2 ? j : u01(g);
        for (LinkIndex i(0); i < a.num_links(); ++i) {
          Eigen::Vector3d a_a, a_b, b_a, b_b;
          a.SegmentAt(i, s, &a_a, &a_b);
          b.SegmentAt(i, s, &b_a, &b_b);
          ++compared;
          ASSERT_LT((a_a - b_a).cwiseAbs().maxCoeff(), 1e-9)
              << RigSummary(rig, model) << " negated " << negated << " link " << i << " s=" << s;
          ASSERT_LT((a_b - b_b).cwiseAbs().maxCoeff(), 1e-9)
              << RigSummary(rig, model) << " negated " << negated << " link " << i << " s=" << s;
        }
      }
    }
  }
  EXPECT_GT(compared, 100000);
}

// Every point of the segment stays within SweepRadius of where it is at the
// midpoint of the sub-interval.
TEST(MotionTest, SweepRadiusEnclosesTheMotion) {
  std::mt19937_64 g(0x40710008);
  std::uniform_real_distribution<double> u01(0, 1);
  int64_t sub_intervals = 0, violations = 0, samples = 0;
  std::string first;
  for (int c = 0; c < 400; ++c) {
    const Rig rig = MakeRig(g, c % 2 == 0, -12);
    const MotionModel model = RandomModel(g);
    const PairMotion motion(rig.skeleton, rig.pose0, rig.pose1, model);
    for (int k = 0; k < 12; ++k) {
      double s0, s1;
      switch (k % 4) {
        case 0:
          s0 = 0;
          s1 = 1;
          break;
        case 1: {  // Tiny.
          s0 = u01(g);
          s1 = std::min(1.0, s0 + LogUniform(g, -12, -5));
          break;
        }
        case 2: {  // Medium.
          s0 = u01(g) * 0.9;
          s1 = std::min(1.0, s0 + LogUniform(g, -3, -1));
          break;
        }
        default:
          s0 = u01(g);
          s1 = u01(g);
          if (s0 > s1) std::swap(s0, s1);
          break;
      }
      const double mid = 0.5 * (s0 + s1);
      for (LinkIndex i(0); i < motion.num_links(); ++i) {
        const double bound = motion.SweepRadius(i, s0, s1);
        Eigen::Vector3d ma, mb;
        motion.SegmentAt(i, mid, &ma, &mb);
        ++sub_intervals;
        double worst = 0;
        for (int j = 0; j <= 16; ++j) {
          const double s = j == 16 ? s1 : s0 + (s1 - s0) * (j / 16.0);
          Eigen::Vector3d a, b;
          motion.SegmentAt(i, s, &a, &b);
          for (double u : {0.0, 1.0, u01(g), u01(g), 0.5}) {
            ++samples;
            const Eigen::Vector3d p = (1 - u) * a + u * b;
            const Eigen::Vector3d pm = (1 - u) * ma + u * mb;
            worst = std::max(worst, (p - pm).norm());
          }
        }
        if (!(worst <= bound)) {
          ++violations;
          if (violations <= 5) {
            std::ostringstream s;
            s.precision(17);
            s << RigSummary(rig, model) << " link " << i << " [" << s0 << ", " << s1 << "]: moved "
              << worst << " > SweepRadius " << bound << "\n";
            first += s.str();
          }
        }
      }
    }
  }
  RecordProperty("sub_intervals", std::to_string(sub_intervals));
  RecordProperty("samples", std::to_string(samples));
  EXPECT_EQ(violations, 0) << first;
  EXPECT_GE(sub_intervals, 20000);
  EXPECT_GT(samples, 1000000);
}

// The speed bounds really bound finite differences of the link origin and
// of the orientation, and are tight for a root (nothing to compose).
TEST(MotionTest, SpeedBoundsBoundFiniteDifferences) {
  std::mt19937_64 g(0x40710009);
  std::uniform_real_distribution<double> u01(0, 1);
  int64_t steps = 0;
  for (int c = 0; c < 600; ++c) {
    const Rig rig = MakeRig(g, c % 2 == 0, -12);
    const MotionModel model = RandomModel(g);
    const PairMotion motion(rig.skeleton, rig.pose0, rig.pose1, model);
    constexpr double h = 1e-3;
    for (LinkIndex i(0); i < motion.num_links(); ++i) {
      const double v = motion.origin_speed_bound(i), w = motion.angular_speed_bound(i);
      ASSERT_TRUE(std::isfinite(v) && v >= 0);
      ASSERT_TRUE(std::isfinite(w) && w >= 0);
      for (int j = 0; j < 20; ++j) {
        const double s = u01(g) * (1 - h);
        const LinkPose x0 = motion.PoseAt(i, s), x1 = motion.PoseAt(i, s + h);
        const double dp = (x1.p - x0.p).norm() / h;
        const double dq = static_cast<double>(TwinAngle(ToQL(x0.q), ToQL(x1.q))) / h;
        // Rounding of positions of up to ~1e3 m: 1e-12 / h.
        ++steps;
        ASSERT_LE(dp, v * (1 + 1e-9) + 1e-8)
            << RigSummary(rig, model) << " link " << i << " s=" << s;
        ASSERT_LE(dq, w * (1 + 1e-9) + 1e-8)
            << RigSummary(rig, model) << " link " << i << " s=" << s;
      }
      const bool own = model == MotionModel::kIndependent || rig.skeleton.link(i).parent < 0;
      if (own) {
        const LinkPose& X0 = rig.pose0.links[i];
        const LinkPose& X1 = rig.pose1.links[i];
        EXPECT_NEAR(v, (X1.p - X0.p).norm(), 1e-12 * (1 + v));
        EXPECT_NEAR(w, SlerpAngle(X0.q, X1.q), 1e-9 * (1 + w));
      }
    }
  }
  RecordProperty("steps", std::to_string(steps));
  EXPECT_GT(steps, 100000);
}

// PoseAt at s = 0, 0.5 and 1 is a look-up of poses composed once per pair
// (a culled link of a deep chain costs O(1)): it must equal PosesAt at the
// same time bit for bit, and agree with the composition just beside it
// (nextafter), on chains deeper than PoseAt's 64-link step.
TEST(MotionTest, PoseAtEndsAndMiddleMatchPosesAtOnDeepChains) {
  std::mt19937_64 g(0x40710077);
  std::uniform_real_distribution<double> u(-1, 1);
  for (int n : {1, 63, 65, 300}) {
    std::vector<Link> links(n);
    for (int i = 0; i < n; ++i) {
      links[i].name = "l" + std::to_string(i);
      links[i].parent = i - 1;
      links[i].b_L = {0, 0.05, 0};
      links[i].radius = 0.01;
    }
    const Skeleton skeleton = Skeleton::FromLinks("chain", links, "test");
    Pose pose[2];
    for (Pose& p : pose) {
      p.links.resize(n);
      for (LinkPose& l : p.links) {
        l.p = {u(g), u(g), u(g)};
        l.q = Eigen::Quaterniond(u(g), u(g), u(g), u(g)).normalized();
      }
    }
    const PairMotion motion(skeleton, pose[0], pose[1], MotionModel::kArticulated);
    for (double s : {0.0, 0.5, 1.0}) {
      std::vector<LinkPose> all;
      motion.PosesAt(s, &all);
      const double beside = s < 1 ? std::nextafter(s, 1.0) : std::nextafter(s, 0.0);
      for (LinkIndex i(0); i < n; ++i) {
        const LinkPose one = motion.PoseAt(i, s);
        ASSERT_EQ(one.p, all[i].p) << "n " << n << " link " << i << " s " << s;
        ASSERT_EQ(one.q.coeffs(), all[i].q.coeffs()) << "n " << n << " link " << i << " s " << s;
        const LinkPose near = motion.PoseAt(i, beside);
        EXPECT_LT((near.p - one.p).norm(), 1e-9) << "n " << n << " link " << i << " s " << s;
        EXPECT_LT((near.q.coeffs() - one.q.coeffs()).norm(), 1e-9);
      }
    }
  }
}

// The slerp sines cached per link (s = 0, 0.5, 1 and the inverse of
// sin(half angle) everywhere) and the segments cached at s = 0, 0.5, 1 give
// the same bits as computing them afresh: the twin is Slerp() (fresh sines)
// composed by hand as SPEC section 3 says, in the engine's operation order.
TEST(MotionTest, CachedSinesAndSegmentsMatchFreshComputationBitForBit) {
  std::mt19937_64 g(0x5117e5);
  std::uniform_real_distribution<double> u(-1, 1);
  std::uniform_real_distribution<double> u01(0, 1);
  std::vector<Link> links(2);
  links[0].name = "root";
  links[1].name = "child";
  links[1].parent = 0;
  for (int trial = 0; trial < 3000; ++trial) {
    for (Link& l : links) {
      l.a_L = {u(g), u(g), u(g)};
      l.b_L = trial % 5 == 0 ? l.a_L : Eigen::Vector3d(u(g), u(g), u(g));
      l.radius = 0.05;
    }
    const Skeleton skeleton = Skeleton::FromLinks("pair", links, "test");
    Pose pose[2];
    for (Pose& p : pose) {
      p.links.resize(2);
      for (LinkPose& l : p.links) {
        l.p = {u(g), u(g), u(g)};
        l.q = Eigen::Quaterniond(u(g), u(g), u(g), u(g)).normalized();
      }
    }
    // Small turns too (the nlerp fallback below 1e-6 rad), and sign flips.
    if (trial % 3 == 0) {
      for (int i = 0; i < 2; ++i) {
        const double tiny = std::pow(10.0, -9 + 6 * u01(g));
        pose[1].links[i].q = (pose[0].links[i].q *
                              Eigen::Quaterniond(Eigen::AngleAxisd(tiny, Eigen::Vector3d::UnitX())))
                                 .normalized();
      }
    }
    if (trial % 4 == 1) pose[1].links[1].q.coeffs() *= -1;
    const double random_s = u01(g);
    for (MotionModel model : {MotionModel::kIndependent, MotionModel::kArticulated}) {
      const PairMotion motion(skeleton, pose[0], pose[1], model);
      for (double s : {0.0, 0.5, 1.0, random_s, 0.25}) {
        LinkPose twin[2];
        for (int i = 0; i < 2; ++i) {
          const LinkPose& x0 = pose[0].links[i];
          const LinkPose& x1 = pose[1].links[i];
          if (model == MotionModel::kIndependent || i == 0) {
            twin[i].p = (1 - s) * x0.p + s * x1.p;
            twin[i].q = Slerp(x0.q, x1.q, s);
            continue;
          }
          const LinkPose& k0 = pose[0].links[0];
          const LinkPose& k1 = pose[1].links[0];
          const Eigen::Vector3d c0 = k0.q.toRotationMatrix().transpose() * (x0.p - k0.p);
          const Eigen::Vector3d c1 = k1.q.toRotationMatrix().transpose() * (x1.p - k1.p);
          const Eigen::Quaterniond r0 = (k0.q.conjugate() * x0.q).normalized();
          const Eigen::Quaterniond r1 = (k1.q.conjugate() * x1.q).normalized();
          const Eigen::Vector3d c = (1 - s) * c0 + s * c1;
          const Eigen::Quaterniond r = Slerp(r0, r1, s);
          twin[i].q = (twin[0].q * r).normalized();
          twin[i].p = twin[0].p + twin[0].q * c;
        }
        for (LinkIndex i(0); i < 2; ++i) {
          const LinkPose got = motion.PoseAt(i, s);
          ASSERT_EQ(got.p, twin[i].p) << "trial " << trial << " link " << i << " s " << s;
          ASSERT_EQ(got.q.coeffs(), twin[i].q.coeffs())
              << "trial " << trial << " link " << i << " s " << s;
          const Eigen::Matrix3d R = twin[i].q.toRotationMatrix();
          const Eigen::Vector3d A = twin[i].p + R * links[i].a_L;
          const Eigen::Vector3d B = twin[i].p + R * links[i].b_L;
          Eigen::Vector3d a, b;
          motion.SegmentAt(i, s, &a, &b);
          ASSERT_EQ(a, A) << "trial " << trial << " link " << i << " s " << s;
          ASSERT_EQ(b, B) << "trial " << trial << " link " << i << " s " << s;
        }
      }
    }
  }
}

// The growth bounds' upper-end arithmetic against its twin, the interval
// expressions it replaced (verbatim), bit for bit, on random non-negative
// bounds of every magnitude (zeros and subnormals included) and intervals
// [s0, s1] of every width (zero included).
TEST(MotionTest, GrowthUpperEndsMatchIntervalExpressionsBitForBit) {
  std::mt19937_64 g(0x60e7);
  std::uniform_real_distribution<double> u01(0, 1);
  auto value = [&]() {
    const double r = u01(g);
    if (r < 0.1) return 0.0;
    if (r < 0.15) return std::ldexp(u01(g), -1060);  // Subnormal.
    if (r < 0.5) return 10 * u01(g);
    return std::pow(10.0, -300 + 600 * u01(g)) * u01(g);
  };
  for (int k = 0; k < 1'000'000; ++k) {
    const double speed = value(), angular = value(), extent = value(), slack = value();
    const double accel = value(), angular_accel = value(), chord = value();
    double s0 = u01(g), s1 = u01(g);
    if (s1 < s0) std::swap(s0, s1);
    const double r = u01(g);
    if (r < 0.1)
      s1 = s0;
    else if (r < 0.2)
      s1 = std::nextafter(s0, 2.0);
    else if (r < 0.3)
      s0 = 0, s1 = 1;
    // The expressions as PairMotion wrote them with intervals.
    const Interval half_width = (Interval(s1) - Interval(s0)) * Interval(0.5);
    const Interval speed_all = Interval(speed) + Interval(angular) * Interval(extent);
    const double first = (speed_all * half_width + Interval(slack)).hi();
    const Interval w(angular);
    const Interval acc = Interval(accel) + (Interval(angular_accel) + w * w) * Interval(extent);
    const Interval width = Interval(s1) - Interval(s0);
    const double second = (Interval(chord) * Interval(0.5) + Interval(0.25) * Sqr(width) * acc +
                           Interval(4.0) * Interval(slack))
                              .hi();
    ASSERT_EQ(Bits(internal::FirstOrderGrowth(speed, angular, extent, slack, s0, s1)), Bits(first))
        << k;
    ASSERT_EQ(Bits(internal::SecondOrderGrowth(chord, accel, angular_accel, angular, extent, slack,
                                               s0, s1)),
              Bits(second))
        << k;
  }
}

// The whole pair's first-order growth (FirstOrderGrowthOverPair, which
// PairMotion::PairGrowthUpper reads for every link of a query) against its
// two twins, bit for bit: FirstOrderGrowth over [0, 1] and the interval
// expression it replaced, on random non-negative bounds of every magnitude
// (zeros, subnormals, and values whose products overflow, so the interval
// fallback answers too).
TEST(MotionTest, WholePairGrowthMatchesFirstOrderGrowthBitForBit) {
  std::mt19937_64 g(0x9a1f);
  std::uniform_real_distribution<double> u01(0, 1);
  auto value = [&]() {
    const double r = u01(g);
    if (r < 0.1) return 0.0;
    if (r < 0.15) return std::ldexp(u01(g), -1060);  // Subnormal.
    if (r < 0.5) return 10 * u01(g);
    if (r < 0.6) return std::numeric_limits<double>::max() * u01(g);
    return std::pow(10.0, -300 + 600 * u01(g)) * u01(g);
  };
  const int n = std::max(1000, static_cast<int>(1'000'000 * testing::TestScale()));
  int overflowed = 0;
  for (int k = 0; k < n; ++k) {
    const double speed = value(), angular = value(), extent = value(), slack = value();
    const double pair = internal::FirstOrderGrowthOverPair(speed, angular, extent, slack);
    const Interval speed_all = Interval(speed) + Interval(angular) * Interval(extent);
    const double twin =
        (speed_all * ((Interval(1.0) - Interval(0.0)) * Interval(0.5)) + Interval(slack)).hi();
    ASSERT_EQ(Bits(pair), Bits(internal::FirstOrderGrowth(speed, angular, extent, slack, 0, 1)))
        << k;
    ASSERT_EQ(Bits(pair), Bits(twin)) << k;
    overflowed += pair > std::numeric_limits<double>::max() ? 1 : 0;
  }
  EXPECT_GT(overflowed, n / 100);  // The fallback was reached.
}

// The link bounds from upper ends alone give the interval arithmetic's bits
// wherever they answer, and decline only where a step overflows (an operand
// above 1e100 here): random
// half angles (0 to pi, zero, subnormal), speeds, levers and parent bounds
// from 0 through subnormals to 1e300, roots and children.
TEST(MotionTest, LinkBoundsUpperEndsMatchIntervalsBitForBit) {
  std::mt19937_64 g(0xb0b5);
  std::uniform_real_distribution<double> u01(0, 1);
  auto value = [&]() {
    const double r = u01(g);
    if (r < 0.1) return 0.0;
    if (r < 0.15) return std::ldexp(u01(g), -1060);  // Subnormal.
    if (r < 0.6) return 10 * u01(g);
    return std::pow(10.0, -300 + 600 * u01(g)) * u01(g);
  };
  auto angle = [&]() {
    const double r = u01(g);
    if (r < 0.1) return 0.0;
    if (r < 0.15) return std::ldexp(u01(g), -1060);
    if (r < 0.3) return 1e-6 * u01(g);  // Around the nlerp fallback.
    return M_PI * u01(g);
  };
  int declined = 0;
  for (int k = 0; k < 1'000'000; ++k) {
    const double half_angle = angle(), own_speed = value(), lever = value();
    internal::LinkBounds parent{value(), value(), value(), value()};
    const internal::LinkBounds* p = u01(g) < 0.2 ? nullptr : &parent;
    const internal::LinkBounds want =
        internal::LinkBoundsByIntervals(half_angle, own_speed, lever, p);
    internal::LinkBounds got;
    if (!internal::LinkBoundsByUpperEnds(half_angle, own_speed, lever, p, &got)) {
      // Declining is safe (the caller then takes the intervals' bounds); it
      // must only happen where some operand is huge.
      ++declined;
      const double largest = std::max(
          {own_speed, lever, parent.speed, parent.angular, parent.accel, parent.angular_accel});
      ASSERT_GT(largest, 1e100) << k << ": declined with every operand at most 1e100";
      continue;
    }
    ASSERT_EQ(Bits(got.speed), Bits(want.speed)) << k;
    ASSERT_EQ(Bits(got.angular), Bits(want.angular)) << k;
    ASSERT_EQ(Bits(got.accel), Bits(want.accel)) << k;
    ASSERT_EQ(Bits(got.angular_accel), Bits(want.angular_accel)) << k;
  }
  // Products of two values up to 1e300 overflow often: both paths are taken.
  EXPECT_GT(declined, 10000);
  EXPECT_LT(declined, 900000);
}

}  // namespace
}  // namespace sweptccd
