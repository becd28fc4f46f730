#pragma once
// The one percentile rule of the project: the service's status (latency
// median and p99), `sweptccd monitor`'s summary, the `world --bench` counts
// and every benchmark table (`bench`, `world-bench`, the service benches).

#include <cstddef>
#include <vector>

namespace sweptccd {

/// The q-percentile of `samples` (q in [0, 1]) by the upper-rank rule: with
/// the n samples sorted ascending, the one at 0-based index
/// min(n - 1, floor(q * n)). Equivalently, the smallest sample x with more
/// than q * n samples <= x (the largest sample when none has). So q = 0.5
/// gives the upper median of an even count, q = 0 the smallest sample and
/// q = 1 the largest. Returns 0 for no samples. Takes its argument by value
/// (it is partially reordered). Precondition: 0 <= q <= 1 and no NaN sample.
double Percentile(std::vector<double> samples, double q);

/// What a benchmark table prints of a sample: its count, median and p99 (both
/// by Percentile's rule), max and mean. No value is dropped; all zero for an
/// empty sample.
struct Summary {
  size_t n = 0;
  double median = 0, p99 = 0, max = 0, mean = 0;
};

/// The Summary of `samples`. Precondition: no NaN sample.
Summary Summarise(std::vector<double> samples);

}  // namespace sweptccd
