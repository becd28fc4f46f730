#pragma once
// A cumulative latency histogram with fixed bucket bounds, as Prometheus
// exposes one (docs/DEPLOY.md "Metrics"): counts since start, never reset,
// so a scraper's rate() works across scrapes. Not thread-safe: the owner
// (CollisionService, under its mutex) observes and copies it.

#include <array>
#include <cstddef>
#include <cstdint>

namespace sweptccd {

class LatencyHistogram {
 public:
  /// Upper bounds of the finite buckets, seconds (le="..."), increasing;
  /// +Inf follows them. From 50 us (a CPU pair) to 1 s (a stalled worker).
  static constexpr std::array<double, 14> kBoundsS = {50e-6,  100e-6, 200e-6, 500e-6, 1e-3,
                                                      2e-3,   5e-3,   10e-3,  20e-3,  50e-3,
                                                      100e-3, 200e-3, 500e-3, 1.0};

  /// Counts one latency in microseconds (a negative or NaN one as 0).
  void ObserveMicros(double us);

  /// Observations in bucket i (not cumulative); i == kBoundsS.size() is +Inf.
  int64_t bucket(size_t i) const { return counts_[i]; }
  int64_t count() const { return count_; }
  double sum_s() const { return sum_s_; }

 private:
  std::array<int64_t, kBoundsS.size() + 1> counts_{};
  int64_t count_ = 0;
  double sum_s_ = 0;
};

}  // namespace sweptccd
