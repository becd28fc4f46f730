#pragma once
// One frame of a tracking runtime's joint poses, the skeleton a joint set
// gives (SPEC 1) and the conversion of a frame to a SPEC 2 pose
// (docs/SKELETONS.md, "Joint frames").

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <cstdint>
#include <limits>
#include <optional>
#include <string>
#include <vector>

#include "core/avatar/joint_set.h"
#include "core/avatar/pose.h"
#include "core/avatar/skeleton.h"

namespace sweptccd {

/// One joint's world pose as the runtime reports it.
struct JointSample {
  Eigen::Vector3d p{0, 0, 0};
  Eigen::Quaterniond q{1, 0, 0, 0};  // [w x y z]; normalised by the conversion.
  /// False when the runtime says the joint's pose is not valid or not
  /// tracked (OpenXR's location flags, WebXR's missing pose).
  bool valid = true;
  /// The runtime's joint radius in metres, or NaN when it gives none.
  double radius = std::numeric_limits<double>::quiet_NaN();
};

/// One frame: utime (microseconds) and one sample per joint, in the joint
/// set's order.
struct JointFrame {
  int64_t utime = 0;
  std::vector<JointSample> joints;
};

/// Parses one joint frame line:
///   {"utime": U, "joints": [[px,py,pz,qw,qx,qy,qz] or null, ...],
///    "valid": [true, ...], "radii": [0.01 or null, ...]}
/// `joints` has exactly `num_joints` entries; null marks a joint the runtime
/// does not track; `valid` (optional, same length) marks joints false too;
/// `radii` (optional, same length) gives the runtime's radii. Numbers are
/// not checked here (ConvertJointFrame does). On failure returns nullopt and
/// sets `*error` to one line ("joints: 83 entries, the joint set has 84").
std::optional<JointFrame> ParseJointFrameLine(const std::string& line, int num_joints,
                                              std::string* error);

/// The longest joint frame line the readers hold: 8 numbers of up to 64
/// bytes and a flag per joint, plus 4 KiB.
uint64_t MaxJointFrameLineBytes(int num_joints);

/// Serialises a frame as one joint frame line (no newline): tests, tools.
std::string JointFrameToJsonLine(const JointFrame& frame);

struct JointSkeletonOptions {
  /// The user's height in metres (0.5..2.5): scales the default lengths and
  /// radii (joint_sets/anthropometry.h).
  double height_m = 1.75;
  HandsOption hands = HandsOption::kFull;
  /// A frame whose joint distances set the bones' lengths (and, for joint
  /// sets with runtime radii, whose radii set the links' radii): e.g. the
  /// runtime's reference skeleton (xrGetBodySkeletonFB) or a first frame.
  /// Null: the defaults scaled by height_m.
  const JointFrame* calibration = nullptr;
  /// A frame's bone may differ from its link's length by at most
  /// max(length_tolerance_m, length_tolerance_fraction * length); beyond it
  /// the frame is invalid (its capsule would be off by more).
  double length_tolerance_m = 0.01;
  double length_tolerance_fraction = 0.05;
};

/// A joint set's skeleton and the conversion of its joint frames. Immutable
/// after Build(); safe to share between threads.
///
/// Link frames: a link's origin is its joint_a; its +Y axis points along the
/// bone (towards joint_b, or away from joint_from for an extension), its
/// twist is joint_a's orientation turned by the shortest arc that takes
/// joint_a's +Y onto the bone; a sphere's frame is joint_a's pose. In that
/// frame a = (0, 0, 0) and b = (0, length, 0).
class JointSkeleton {
 public:
  /// `set` must outlive the result (FindJointSet's sets live for the whole
  /// program). Throws InputError: a height out of range, --hands none on a hand-only
  /// set, a calibration frame of the wrong size or with an invalid joint a
  /// link needs.
  static JointSkeleton Build(const JointSet& set, const JointSkeletonOptions& options);

  const JointSet& joint_set() const { return *set_; }
  const Skeleton& skeleton() const { return skeleton_; }
  const std::vector<PlannedLink>& plan() const { return plan_; }
  /// Whether some link uses joint j (only those joints are checked).
  bool uses_joint(int j) const { return used_[j]; }

  /// Converts `frame` into `*pose` (utime and one link pose per link,
  /// normalised as ValidateAndNormalizePose leaves it). Returns "" on
  /// success, else the one-line problem and leaves `*pose` untouched: a
  /// wrong joint count, a joint a link needs that is not valid, a
  /// non-finite or out-of-range number, a zero quaternion where an
  /// orientation is needed, or a bone whose length is beyond the tolerance.
  /// Joints no link uses are not looked at. Thread-safe.
  std::string Convert(const JointFrame& frame, Pose* pose) const;

 private:
  const JointSet* set_ = nullptr;
  JointSkeletonOptions options_;
  std::vector<PlannedLink> plan_;
  std::vector<double> length_;  // By link.
  std::vector<bool> used_;      // By joint.
  Skeleton skeleton_;
};

}  // namespace sweptccd
