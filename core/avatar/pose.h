#pragma once
// Tracker poses and the pairing rule of SPEC section 2.

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <cstdint>
#include <istream>
#include <optional>
#include <string>
#include <vector>

namespace sweptccd {

/// World pose X_WL of one link frame: origin position p_WL and unit
/// orientation q_WL.
struct LinkPose {
  Eigen::Vector3d p{0, 0, 0};
  Eigen::Quaterniond q{1, 0, 0, 0};
};

/// One tracker sample: utime (microseconds) and one LinkPose per link.
struct Pose {
  int64_t utime = 0;
  std::vector<LinkPose> links;
};

/// Quaternions below this norm make a pose invalid (SPEC section 2).
inline constexpr double kMinQuaternionNorm = 1e-6;
/// Positions beyond this many metres from the origin make a pose invalid: the
/// geometry would overflow (1e308 squared) long before such numbers mean
/// anything for a tracked body.
inline constexpr double kMaxCoordinate = 1e9;

/// Why a pose is invalid under SPEC section 2: the one rule, shared by
/// `sweptccd query` (pose lines) and the collision service (tracker
/// messages), each wording it for its own users.
struct PoseProblem {
  enum class Kind {
    kLinkCount,           // `value` is the number of link poses given.
    kNonFinite,           // `value` is the NaN or infinity.
    kPositionOutOfRange,  // `value` is the coordinate, |value| > kMaxCoordinate.
    kZeroQuaternion,      // `value` is the norm, below kMinQuaternionNorm.
  };
  Kind kind = Kind::kLinkCount;
  int link = -1;                // The link index; -1 for kLinkCount.
  bool in_orientation = false;  // kNonFinite: in the quaternion, not the position.
  /// kNonFinite, kPositionOutOfRange: index in [x y z] or in [w x y z].
  int component = -1;
  double value = 0;

  /// The wording of `sweptccd query`'s records, e.g. "link 2: non-finite
  /// number" (`num_links` is what the skeleton has).
  std::string Describe(int num_links) const;
};

/// The first problem of `pose` for a skeleton of `num_links` links, or
/// nullopt: the link count, then link by link its non-finite numbers
/// (position x, y, z, then quaternion w, x, y, z), a coordinate beyond
/// kMaxCoordinate, a quaternion norm below kMinQuaternionNorm. Pure.
std::optional<PoseProblem> FindPoseProblem(const Pose& pose, int num_links);

/// Checks `pose` (FindPoseProblem) and, when valid, normalises its
/// quaternions. Returns an empty string when valid, else the problem as
/// PoseProblem::Describe words it (the pose is then left as it was).
std::string ValidateAndNormalizePose(Pose* pose, int num_links);

/// Parses one pose line `{"utime": ..., "links": [[px,py,pz,qw,qx,qy,qz], ...]}`
/// and validates it. On failure returns nullopt and sets `*error`.
std::optional<Pose> ParsePoseLine(const std::string& line, int num_links, std::string* error);

/// Serialises a pose as one SPEC pose line (no newline).
std::string PoseToJsonLine(const Pose& pose);

/// What one pose line yields under the pairing rule of SPEC section 2.
struct PairOutcome {
  int64_t pair = 0;          // k - 1 for the k-th counted line.
  bool valid = false;        // True: (pose0, pose1) is a pair to query.
  std::string error;         // Why the record is invalid.
  std::optional<int64_t> utime0;  // Known utimes, for the record.
  std::optional<int64_t> utime1;
  Pose pose0, pose1;
};

/// Applies SPEC section 2's pairing rule to a sequence of poses, one per
/// counted line. The first line yields no record; every later line yields one.
/// A valid pose becomes the anchor when it forms a pair, or when no anchor
/// exists yet. Not thread-safe; one instance per stream (or per client).
class PosePairer {
 public:
  /// Feeds the next counted line: its pose, or nullopt with `error` set.
  std::optional<PairOutcome> Feed(std::optional<Pose> pose, const std::string& error);
  bool has_anchor() const { return anchor_.has_value(); }

 private:
  int64_t lines_seen_ = 0;
  std::optional<Pose> anchor_;
};

/// A SPEC pose stream file read line by line: blank lines are not counted,
/// each counted line is parsed (ParsePoseLine) and paired (PosePairer). Holds
/// a reference to the stream. Not thread-safe.
class PoseStreamReader {
 public:
  PoseStreamReader(std::istream& in, int num_links) : in_(in), num_links_(num_links) {}

  /// The next record, or nullopt at the end of the stream.
  std::optional<PairOutcome> Next();
  /// Why the first counted line (which yields no record) could not be
  /// parsed, as "line N: ..."; empty when it could.
  const std::string& first_line_error() const { return first_line_error_; }
  /// True when reading failed (not at the end of the stream).
  bool bad() const { return in_.bad(); }

 private:
  std::istream& in_;
  int num_links_;
  int64_t line_number_ = 0;
  PosePairer pairer_;
  std::string first_line_error_;
};

}  // namespace sweptccd
