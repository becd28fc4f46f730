#pragma once
// A twin of SPEC section 3's motion, written from the SPEC alone for the
// tests: slerp through the axis-angle form q0 * exp(s * log(conj(q0) * q1')),
// the articulated model composed root-down with rotation matrices, all in
// long double, with none of core/avatar's code. Shared by the motion tests
// and the shared-world reference (tests/core/world).

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <cmath>
#include <vector>

#include "core/avatar/motion.h"
#include "core/avatar/pose.h"
#include "core/avatar/skeleton.h"

namespace sweptccd::twin {

using LD = long double;
using Vec3L = Eigen::Matrix<LD, 3, 1>;
using Mat3L = Eigen::Matrix<LD, 3, 3>;

// The twin: quaternions as (w, x, y, z) in long double, with our own product,
// rotation matrix and slerp.

struct QL {
  LD w = 1, x = 0, y = 0, z = 0;
};

inline QL ToQL(const Eigen::Quaterniond& q) { return {q.w(), q.x(), q.y(), q.z()}; }
inline LD Dot(const QL& a, const QL& b) { return a.w * b.w + a.x * b.x + a.y * b.y + a.z * b.z; }
inline QL Neg(const QL& a) { return {-a.w, -a.x, -a.y, -a.z}; }
inline QL Conj(const QL& a) { return {a.w, -a.x, -a.y, -a.z}; }
inline QL Mul(const QL& a, const QL& b) {
  return {
      a.w * b.w - a.x * b.x - a.y * b.y - a.z * b.z, a.w * b.x + a.x * b.w + a.y * b.z - a.z * b.y,
      a.w * b.y - a.x * b.z + a.y * b.w + a.z * b.x, a.w * b.z + a.x * b.y - a.y * b.x + a.z * b.w};
}
inline QL Normalised(const QL& a) {
  const LD n = std::sqrt(Dot(a, a));
  return {a.w / n, a.x / n, a.y / n, a.z / n};
}

inline Mat3L RotL(const QL& q) {
  const LD w = q.w, x = q.x, y = q.y, z = q.z;
  Mat3L r;
  r << 1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y),  //
      2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x),   //
      2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y);
  return r;
}

// The sign of the dot product of two 4-vectors of doubles, summed in
// binary128, where each product of two doubles is exact: -1 or 1, or 0 when
// the sum is within its own rounding (1e-30 of the products' magnitudes) of
// 0, where this twin does not know the sign.
inline int Binary128DotSign(const double a[4], const double b[4]) {
  __float128 sum = 0, size = 0;
  for (int k = 0; k < 4; ++k) {
    const __float128 p = static_cast<__float128>(a[k]) * static_cast<__float128>(b[k]);
    sum += p;
    size += p < 0 ? -p : p;
  }
  const __float128 magnitude = sum < 0 ? -sum : sum;
  if (magnitude <= size * static_cast<__float128>(1e-30)) return 0;
  return sum > 0 ? 1 : -1;
}

// SPEC 3's sign rule: q1 is replaced by -q1 when dot(q0, q1) < 0. Where
// the long double dot is within rounding of 0 (a turn of 180 degrees: both
// arcs are as short), the dot of the quaternions as doubles (the numbers a
// pose stream holds) is taken in binary128 (Binary128DotSign; 0: no flip).
inline bool ShortestArcFlips(const QL& q0, const QL& q1) {
  const LD dot = Dot(q0, q1);
  if (std::fabs(dot) > 1e-12L) return dot < 0;
  const double a[4] = {static_cast<double>(q0.w), static_cast<double>(q0.x),
                       static_cast<double>(q0.y), static_cast<double>(q0.z)};
  const double b[4] = {static_cast<double>(q1.w), static_cast<double>(q1.x),
                       static_cast<double>(q1.y), static_cast<double>(q1.z)};
  return Binary128DotSign(a, b) < 0;
}

