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

/// Components of a normalised quaternion below this magnitude are set to 0
/// (a rotation moves by less than 1e-135): every product of two components
/// is then 0 or at least 2^-900, the domain where SPEC 3's shortest-arc
/// sign is decided exactly (internal::DotSign in core/avatar/motion.h).
inline constexpr double kTinyQuaternionComponent = 0x1p-450;
/// Sets q's components below kTinyQuaternionComponent in magnitude to 0.
void FlushTinyComponents(Eigen::Quaterniond* q);

/// Checks `pose` (FindPoseProblem) and, when valid, normalises its
/// quaternions (then FlushTinyComponents). Returns an empty string when valid, else the problem as
/// PoseProblem::Describe words it (the pose is then left as it was).
std::string ValidateAndNormalizePose(Pose* pose, int num_links);

/// Parses one pose line `{"utime": ..., "links": [[px,py,pz,qw,qx,qy,qz], ...]}`
/// and validates it. On failure returns nullopt and sets `*error`.
std::optional<Pose> ParsePoseLine(const std::string& line, int num_links, std::string* error);

/// The structural half of ParsePoseLine: a JSON object with an integral
/// `utime` (1000000.0 accepted) and `num_links` arrays of 7 numbers, returned
/// as written (not validated, quaternions not normalised). `num_links` < 0
/// accepts any non-empty `links` array. On failure returns nullopt and sets
/// `*error` (the same words as ParsePoseLine).
std::optional<Pose> ParsePoseLineAsWritten(const std::string& line, int num_links,
                                           std::string* error);

/// The longest pose line the readers hold, by default: 7 numbers of up to 64
/// bytes each (a double needs at most 24, plus separators) per link, plus
/// 4 KiB for the rest. `num_links` < 0 (unknown) counts kDefaultMaxLinks.
uint64_t DefaultMaxPoseLineBytes(int num_links);

/// One counted (non-blank) line of a pose stream.
struct PoseLine {
  int64_t line_number = 0;   // 1-based, blank lines included.
  std::optional<Pose> pose;  // As written (ParsePoseLineAsWritten), or empty.
  std::string error;         // "line N: why" when `pose` is empty.
};

/// Reads a SPEC pose stream line by line, holding at most one line of at most
/// `max_line_bytes` bytes (0: DefaultMaxPoseLineBytes(num_links)). Blank lines
/// (only whitespace) are skipped and not counted. A longer line is read to its
/// newline without being kept and yields an error ("longer than the cap"),
/// like any other malformed line (SPEC 2: an invalid pose, not a fatal error).
/// `num_links` < 0: the first line that parses fixes the count. Holds a
/// reference to the stream. Not thread-safe.
class PoseLineReader {
 public:
  PoseLineReader(std::istream& in, int num_links, uint64_t max_line_bytes = 0);

  /// The next counted line, or nullopt at the end of the stream.
  std::optional<PoseLine> Next();
  /// True when reading failed (not at the end of the stream).
  bool bad() const { return in_.bad(); }
  /// The link count lines are checked against (-1 until one line parsed when
  /// constructed with -1).
  int num_links() const { return num_links_; }
  uint64_t max_line_bytes() const { return max_line_bytes_; }

 private:
  std::istream& in_;
  int num_links_;
  uint64_t max_line_bytes_;
  int64_t line_number_ = 0;
  std::string line_;
};

/// Serialises a pose as one SPEC pose line (no newline).
std::string PoseToJsonLine(const Pose& pose);

/// Whether two poses hold the same numbers, bit for bit (utime, every link's
/// position and quaternion; -0.0 is not 0.0): a motion built from either is
/// the same, bit for bit.
bool SamePose(const Pose& x, const Pose& y);

/// What one pose line yields under the pairing rule of SPEC section 2.
struct PairOutcome {
  int64_t pair = 0;               // k - 1 for the k-th counted line.
  bool valid = false;             // True: (pose0, pose1) is a pair to query.
  std::string error;              // Why the record is invalid.
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

/// Validates the pose of one counted line (ValidateAndNormalizePose) and
/// feeds it to `pairer`: a pose with a problem is fed as invalid, `*error`
/// set to "line N: problem" (N = `line_number`); `pose` empty means the line
/// did not parse, `*error` saying why. Returns what the pairer returns. The
/// one wording of pose-stream records, shared by PoseStreamReader and the
/// Python engine (python/, whose array rows are lines).
std::optional<PairOutcome> FeedCountedPose(PosePairer* pairer, std::optional<Pose> pose,
                                           int64_t line_number, int num_links, std::string* error);

/// A SPEC pose stream file read line by line (PoseLineReader: blank lines not
/// counted, lines over `max_line_bytes` (0: the default cap) invalid), each
/// counted line validated (ValidateAndNormalizePose, so as ParsePoseLine) and
/// paired (PosePairer). Holds a reference to the stream. Not thread-safe.
class PoseStreamReader {
 public:
  PoseStreamReader(std::istream& in, int num_links, uint64_t max_line_bytes = 0)
      : lines_(in, num_links, max_line_bytes), num_links_(num_links) {}

  /// The next record, or nullopt at the end of the stream.
  std::optional<PairOutcome> Next();
  /// Why the first counted line (which yields no record) could not be
  /// parsed, as "line N: ..."; empty when it could.
  const std::string& first_line_error() const { return first_line_error_; }
  /// True when reading failed (not at the end of the stream).
  bool bad() const { return lines_.bad(); }

 private:
  PoseLineReader lines_;
  int num_links_;
  PosePairer pairer_;
  std::string first_line_error_;
};

}  // namespace sweptccd
