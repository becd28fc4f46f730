#include "sweptccd_client/pair_ledger.h"

#include <algorithm>

namespace sweptccd {

bool PairLedger::Sent(const tracker_pose_t& pose) {
  if (pose.seq <= last_seq_) {
    // The application numbers from anew (a new stream): what was answered or
    // pending belongs to the old one.
    pending_.clear();
    answered_.clear();
  }
  last_seq_ = pose.seq;
  pending_.push_back(pose);
  if (pending_.size() <= max_pending_) return true;
  pending_.pop_front();
  ++forgotten_;
  return false;
}

bool PairLedger::Answered(int64_t seq1) {
  while (!pending_.empty() && pending_.front().seq < seq1) pending_.pop_front();
  if (!answered_.insert(seq1).second) {
    ++repeats_;
    return false;
  }
  while (answered_.size() > max_remembered_) answered_.erase(answered_.begin());
  return true;
}

void PairLedger::Refused(int64_t seq) {
  pending_.erase(std::remove_if(pending_.begin(), pending_.end(),
                                [seq](const tracker_pose_t& p) { return p.seq == seq; }),
                 pending_.end());
}

std::vector<tracker_pose_t> PairLedger::ForResend(int64_t session) const {
  std::vector<tracker_pose_t> out(pending_.begin(), pending_.end());
  for (tracker_pose_t& p : out) p.session = session;
  return out;
}

}  // namespace sweptccd
