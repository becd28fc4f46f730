// Failover bookkeeping (client/pair_ledger.cc): pending poses re-sent after
// a re-join from the last answered one, answers repeated by a new server
// dropped, the epoch fence.
#include "sweptccd_client/pair_ledger.h"

#include <gtest/gtest.h>

namespace sweptccd {
namespace {

tracker_pose_t Pose(int64_t seq) {
  tracker_pose_t p{};
  p.seq = seq;
  p.utime = 1000000 + seq * 10000;
  p.session = 7;
  return p;
}

std::vector<int64_t> Seqs(const std::vector<tracker_pose_t>& v) {
  std::vector<int64_t> s;
  for (const auto& p : v) s.push_back(p.seq);
  return s;
}

TEST(PairLedgerTest, ResendFromTheLastAnsweredPose) {
  PairLedger l;
  for (int64_t s = 0; s < 6; ++s) EXPECT_TRUE(l.Sent(Pose(s)));
  EXPECT_TRUE(l.Answered(1));
  EXPECT_TRUE(l.Answered(2));
  // Pairs (2,3), (3,4), (4,5) unanswered when the room died: pose 2 anchors.
  const auto again = l.ForResend(99);
  EXPECT_EQ(Seqs(again), (std::vector<int64_t>{2, 3, 4, 5}));
  for (const auto& p : again) EXPECT_EQ(p.session, 99);
  EXPECT_EQ(again[1].utime, Pose(3).utime);
  // The new server answers (2,3) again? No: it answers (2,3) once; a repeat
  // of an already delivered pair is dropped.
  EXPECT_TRUE(l.Answered(3));
  EXPECT_FALSE(l.Answered(3));
  EXPECT_FALSE(l.Answered(2));
  EXPECT_EQ(l.repeats(), 2);
  EXPECT_EQ(Seqs(l.ForResend(1)), (std::vector<int64_t>{3, 4, 5}));
}

TEST(PairLedgerTest, RefusedPosesFormNoPairAndTheBoundHolds) {
  PairLedger l(3);
  EXPECT_TRUE(l.Sent(Pose(0)));
  EXPECT_TRUE(l.Sent(Pose(1)));
  l.Refused(1);
  EXPECT_TRUE(l.Sent(Pose(2)));
  EXPECT_TRUE(l.Sent(Pose(3)));
  EXPECT_FALSE(l.Sent(Pose(4)));  // Over 3: the oldest is forgotten, counted.
  EXPECT_EQ(l.forgotten(), 1);
  EXPECT_EQ(Seqs(l.ForResend(1)), (std::vector<int64_t>{2, 3, 4}));
}

TEST(PairLedgerTest, NumberingFromAnewIsANewStream) {
  PairLedger l;
  for (int64_t s = 0; s < 4; ++s) l.Sent(Pose(s));
  EXPECT_TRUE(l.Answered(3));
  l.Sent(Pose(0));  // The application restarts its stream at 0.
  EXPECT_EQ(Seqs(l.ForResend(1)), (std::vector<int64_t>{0}));
  l.Sent(Pose(1));
  EXPECT_TRUE(l.Answered(1));  // Not a repeat: a pair of the new stream.
}

TEST(PairLedgerTest, EpochFence) {
  EXPECT_FALSE(IsStaleEpoch(500, 500));
  EXPECT_TRUE(IsStaleEpoch(400, 500));  // The dead room's late event.
  EXPECT_TRUE(IsStaleEpoch(600, 500));  // Not this join's either.
  EXPECT_FALSE(IsStaleEpoch(0, 500));   // A door that does not say.
}

}  // namespace
}  // namespace sweptccd
