// Percentile against its brute-force twin: the smallest sample x with more
// than q * n samples <= x (the largest when none has), found by counting.
#include "service/percentile.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <random>

namespace sweptccd {
namespace {

double BruteForcePercentile(const std::vector<double>& samples, double q) {
  if (samples.empty()) return 0;
  const double need = q * static_cast<double>(samples.size());
  double best = *std::max_element(samples.begin(), samples.end());
  for (double x : samples) {
    const auto at_or_below =
        std::count_if(samples.begin(), samples.end(), [x](double v) { return v <= x; });
    if (static_cast<double>(at_or_below) > need && x < best) best = x;
  }
  return best;
}

TEST(PercentileTest, MatchesTheBruteForceTwinOnRandomSamples) {
  std::mt19937_64 rng(20261123);
  std::uniform_int_distribution<int> size(1, 40);
  std::uniform_int_distribution<int> small_value(0, 9);  // Many ties.
  std::uniform_real_distribution<double> value(-1e3, 1e3);
  const double qs[] = {0, 0.01, 0.25, 0.5, 0.9, 0.99, 1};
  for (int trial = 0; trial < 3000; ++trial) {
    std::vector<double> samples(size(rng));
    for (double& v : samples) v = trial % 2 ? value(rng) : small_value(rng);
    for (double q : qs) {
      ASSERT_EQ(Percentile(samples, q), BruteForcePercentile(samples, q))
          << "trial " << trial << " q " << q << " n " << samples.size();
    }
    const double q = std::uniform_real_distribution<double>(0, 1)(rng);
    ASSERT_EQ(Percentile(samples, q), BruteForcePercentile(samples, q)) << "q " << q;
  }
}

TEST(PercentileTest, TheDocumentedRankRule) {
  EXPECT_EQ(Percentile({}, 0.5), 0);
  EXPECT_EQ(Percentile({7}, 0.99), 7);
  // Even count: the upper median. p99 of 100 samples: the largest.
  EXPECT_EQ(Percentile({4, 1, 3, 2}, 0.5), 3);
  std::vector<double> hundred;
  for (int i = 1; i <= 100; ++i) hundred.push_back(i);
  EXPECT_EQ(Percentile(hundred, 0.99), 100);
  EXPECT_EQ(Percentile(hundred, 0.5), 51);
  EXPECT_EQ(Percentile(hundred, 0), 1);
  EXPECT_EQ(Percentile(hundred, 1), 100);
}

}  // namespace
}  // namespace sweptccd
