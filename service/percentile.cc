#include "service/percentile.h"

#include <algorithm>
#include <cmath>
#include <cstddef>

namespace sweptccd {

double Percentile(std::vector<double> samples, double q) {
  if (samples.empty()) return 0;
  const double rank = std::floor(q * static_cast<double>(samples.size()));
  const size_t k = std::min(samples.size() - 1, static_cast<size_t>(std::max(0.0, rank)));
  std::nth_element(samples.begin(), samples.begin() + static_cast<std::ptrdiff_t>(k),
                   samples.end());
  return samples[k];
}

}  // namespace sweptccd
