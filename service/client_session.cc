#include "service/client_session.h"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <utility>

#include "core/errors.h"

namespace sweptccd {

namespace {

std::string Num(double v) {
  char buf[64];
  std::snprintf(buf, sizeof(buf), "%.17g", v);
  return buf;
}

}  // namespace

Rejection PoseRejection(const PoseProblem& problem, const std::string& where) {
  const std::string& link = where;
  const std::string component =
      "[" + std::to_string(problem.component) + "] is " + Num(problem.value);
  switch (problem.kind) {
    case PoseProblem::Kind::kNonFinite:
      return Rejection{rejection_code::kNonFinite,
                       link + (problem.in_orientation ? "orientation" : "position") + component +
                           "; send finite numbers"};
    case PoseProblem::Kind::kPositionOutOfRange:
      return Rejection{
          rejection_code::kPositionOutOfRange,
          link + "position" + component + " m, beyond 1e9 m; send metres in the " + "world frame"};
    case PoseProblem::Kind::kZeroQuaternion:
      return Rejection{rejection_code::kZeroQuaternion,
                       link + "quaternion norm " + Num(problem.value) +
                           " is below 1e-6; send a rotation as [w x y z]"};
    case PoseProblem::Kind::kLinkCount:
      break;  // Checked on the message's arrays before a Pose exists.
  }
  return Rejection{rejection_code::kWrongLinkCount,
                   "got " + Num(problem.value) + " link poses; send one pose per skeleton link"};
}

uint64_t UtimeJump(int64_t last, int64_t utime) {
  SWEPTCCD_CHECK(utime > last);
  // utime > last, so the difference fits in uint64 (wrapping is defined).
  return static_cast<uint64_t>(utime) - static_cast<uint64_t>(last);
}

namespace {

// An avatar's pose problem, placed at its link.
Rejection ToRejection(const PoseProblem& problem) {
  return PoseRejection(problem, "link " + std::to_string(problem.link) + ": ");
}

}  // namespace

std::optional<Rejection> ValidateTrackerPose(const tracker_pose_t& msg, int num_links, Pose* pose) {
  if (msg.num_links != num_links || static_cast<int64_t>(msg.position.size()) != num_links ||
      static_cast<int64_t>(msg.orientation.size()) != num_links) {
    return Rejection{rejection_code::kWrongLinkCount,
                     "num_links is " + std::to_string(msg.num_links) + " (arrays " +
                         std::to_string(msg.position.size()) + "/" +
                         std::to_string(msg.orientation.size()) + ") but the skeleton of client '" +
                         msg.client_id + "' has " + std::to_string(num_links) +
                         " links; send one pose per skeleton link, in link index order"};
  }
  for (int i = 0; i < num_links; ++i) {
    if (msg.position[i].size() != 3 || msg.orientation[i].size() != 4) {
      return Rejection{rejection_code::kWrongLinkCount,
                       "link " + std::to_string(i) + ": position has " +
                           std::to_string(msg.position[i].size()) + " values and orientation " +
                           std::to_string(msg.orientation[i].size()) + "; send 3 and 4 per link"};
    }
  }
  pose->utime = msg.utime;
  pose->links.assign(num_links, LinkPose{});
  for (int i = 0; i < num_links; ++i) {
    const auto& p = msg.position[i];
    const auto& q = msg.orientation[i];
    pose->links[i].p = Eigen::Vector3d(p[0], p[1], p[2]);
    pose->links[i].q = Eigen::Quaterniond(q[0], q[1], q[2], q[3]);  // w, x, y, z
  }
  // The rule is core's (FindPoseProblem); the wording is the service's.
  const std::optional<PoseProblem> problem = FindPoseProblem(*pose, num_links);
  if (problem) return ToRejection(*problem);
  const std::string error = ValidateAndNormalizePose(pose, num_links);
  SWEPTCCD_CHECK(error.empty());  // Same rule as FindPoseProblem just passed.
  return std::nullopt;
}

ClientSession::ClientSession(std::string client_id, int num_links, int64_t max_utime_jump_us)
    : client_id_(std::move(client_id)),
      num_links_(num_links),
      max_utime_jump_us_(max_utime_jump_us) {
  SWEPTCCD_CHECK(num_links_ > 0);
  SWEPTCCD_CHECK(max_utime_jump_us_ > 0);
}

std::optional<Rejection> ClientSession::CheckOrder(const tracker_pose_t& msg) const {
  if (!last_ || msg.session > session_) return std::nullopt;  // A new stream.
  if (msg.session < session_) {
    return Rejection{
        rejection_code::kStaleSession,
        "session " + std::to_string(msg.session) + " is older than the current " +
            std::to_string(session_) +
            "; a restarted tracker takes a greater session (e.g. its start time in us)"};
  }
  if (msg.seq <= last_->seq) {
    return Rejection{rejection_code::kNonIncreasingSeq,
                     "seq " + std::to_string(msg.seq) + " is not greater than " +
                         std::to_string(last_->seq) +
                         " of the last accepted pose; number poses strictly increasing"};
  }
  if (msg.utime <= last_->pose.utime) {
    return Rejection{rejection_code::kNonIncreasingUtime,
                     "utime " + std::to_string(msg.utime) + " is not greater than " +
                         std::to_string(last_->pose.utime) +
                         " of the last accepted pose; stamp samples strictly increasing"};
  }
  const uint64_t jump = UtimeJump(last_->pose.utime, msg.utime);
  if (jump > static_cast<uint64_t>(max_utime_jump_us_)) {
    return Rejection{rejection_code::kUtimeJump,
                     "utime " + std::to_string(msg.utime) + " is " + std::to_string(jump) +
                         " us after the last accepted pose, beyond the " +
                         std::to_string(max_utime_jump_us_) +
                         " us horizon; stamp in microseconds, or start a new session"};
  }
  return std::nullopt;
}

std::optional<Rejection> ClientSession::OnPose(const tracker_pose_t& msg, int64_t receive_utime,
                                               SteadyClock::time_point receive_time) {
  ++poses_received_;
  Pose pose;
  std::optional<Rejection> rejection = ValidateTrackerPose(msg, num_links_, &pose);
  if (!rejection) rejection = CheckOrder(msg);
  if (rejection) {
    ++rejected_;
    return rejection;
  }
  if (last_ && msg.session > session_) last_.reset();  // No pair across sessions.
  if (!last_) {
    ++streams_started_;
    session_ = msg.session;
  }
  ++poses_accepted_;
  if (last_) {
    // msg.seq > last_->seq here; the difference fits in uint64 (saturated below).
    const uint64_t missing = static_cast<uint64_t>(msg.seq) - static_cast<uint64_t>(last_->seq) - 1;
    const uint64_t room = static_cast<uint64_t>(INT64_MAX - seq_gaps_);
    seq_gaps_ += static_cast<int64_t>(std::min(missing, room));
    if (pending_ && pending_->session == session_) {
      // Latest wins: (A, B) pending and C arrives -> (A, C); (A, B) and
      // (B, C) are answered as one, so one pair is skipped.
      pending_->seq1 = msg.seq;
      pending_->pose1 = pose;
      ++pairs_skipped_;
    } else {
      // A pair of an older stream still pending is replaced (latest wins,
      // one pair skipped): no pair spans two sessions.
      if (pending_) ++pairs_skipped_;
      pending_.emplace();
      pending_->session = session_;
      pending_->seq0 = last_->seq;
      pending_->pose0 = last_->pose;
      pending_->seq1 = msg.seq;
      pending_->pose1 = pose;
    }
    pending_->receive_utime = receive_utime;
    pending_->receive_time = receive_time;
  }
  last_ = Accepted{msg.seq, std::move(pose)};
  return std::nullopt;
}

PosePair ClientSession::TakePair() {
  SWEPTCCD_CHECK(ready());
  PosePair pair = std::move(*pending_);
  pending_.reset();
  pair.pair = pairs_taken_++;
  pair.skipped_pairs_total = pairs_skipped_;
  in_flight_ = true;
  return pair;
}

void ClientSession::FinishPair() {
  SWEPTCCD_CHECK(in_flight_);
  in_flight_ = false;
  ++pairs_finished_;
}

}  // namespace sweptccd
