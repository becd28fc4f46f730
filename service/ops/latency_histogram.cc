#include "service/ops/latency_histogram.h"

#include <cmath>

namespace sweptccd {

void LatencyHistogram::ObserveMicros(double us) {
  const double s = (std::isnan(us) || us < 0) ? 0.0 : us * 1e-6;
  size_t i = 0;
  while (i < kBoundsS.size() && s > kBoundsS[i]) ++i;
  ++counts_[i];
  ++count_;
  sum_s_ += s;
}

}  // namespace sweptccd
