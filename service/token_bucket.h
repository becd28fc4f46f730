#pragma once
// Rate limits for what arrives from the network: a token bucket per client
// for poses, and a throttle for the rejections the service publishes.

#include <cstdint>
#include <map>
#include <string>

namespace sweptccd {

/// A token bucket: at most `burst` events at once, refilled at `rate_hz`,
/// kept as the generic cell rate algorithm (a theoretical arrival time in
/// integer microseconds, so no rounding accumulates). The period is
/// 1/rate_hz rounded to whole microseconds (at least 1 us). Time is passed
/// in (microseconds, any monotonic base), so the bucket is a pure function
/// of its inputs and testable without clocks.
///
/// Threading: not thread-safe; the owner serialises calls.
class TokenBucket {
 public:
  /// `rate_hz` > 0 and `burst` >= 1 (checked by the caller's configuration;
  /// smaller values are clamped to 1e-6 Hz and 1).
  TokenBucket(double rate_hz, int burst);

  /// Takes one token if there is one at `now_us`. Returns whether the event
  /// is admitted. A `now_us` earlier than a previous call does not refill.
  bool TryTake(int64_t now_us);

  int64_t period_us() const { return period_us_; }
  int burst() const { return burst_; }

 private:
  int64_t period_us_;
  int burst_;
  int64_t tolerance_us_;     // (burst - 1) periods.
  int64_t theoretical_us_;   // When the next event would conform at the steady rate.
  bool started_ = false;
};

/// Decides which rejections are published: at most `rate_hz` per key (a
/// client id, or "" for messages attributable to no registered client),
/// with a burst, and counts what it held back so that the next published
/// rejection of that key can say how many were suppressed. The number of
/// keys is bounded (`max_keys`); beyond it every key shares one bucket, so a
/// sender inventing ids cannot grow memory.
///
/// Threading: not thread-safe; the owner serialises calls.
class RejectionThrottle {
 public:
  RejectionThrottle(double rate_hz, int burst, int max_keys);

  /// Returns -1 when this rejection is held back (counted); otherwise the
  /// number held back for this key since its last published rejection (and
  /// resets that count).
  int64_t Admit(const std::string& key, int64_t now_us);

  /// Rejections held back so far, all keys.
  int64_t suppressed_total() const { return suppressed_total_; }

 private:
  struct Entry {
    TokenBucket bucket;
    int64_t suppressed = 0;
  };
  Entry& EntryFor(const std::string& key);

  double rate_hz_;
  int burst_;
  int max_keys_;
  std::map<std::string, Entry> entries_;
  Entry overflow_;
  int64_t suppressed_total_ = 0;
};

}  // namespace sweptccd
