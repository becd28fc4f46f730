#pragma once
// Internal to the query engine (see docs/DESIGN.md, "core/query"): the swept
// capsule of a link over a time interval, with its radius computed here and
// nowhere else.

#include <Eigen/Core>

#include "core/avatar/motion.h"
#include "core/avatar/skeleton.h"
#include "core/query/link_capsule.h"
#include "core/scene/environment.h"

namespace sweptccd::internal {

/// A link's segment at both ends of a time interval, as PairMotion::SegmentAt
/// computes them (time slicing hands them from parent to child).
struct SegmentEnds {
  Eigen::Vector3d a0{0, 0, 0}, b0{0, 0, 0};  // At s0.
  Eigen::Vector3d a1{0, 0, 0}, b1{0, 0, 0};  // At s1.
};

/// Swept capsules of one pair's motion: the segment at the interval's
/// midpoint, radius = link radius + the motion's growth over the interval +
/// the query tolerance. Holds references (skeleton and motion outlive it);
/// const and thread-compatible.
class SweptBounds {
 public:
  SweptBounds(const Skeleton& skeleton, const PairMotion& motion, double tolerance_m)
      : skeleton_(skeleton), motion_(motion), tolerance_m_(tolerance_m) {}

  /// The distance slack (metres) of a query on `environment` with `motion`:
  /// the environment's float storage, and the rounding of the distance
  /// routines (at most ~2e-8 of the coordinates' magnitude, see
  /// tests/core/geometry/distance_test.cc; 2^-22 of the avatar's is ten times that).
  static double Tolerance(const Environment& environment, const PairMotion& motion);

  /// The link's segment at s0 and at s1.
  SegmentEnds EndsOver(LinkIndex link, double s0, double s1) const;
  /// The capsule over [s0, s1], computing the segments at the ends.
  LinkCapsule Over(LinkIndex link, double s0, double s1) const;
  /// The capsule over [s0, s1] from the segments at its ends (same numbers as
  /// Over). Its segment is the link's segment at the midpoint.
  LinkCapsule FromEnds(LinkIndex link, double s0, double s1, const SegmentEnds& ends) const;

  /// A capsule holding Over(link, 0, 1) (`articulated`) that needs no pose
  /// composed nor motion finished: the segment between the midpoints of the
  /// link's segment ends in `pose0` and `pose1` (the poses the motion was
  /// built from), radius link radius + 2 g + tolerance + 4 rounding slacks +
  /// BoxPad, g = PairMotion::PairGrowthUpper. Every link point moves at most
  /// 2 g over [0, 1] (SPEC 3; first order), so its place at s = 0.5 is
  /// within g of the midpoint of its two ends. docs/DESIGN.md, "Loose
  /// capsules".
  LinkCapsule LooseOver(LinkIndex link, const Pose& pose0, const Pose& pose1) const {
    return LooseOver(link, pose0, pose1, motion_.PairGrowthUpper(link));
  }
  /// As above with g given: `growth` must be motion().PairGrowthUpper(link)
  /// (e.g. SubtreeReach's copy, computed before; the same bits while the
  /// link's motion is not finished in between).
  LinkCapsule LooseOver(LinkIndex link, const Pose& pose0, const Pose& pose1, double growth) const;
  double tolerance_m() const { return tolerance_m_; }
  const PairMotion& motion() const { return motion_; }

 private:
  double Radius(LinkIndex link, double growth) const {
    return skeleton_.link(link).radius + growth + tolerance_m_;
  }

  const Skeleton& skeleton_;
  const PairMotion& motion_;
  double tolerance_m_;
};

}  // namespace sweptccd::internal
