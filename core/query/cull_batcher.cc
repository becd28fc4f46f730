#include "core/query/cull_batcher.h"

namespace sweptccd::internal {

void CullBatcher::AppendSubtree(LinkIndex link, double s0, double s1, const SegmentEnds& ends,
                                int levels) {
  const LinkCapsule c = bounds_.FromEnds(link, s0, s1, ends);
  batch_.push_back(c);
  keys_.push_back(Key{link, s0, s1});
  const double mid = 0.5 * (s0 + s1);
  if (levels == 0 || !(mid > s0 && mid < s1)) return;
  // c.a, c.b is the segment at mid.
  AppendSubtree(link, s0, mid, SegmentEnds{ends.a0, ends.b0, c.a, c.b}, levels - 1);
  AppendSubtree(link, mid, s1, SegmentEnds{c.a, c.b, ends.a1, ends.b1}, levels - 1);
}

bool CullBatcher::Flush() {
  if (batch_.empty() || culler_ == nullptr) return culler_ != nullptr;
  const bool ok = culler_->Cull(batch_, &may_touch_);
  if (ok) {
    ++stats_.cull_round_trips;
    stats_.cull_capsules += static_cast<int64_t>(batch_.size());
    for (size_t i = 0; i < keys_.size(); ++i) {
      answers_[keys_[i]] = CullAnswer{may_touch_[i] == 0, batch_[i]};
    }
  } else {
    culler_ = nullptr;  // Failed (logged by the culler): the CPU decides alone.
  }
  batch_.clear();
  keys_.clear();
  return ok;
}

const CullAnswer* CullBatcher::Find(LinkIndex link, double s0, double s1) const {
  const auto it = answers_.find(Key{link, s0, s1});
  return it == answers_.end() ? nullptr : &it->second;
}

const CullAnswer* CullBatcher::AnswerFor(const Interval& interval,
                                         const std::vector<Interval>& pending,
                                         const std::vector<bool>& done) {
  if (culler_ == nullptr) return nullptr;
  const CullAnswer* answer = Find(interval.link, interval.s0, interval.s1);
  if (answer != nullptr) return answer;
  AppendSubtree(interval.link, interval.s0, interval.s1, interval.ends, kLevels);
  const size_t per_interval = batch_.size();
  for (const Interval& t : pending) {
    if (batch_.size() + per_interval > kMaxBatch) break;
    if (done[t.link] || t.prefiltered || Find(t.link, t.s0, t.s1) != nullptr) continue;
    AppendSubtree(t.link, t.s0, t.s1, t.ends, kLevels);
  }
  Flush();
  return Find(interval.link, interval.s0, interval.s1);  // nullptr if the culler failed.
}

}  // namespace sweptccd::internal
