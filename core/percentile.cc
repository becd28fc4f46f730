#include "core/percentile.h"

#include <algorithm>
#include <cmath>
#include <cstddef>

namespace sweptccd {

namespace {

// The 0-based rank of the q-percentile among n > 0 sorted samples.
size_t RankOf(size_t n, double q) {
  const double rank = std::floor(q * static_cast<double>(n));
  return std::min(n - 1, static_cast<size_t>(std::max(0.0, rank)));
}

}  // namespace

double Percentile(std::vector<double> samples, double q) {
  if (samples.empty()) return 0;
  const size_t k = RankOf(samples.size(), q);
  std::nth_element(samples.begin(), samples.begin() + static_cast<std::ptrdiff_t>(k),
                   samples.end());
  return samples[k];
}

Summary Summarise(std::vector<double> samples) {
  Summary s;
  if (samples.empty()) return s;
  std::sort(samples.begin(), samples.end());
  s.n = samples.size();
  s.median = samples[RankOf(s.n, 0.5)];
  s.p99 = samples[RankOf(s.n, 0.99)];
  s.max = samples.back();
  double sum = 0;
  for (double x : samples) sum += x;
  s.mean = sum / static_cast<double>(s.n);
  return s;
}

}  // namespace sweptccd
