#pragma once
// A 16-link mocap pose (mocap_import.h) as one joint frame of
// XR_META_body_tracking_full_body (84 joints), with PROCEDURALLY ANIMATED
// fingers (not captured): the body joints lie on the mocap links' segments
// (spine joints between pelvis, spine and chest; shoulder and scapula between
// chest and upper arm; ankle, subtalar, transverse and ball along the foot),
// and each hand's fingers curl about the hand's lateral axis by a curl in
// [0, 1] (0 open, 1 closed round a grip). Used by sweptccd_full_body_bench,
// `sweptccd world-bench --scenario hands` and the engine's randomized suites
// at full-body size (docs/SKELETONS.md, "Full-body benchmark").

#include <Eigen/Core>
#include <Eigen/Geometry>

#include "core/avatar/joint_frame.h"
#include "core/avatar/joint_set.h"
#include "core/avatar/pose.h"
#include "core/avatar/skeleton.h"

namespace sweptccd::full_body {

/// The benchmark's grasp cycle, 3 s: open 0-1 s (reach), curl 1-1.4 s
/// (grasp), closed to 2.2 s (hold), open 2.2-2.6 s (release), open to 3 s.
double CycleCurl(double t_s);

/// Smooth step of x clamped to [0, 1] (3x^2 - 2x^3).
double SmoothStep(double x);

/// The frame the procedural fingers are built in, from a mocap hand link
/// pose: the wrist (the link's start), fwd (wrist to the link's end), lat
/// (the link's x axis made orthogonal to fwd) and normal = fwd x lat, the
/// back of the hand (fingers curl towards -normal).
struct HandFrame {
  Eigen::Vector3d wrist, fwd, lat, normal;
  Eigen::Quaterniond q;  // The hand link's orientation.
  /// The rotation whose columns are (fwd, lat, normal).
  Eigen::Quaterniond Basis() const;
};

/// Builds XR_META_body_tracking_full_body joint frames from poses of a
/// 16-link mocap skeleton (MocapLinkNames()). Aborts on a skeleton without
/// those links (a programming error).
class FrameBuilder {
 public:
  /// `set` must be FindJointSet("meta-full-body"); both must outlive this.
  FrameBuilder(const JointSet& set, const Skeleton& mocap);

  /// Fingers on the grasp cycle (CycleCurl), the left hand half a cycle
  /// after the right.
  JointFrame Build(const Pose& pose) const;
  /// Fingers at the given curls.
  JointFrame Build(const Pose& pose, double curl_left, double curl_right) const;

  /// The hand frame of the mocap pose's left or right hand.
  HandFrame Hand(const Pose& pose, bool left) const;

 private:
  int Index(const char* link) const;

  const JointSet& set_;
  const Skeleton& mocap_;
};

/// The meta-full-body skeleton (--hands full, 81 links) calibrated on
/// `first` (its bone lengths are the mocap skeleton's), with the length
/// tolerance the benchmarks use (5 cm or 25 %: the CMU clavicles move the
/// shoulders against the chest a little).
JointSkeleton CalibratedFullBody(const JointSet& set, const JointFrame& first);

}  // namespace sweptccd::full_body
