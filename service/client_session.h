#pragma once
// Per-client logic of the collision service: validation of tracker poses,
// pairing of consecutive accepted poses, and the latest-wins hand-out of pairs.
// Transport-free (no LCM runtime, only the generated message type) and
// single-threaded: CollisionService serialises all calls under its mutex.

#include <chrono>
#include <cstdint>
#include <optional>
#include <string>

#include "core/avatar/pose.h"
#include "sweptccd/tracker_pose_t.hpp"

namespace sweptccd {

/// Stable rejection codes (rejection_t.reason).
namespace rejection_code {
inline constexpr char kWrongLinkCount[] = "wrong_link_count";
inline constexpr char kNonFinite[] = "non_finite";
inline constexpr char kPositionOutOfRange[] = "position_out_of_range";
inline constexpr char kZeroQuaternion[] = "zero_quaternion";
inline constexpr char kUnknownClient[] = "unknown_client";
inline constexpr char kNonIncreasingSeq[] = "non_increasing_seq";
inline constexpr char kNonIncreasingUtime[] = "non_increasing_utime";
inline constexpr char kDecodeError[] = "decode_error";
inline constexpr char kBadClientId[] = "bad_client_id";   // Breaks the id rule (SPEC section 8).
inline constexpr char kBadSignature[] = "bad_signature";  // mac missing, wrong, or no key.
inline constexpr char kStaleSession[] = "stale_session";  // session below the client's current.
inline constexpr char kUtimeJump[] = "utime_jump";        // utime beyond the horizon.
inline constexpr char kRateLimited[] = "rate_limited";    // Over the client's input rate.
inline constexpr char kUnknownObject[] =
    "unknown_object";  // object_pose_t of no configured object.
}  // namespace rejection_code

/// Default horizon of the utime_jump rule: 10 s.
inline constexpr int64_t kDefaultMaxUtimeJumpUs = 10'000'000;  // namespace rejection_code

/// Why a tracker pose was refused: a code from rejection_code and a message
/// that names the value, the place and the fix.
struct Rejection {
  std::string reason;
  std::string message;
};

/// The rejection of a pose problem (FindPoseProblem, or an object's
/// FindRigidProblem): its code, and a message naming the value, the place
/// (`where`, e.g. "link 2: " or "object 'box' seq 7: ") and the fix. The
/// one wording of avatar and object poses.
Rejection PoseRejection(const PoseProblem& problem, const std::string& where);

/// How far `utime` is after `last` (precondition: utime > last), in
/// unsigned 64-bit arithmetic, where the difference of any two int64 fits
/// (signed, a hostile pair overflows). The one utime_jump rule of avatars
/// and objects: a jump beyond max_utime_jump_us is refused.
uint64_t UtimeJump(int64_t last, int64_t utime);

/// Checks one tracker message against a skeleton of `num_links` links (SPEC
/// section 2 plus the message's own consistency): link count, finite numbers,
/// positions within kMaxCoordinate, quaternion norms >= kMinQuaternionNorm.
/// On success fills `*pose` (quaternions normalised) and returns nullopt.
/// Does not look at seq/utime ordering (that needs the client's history).
std::optional<Rejection> ValidateTrackerPose(const tracker_pose_t& msg, int num_links, Pose* pose);

/// Steady clock used for queueing and latency measurements.
using SteadyClock = std::chrono::steady_clock;

/// A pair of accepted poses handed to a worker.
struct PosePair {
  int64_t pair = 0;     // Index among this client's handed-out pairs (0, 1, ...).
  int64_t session = 0;  // The stream both poses belong to.
  int64_t seq0 = 0, seq1 = 0;
  Pose pose0, pose1;
  int64_t receive_utime = 0;             // Wall clock (us) when pose1 was received.
  SteadyClock::time_point receive_time;  // Steady clock when pose1 was received.
  int64_t skipped_pairs_total = 0;       // The client's skipped count when handed out.
};

/// One client's poses. Pairs consecutive accepted poses of one stream; at
/// most one pair is pending (formed, not yet taken) and at most one in flight
/// (taken, not yet finished). When a pose is accepted while a pair is pending,
/// the pending pair (A, B) becomes (A, newest): latest wins, and one skipped
/// pair is counted. The first accepted pose of each stream pairs with nothing,
/// so at every moment
///   poses_accepted - streams_started == pairs_taken + pairs_skipped + (pending ? 1 : 0):
/// no pair is lost silently. Pairs are taken strictly in pose order, one at a
/// time.
///
/// Streams (docs/SERVICE.md, "Sessions"): the session remembers the current
/// `session` of tracker_pose_t. A pose with a greater session starts a new
/// stream (seq and utime may restart; no pair spans two sessions; a pair
/// still pending from the old stream is answered); a smaller one is refused
/// (stale_session); an equal one must have seq and utime strictly greater
/// than the last accepted pose's, and utime at most `max_utime_jump_us` past
/// it (utime_jump), so one bogus stamp cannot lock the stream out.
class ClientSession {
 public:
  /// `max_utime_jump_us` > 0.
  ClientSession(std::string client_id, int num_links,
                int64_t max_utime_jump_us = kDefaultMaxUtimeJumpUs);

