// Percentile against its brute-force twin: the smallest sample x with more
// than q * n samples <= x (the largest when none has), found by counting.
#include "core/percentile.h"

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

// Summarise, what every benchmark table prints, by the same rule: its median
// and p99 are the brute-force twin's, its max the largest sample, its mean
// the sum over the count.
TEST(PercentileTest, SummariseUsesTheSameRule) {
  std::mt19937_64 rng(20261128);
  std::uniform_int_distribution<int> size(1, 300);
  std::uniform_int_distribution<int> small_value(0, 9);
  for (int trial = 0; trial < 500; ++trial) {
    std::vector<double> samples(size(rng));
    for (double& v : samples) v = small_value(rng) + (trial % 2 ? 0.25 * small_value(rng) : 0);
    const Summary s = Summarise(samples);
    ASSERT_EQ(s.n, samples.size());
    ASSERT_EQ(s.median, BruteForcePercentile(samples, 0.5)) << "n " << samples.size();
    ASSERT_EQ(s.p99, BruteForcePercentile(samples, 0.99)) << "n " << samples.size();
    ASSERT_EQ(s.max, *std::max_element(samples.begin(), samples.end()));
    double sum = 0;
    for (double v : samples) sum += v;  // Multiples of 0.25 below 2^40: exact sums.
    ASSERT_EQ(s.mean, sum / static_cast<double>(samples.size()));
  }
  const Summary none = Summarise({});
  EXPECT_EQ(none.n, 0u);
  EXPECT_EQ(none.median, 0);
  EXPECT_EQ(none.p99, 0);
  EXPECT_EQ(none.max, 0);
  EXPECT_EQ(none.mean, 0);
  // Where the rank rules the tools used before gave other samples: the
  // upper median of 4 (floor(q (n - 1)) gave the lower), the largest of 100
  // for p99 (floor(q (n - 1)) and round(q (n - 1)) gave the 99th).
  EXPECT_EQ(Summarise({1, 2, 3, 4}).median, 3);
  std::vector<double> hundred;
  for (int i = 1; i <= 100; ++i) hundred.push_back(i);
  EXPECT_EQ(Summarise(hundred).p99, 100);
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
