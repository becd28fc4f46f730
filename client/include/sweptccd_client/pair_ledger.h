#pragma once
// The client's side of failover (docs/WEBSOCKET.md section 9, docs/DEPLOY.md
// "Failover"): the poses whose pair is not answered yet (re-sent after a
// re-join, so no pair is lost), the pairs already delivered (an answer
// repeated by a new server is dropped, so none is delivered twice), and the
// epoch fence (events of an older daemon instance are dropped).
//
// A pair is named by its second pose's seq (seq1): the client numbers its
// poses, and a re-sent pose keeps its seq and utime, so the new server's pair
// (seq0, seq1) is the old one's.

#include <climits>
#include <cstddef>
#include <cstdint>
#include <deque>
#include <set>
#include <vector>

#include "sweptccd/tracker_pose_t.hpp"

namespace sweptccd {

class PairLedger {
 public:
  explicit PairLedger(size_t max_pending = 4096, size_t max_remembered = 8192)
      : max_pending_(max_pending), max_remembered_(max_remembered) {}

  /// A pose handed to the client (sent now or later). False when the oldest
  /// pending pose had to be forgotten (max_pending): its pair may be lost.
  /// A seq not above the previous pose's starts a new stream (the
  /// application numbers from anew): the old stream's poses and answers are
  /// forgotten.
  bool Sent(const tracker_pose_t& pose);
  /// An answer (contact_event) for the pair ending at seq1: true the first
  /// time (deliver it), false for a repeat. Forgets the poses before seq1
  /// (seq1 stays: it anchors the next pair).
  bool Answered(int64_t seq1);
  /// A refused pose (rejection other than unknown_client): it forms no pair.
  void Refused(int64_t seq);
  /// The poses to send again after a re-join, in order, under `session`:
  /// the last answered pose (the anchor) and every later one.
  std::vector<tracker_pose_t> ForResend(int64_t session) const;

  size_t pending() const { return pending_.size(); }
  int64_t forgotten() const { return forgotten_; }
  int64_t repeats() const { return repeats_; }

 private:
  size_t max_pending_, max_remembered_;
  std::deque<tracker_pose_t> pending_;
  std::set<int64_t> answered_;
  int64_t forgotten_ = 0, repeats_ = 0;
  int64_t last_seq_ = INT64_MIN;
};

/// The epoch fence: an event whose `instance` (the daemon run that sent it)
/// is not the instance this client joined is stale. `event_instance` 0
/// means the server did not say (a door before this field): not fenced.
inline bool IsStaleEpoch(int64_t event_instance, int64_t joined_instance) {
  return event_instance != 0 && event_instance != joined_instance;
}

}  // namespace sweptccd
