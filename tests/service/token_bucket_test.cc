#include "service/token_bucket.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <random>
#include <vector>

namespace sweptccd {
namespace {

// The twin: a token bucket in exact integer arithmetic. One token is
// `period_us` units; every microsecond adds one unit, up to `burst` tokens;
// an event takes a token when a whole one is there. The bucket under test
// keeps a theoretical arrival time instead (GCRA); both admit the same events.
class CountingBucket {
 public:
  CountingBucket(int64_t period_us, int burst)
      : period_us_(period_us), capacity_(burst * period_us), units_(capacity_) {}
  bool Admit(int64_t t) {
    if (started_ && t > last_) units_ = std::min(capacity_, units_ + (t - last_));
    if (!started_ || t > last_) last_ = t;
    started_ = true;
    if (units_ < period_us_) return false;
    units_ -= period_us_;
    return true;
  }

 private:
  int64_t period_us_;
  int64_t capacity_;
  int64_t units_;
  int64_t last_ = 0;
  bool started_ = false;
};

TEST(TokenBucketTest, AdmitsTheBurstThenTheRate) {
  TokenBucket bucket(100.0, 5);  // 100 Hz, burst 5.
  int admitted = 0;
  for (int i = 0; i < 20; ++i) admitted += bucket.TryTake(1'000'000);
  EXPECT_EQ(admitted, 5);
  EXPECT_FALSE(bucket.TryTake(1'000'000 + 9'000));  // 0.9 tokens.
  EXPECT_TRUE(bucket.TryTake(1'000'000 + 10'000));
  // A long pause refills to the burst, not beyond.
  admitted = 0;
  for (int i = 0; i < 20; ++i) admitted += bucket.TryTake(60'000'000);
  EXPECT_EQ(admitted, 5);
}

TEST(TokenBucketTest, TimeGoingBackwardsDoesNotRefill) {
  TokenBucket bucket(1000.0, 1);
  EXPECT_TRUE(bucket.TryTake(5'000'000));
  EXPECT_FALSE(bucket.TryTake(4'000'000));
  EXPECT_FALSE(bucket.TryTake(5'000'500));
  EXPECT_TRUE(bucket.TryTake(5'001'000));
}

TEST(TokenBucketTest, MatchesTheVirtualSchedulingTwinOnRandomArrivals) {
  std::mt19937_64 rng(20261123);
  int64_t compared = 0, admitted_total = 0;
  for (int trial = 0; trial < 200; ++trial) {
    const int64_t period_us = std::uniform_int_distribution<int64_t>(1, 50)(rng) * 1000;
    const int burst = std::uniform_int_distribution<int>(1, 8)(rng);
    TokenBucket bucket(1e6 / static_cast<double>(period_us), burst);
    CountingBucket twin(period_us, burst);
    int64_t t = std::uniform_int_distribution<int64_t>(0, 1'000'000'000)(rng);
    const int64_t mean_gap = std::uniform_int_distribution<int64_t>(1, 3)(rng) * period_us / 2;
    std::exponential_distribution<double> gap(1.0 / static_cast<double>(mean_gap));
    for (int i = 0; i < 500; ++i) {
      // Exact boundaries included: gaps are whole periods now and then.
      t += (i % 7 == 0) ? period_us : static_cast<int64_t>(gap(rng));
      const bool got = bucket.TryTake(t);
      ASSERT_EQ(got, twin.Admit(t)) << "trial " << trial << " event " << i << " t " << t;
      admitted_total += got;
      ++compared;
    }
  }
  EXPECT_EQ(compared, 100'000);
  EXPECT_GT(admitted_total, 10'000);
  EXPECT_LT(admitted_total, compared);
}

TEST(RejectionThrottleTest, PublishesAtTheRateAndCountsWhatItHeldBack) {
  RejectionThrottle throttle(10.0, 2, 16);
  EXPECT_EQ(throttle.Admit("alice", 0), 0);
  EXPECT_EQ(throttle.Admit("alice", 0), 0);
  for (int i = 0; i < 7; ++i) EXPECT_EQ(throttle.Admit("alice", 1000), -1);
  // Another key has its own bucket.
  EXPECT_EQ(throttle.Admit("bob", 1000), 0);
  // 0.1 s later alice's next published rejection says 7 were held back.
  EXPECT_EQ(throttle.Admit("alice", 100'000), 7);
  EXPECT_EQ(throttle.Admit("alice", 100'001), -1);
  EXPECT_EQ(throttle.suppressed_total(), 8);
}

TEST(RejectionThrottleTest, InventedKeysShareOneBucketBeyondTheCap) {
  RejectionThrottle throttle(1.0, 1, 4);
  int published = 0;
  for (int i = 0; i < 10'000; ++i) {
    published += throttle.Admit("id" + std::to_string(i), 1'000'000) >= 0;
  }
  // 4 keys of their own, then one shared bucket: 5 published in all.
  EXPECT_EQ(published, 5);
  EXPECT_EQ(throttle.suppressed_total(), 10'000 - 5);
}

}  // namespace
}  // namespace sweptccd