// Shortest-arc slerp as q0 * exp(s * log(conj(q0) * q1')).
inline QL TwinSlerp(const QL& q0, QL q1, LD s) {
  if (ShortestArcFlips(q0, q1)) q1 = Neg(q1);
  const QL d = Mul(Conj(q0), q1);
  const LD vn = std::sqrt(d.x * d.x + d.y * d.y + d.z * d.z);
  if (vn == 0) return q0;
  const LD half = std::atan2(vn, d.w);  // Half the rotation angle.
  const LD c = std::cos(s * half), k = std::sin(s * half) / vn;
  return Mul(q0, QL{c, k * d.x, k * d.y, k * d.z});
}

// Rotation angle (in [0, pi]) from q0 to q1.
inline LD TwinAngle(const QL& q0, const QL& q1) {
  const QL d = Mul(Conj(q0), q1);
  const LD vn = std::sqrt(d.x * d.x + d.y * d.y + d.z * d.z);
  return 2 * std::atan2(vn, std::fabs(d.w));
}

inline Vec3L ToL(const Eigen::Vector3d& v) { return v.cast<LD>(); }

// The articulated and independent models, written from SPEC section 3.

struct TwinPose {
  Vec3L p;
  QL q;
};

class TwinMotion {
 public:
  TwinMotion(const Skeleton& skel, const Pose& pose0, const Pose& pose1, MotionModel model)
      : skel_(skel), pose0_(pose0), pose1_(pose1), model_(model) {}

  // True when every slerp's sign decision is clear (|dot| well away from 0),
  // so that the twin and the core (in double) take the same arc.
  bool Unambiguous() const {
    for (int i = 0; i < skel_.num_links(); ++i) {
      QL a, b;
      Ends(i, &a, &b);
      if (std::fabs(Dot(a, b)) < 1e-9) return false;
    }
    return true;
  }

  std::vector<TwinPose> PosesAt(LD s) const {
    std::vector<TwinPose> out(skel_.num_links());
    std::vector<bool> done(skel_.num_links(), false);
    for (int i = 0; i < skel_.num_links(); ++i) Compose(i, s, &out, &done);
    return out;
  }

 private:
  bool Articulated(int i) const {
    return model_ == MotionModel::kArticulated && skel_.link(i).parent >= 0;
  }
  // Own rotations at the two ends: world for roots/independent, r_i otherwise.
  void Ends(int i, QL* a, QL* b) const {
    const QL q0 = ToQL(pose0_.links[i].q), q1 = ToQL(pose1_.links[i].q);
    if (!Articulated(i)) {
      *a = q0;
      *b = q1;
      return;
    }
    const int k = skel_.link(i).parent;
    *a = Normalised(Mul(Conj(ToQL(pose0_.links[k].q)), q0));
    *b = Normalised(Mul(Conj(ToQL(pose1_.links[k].q)), q1));
  }
  // Recursion from the root down (independent of the core's order).
  void Compose(int i, LD s, std::vector<TwinPose>* out, std::vector<bool>* done) const {
    if ((*done)[i]) return;
    QL ra, rb;
    Ends(i, &ra, &rb);
    const QL r = TwinSlerp(ra, rb, s);
    const Vec3L p0 = ToL(pose0_.links[i].p), p1 = ToL(pose1_.links[i].p);
    if (!Articulated(i)) {
      (*out)[i] = {(1 - s) * p0 + s * p1, r};
    } else {
      const int k = skel_.link(i).parent;
      Compose(k, s, out, done);
      const Vec3L c0 = RotL(ToQL(pose0_.links[k].q)).transpose() * (p0 - ToL(pose0_.links[k].p));
      const Vec3L c1 = RotL(ToQL(pose1_.links[k].q)).transpose() * (p1 - ToL(pose1_.links[k].p));
      const Vec3L c = (1 - s) * c0 + s * c1;
      const TwinPose& K = (*out)[k];
      (*out)[i] = {K.p + RotL(K.q) * c, Mul(K.q, r)};
    }
    (*done)[i] = true;
  }

  const Skeleton& skel_;
  const Pose& pose0_;
  const Pose& pose1_;
  MotionModel model_;
};

}  // namespace sweptccd::twin
