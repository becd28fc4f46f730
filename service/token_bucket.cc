#include "service/token_bucket.h"

#include <algorithm>
#include <cmath>

namespace sweptccd {

namespace {
constexpr int64_t kMaxPeriodUs = int64_t{1} << 40;  // About 12.7 days.
}  // namespace

TokenBucket::TokenBucket(double rate_hz, int burst)
    : period_us_(rate_hz >= 1e6 ? 1
                 : rate_hz > 1e6 / static_cast<double>(kMaxPeriodUs)
                     ? std::max<int64_t>(1, std::llround(1e6 / rate_hz))
                     : kMaxPeriodUs),
      burst_(std::clamp(burst, 1, 1 << 20)),
      tolerance_us_((burst_ - 1) * period_us_),
      theoretical_us_(0) {}

bool TokenBucket::TryTake(int64_t now_us) {
  if (!started_) {
    started_ = true;
    theoretical_us_ = now_us + period_us_;
    return true;
  }
  // Too early: the bucket would be empty (fewer than one token).
  if (now_us < theoretical_us_ - tolerance_us_) return false;
  theoretical_us_ = std::max(theoretical_us_, now_us) + period_us_;
  return true;
}

RejectionThrottle::RejectionThrottle(double rate_hz, int burst, int max_keys)
    : rate_hz_(rate_hz),
      burst_(burst),
      max_keys_(std::max(0, max_keys)),
      overflow_{TokenBucket(rate_hz, burst)} {}

RejectionThrottle::Entry& RejectionThrottle::EntryFor(const std::string& key) {
  auto it = entries_.find(key);
  if (it != entries_.end()) return it->second;
  if (static_cast<int>(entries_.size()) >= max_keys_) return overflow_;
  return entries_.emplace(key, Entry{TokenBucket(rate_hz_, burst_)}).first->second;
}

int64_t RejectionThrottle::Admit(const std::string& key, int64_t now_us) {
  Entry& entry = EntryFor(key);
  if (!entry.bucket.TryTake(now_us)) {
    ++entry.suppressed;
    ++suppressed_total_;
    return -1;
  }
  const int64_t held_back = entry.suppressed;
  entry.suppressed = 0;
  return held_back;
}

}  // namespace sweptccd
