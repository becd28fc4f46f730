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

/// Checks finiteness and quaternion norms and normalises the quaternions.
/// Returns an empty string when valid, else a message naming the link.
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
