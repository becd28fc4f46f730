#pragma once
// The one percentile rule of the service's status (latency median and p99)
// and of `sweptccd monitor`'s summary.

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

}  // namespace sweptccd