  /// Offers a message (its client_id is not checked here). Returns the
  /// rejection, or nullopt when the pose was accepted (and possibly paired).
  std::optional<Rejection> OnPose(const tracker_pose_t& msg, int64_t receive_utime,
                                  SteadyClock::time_point receive_time);

  /// A pair is pending and none is in flight.
  bool ready() const { return pending_.has_value() && !in_flight_; }
  bool has_pending() const { return pending_.has_value(); }
  bool in_flight() const { return in_flight_; }

  /// Hands out the pending pair and marks it in flight. Precondition: ready().
  PosePair TakePair();
  /// The in-flight pair was answered. Precondition: in_flight().
  void FinishPair();

  const std::string& client_id() const { return client_id_; }
  int num_links() const { return num_links_; }
  int64_t poses_received() const { return poses_received_; }
  int64_t poses_accepted() const { return poses_accepted_; }
  int64_t rejected() const { return rejected_; }
  int64_t pairs_taken() const { return pairs_taken_; }
  int64_t pairs_finished() const { return pairs_finished_; }
  int64_t pairs_skipped() const { return pairs_skipped_; }
  /// seq numbers missing between consecutive accepted poses (lost or never
  /// sent); the pair of those two poses is still answered.
  int64_t seq_gaps() const { return seq_gaps_; }
  /// Streams begun: the first accepted pose, then each greater session.
  int64_t streams_started() const { return streams_started_; }
  /// The current stream's session; meaningful once a pose was accepted.
  int64_t session() const { return session_; }
  /// The newest accepted pose of the current stream (quaternions
  /// normalised), or null before the first.
  const Pose* last_pose() const { return last_ ? &last_->pose : nullptr; }

 private:
  // Session, seq, utime and horizon rules against the last accepted pose.
  std::optional<Rejection> CheckOrder(const tracker_pose_t& msg) const;

  struct Accepted {
    int64_t seq = 0;
    Pose pose;
  };

  std::string client_id_;
  int num_links_ = 0;
  int64_t max_utime_jump_us_ = kDefaultMaxUtimeJumpUs;
  int64_t session_ = 0;           // Of the current stream, once last_ is set.
  std::optional<Accepted> last_;  // Newest accepted pose of the current stream.
  std::optional<PosePair> pending_;
  bool in_flight_ = false;
  int64_t poses_received_ = 0;
  int64_t poses_accepted_ = 0;
  int64_t rejected_ = 0;
  int64_t pairs_taken_ = 0;
  int64_t pairs_finished_ = 0;
  int64_t pairs_skipped_ = 0;
  int64_t seq_gaps_ = 0;
  int64_t streams_started_ = 0;
};

}  // namespace sweptccd
