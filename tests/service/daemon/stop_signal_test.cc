// StopSignal: SIGTERM and SIGINT become a readable pipe, not a dead process.
#include "service/daemon/stop_signal.h"

#include <gtest/gtest.h>
#include <poll.h>
#include <signal.h>

#include <chrono>

namespace sweptccd {
namespace {

TEST(StopSignalTest, SignalWakesTheWaiterInsteadOfKillingTheProcess) {
  const StopSignal stop;
  EXPECT_FALSE(stop.stopped());
  // A deadline in the past: returns at once, nothing arrived.
  EXPECT_FALSE(stop.WaitUntil(std::chrono::steady_clock::now()));
  ASSERT_EQ(raise(SIGTERM), 0);  // Handled: the test goes on.
  EXPECT_TRUE(stop.stopped());
  EXPECT_TRUE(stop.WaitUntil(std::chrono::steady_clock::time_point::max()));
  stop.Wait();  // Already signalled: returns at once.
  pollfd p{stop.fd(), POLLIN, 0};
  EXPECT_EQ(poll(&p, 1, 0), 1);
  // A second StopSignal shares the one pipe (handlers install once).
  const StopSignal again;
  EXPECT_EQ(again.fd(), stop.fd());
  ASSERT_EQ(raise(SIGINT), 0);
  EXPECT_TRUE(again.stopped());
}

}  // namespace
}  // namespace sweptccd
