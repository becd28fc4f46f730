// ClientSession: validation codes, pairing, latest-wins, ordering. No threads.
#include "service/client_session.h"

#include <gtest/gtest.h>

#include <limits>
#include <random>

#include "service_test_util.h"

namespace sweptccd {
namespace {

using test::MakePose;

class ClientSessionTest : public ::testing::Test {
 protected:
  std::optional<Rejection> Offer(const tracker_pose_t& m) {
    return session_.OnPose(m, 1000 + m.seq, SteadyClock::now());
  }
  // Offers pose `seq` of a well-formed stream (utime 1e6 + seq * 11111 us).
  std::optional<Rejection> OfferSeq(int64_t seq) {
    return Offer(MakePose("a", seq, 1'000'000 + seq * 11'111, test::Height(seq)));
  }
  // Invariant of ClientSession: no pair is lost silently.
  void ExpectAccounted() {
    if (session_.poses_accepted() == 0) return;
    EXPECT_EQ(session_.poses_accepted() - session_.streams_started(),
              session_.pairs_taken() + session_.pairs_skipped() + (session_.has_pending() ? 1 : 0));
  }

  ClientSession session_{"a", 2};
};

TEST_F(ClientSessionTest, FirstPoseMakesNoPairThenEveryPoseOne) {
  ASSERT_FALSE(OfferSeq(0));
  EXPECT_FALSE(session_.ready());
  for (int64_t k = 1; k <= 5; ++k) {
    ASSERT_FALSE(OfferSeq(k));
    ASSERT_TRUE(session_.ready());
    PosePair p = session_.TakePair();
    EXPECT_EQ(p.pair, k - 1);
    EXPECT_EQ(p.seq0, k - 1);
    EXPECT_EQ(p.seq1, k);
    EXPECT_EQ(p.pose0.utime, 1'000'000 + (k - 1) * 11'111);
    EXPECT_EQ(p.pose1.utime, 1'000'000 + k * 11'111);
    EXPECT_EQ(p.receive_utime, 1000 + k);
    EXPECT_EQ(p.skipped_pairs_total, 0);
    EXPECT_FALSE(session_.ready());
    session_.FinishPair();
    ExpectAccounted();
  }
  EXPECT_EQ(session_.pairs_finished(), 5);
  EXPECT_EQ(session_.pairs_skipped(), 0);
  EXPECT_EQ(session_.poses_received(), 6);
}

// Poses the tracker numbered but the service never received (UDP loss) are
// counted as seq gaps; the pair across the gap is still answered.
TEST_F(ClientSessionTest, SeqGapsCountMissingSamples) {
  for (int64_t seq : {0, 1, 5, 6, 10, 11}) {
    ASSERT_FALSE(OfferSeq(seq));
    if (session_.ready()) {
      const PosePair p = session_.TakePair();
      if (seq == 5) {
        EXPECT_EQ(p.seq0, 1);
        EXPECT_EQ(p.seq1, 5);
      }
      session_.FinishPair();
    }
  }
  EXPECT_EQ(session_.seq_gaps(), 3 + 3);
  EXPECT_EQ(session_.pairs_finished(), 5);
  // A rejected (repeated) seq is not a gap.
  EXPECT_TRUE(OfferSeq(11));
  EXPECT_EQ(session_.seq_gaps(), 6);
  // Extreme numbering saturates instead of overflowing.
  ClientSession extreme("b", 2);
  tracker_pose_t first = MakePose("b", 0, 1, test::Height(0)), last = MakePose("b", 1, 2, test::Height(1));
  first.seq = INT64_MIN;
  last.seq = INT64_MAX;
  EXPECT_FALSE(extreme.OnPose(first, 1, SteadyClock::now()));
  EXPECT_FALSE(extreme.OnPose(last, 2, SteadyClock::now()));
  EXPECT_EQ(extreme.seq_gaps(), INT64_MAX);
}

TEST_F(ClientSessionTest, OnePairInFlightAtATime) {
  ASSERT_FALSE(OfferSeq(0));
  ASSERT_FALSE(OfferSeq(1));
  PosePair first = session_.TakePair();
  EXPECT_TRUE(session_.in_flight());
  ASSERT_FALSE(OfferSeq(2));
  // (1, 2) is pending but waits for (0, 1) to finish.
  EXPECT_TRUE(session_.has_pending());
  EXPECT_FALSE(session_.ready());
  session_.FinishPair();
  ASSERT_TRUE(session_.ready());
  PosePair second = session_.TakePair();
  EXPECT_EQ(first.seq1, second.seq0);
  EXPECT_EQ(second.pair, first.pair + 1);
  ExpectAccounted();
}

TEST_F(ClientSessionTest, LatestWinsReplacesThePendingPairAndCountsSkips) {
  ASSERT_FALSE(OfferSeq(0));
  ASSERT_FALSE(OfferSeq(1));
  PosePair first = session_.TakePair();  // (0, 1) in flight.
  ASSERT_FALSE(OfferSeq(2));             // pending (1, 2)
  ASSERT_FALSE(OfferSeq(3));             // pending (1, 3), one skipped
  ASSERT_FALSE(OfferSeq(4));             // pending (1, 4), two skipped
  EXPECT_EQ(session_.pairs_skipped(), 2);
  ExpectAccounted();
  session_.FinishPair();
  PosePair second = session_.TakePair();
  EXPECT_EQ(second.pair, 1);
  EXPECT_EQ(second.seq0, 1);  // The last answered pose...
  EXPECT_EQ(second.seq1, 4);  // ...to the newest.
  EXPECT_EQ(second.pose0.utime, first.pose1.utime);
  EXPECT_EQ(second.pose1.utime, 1'000'000 + 4 * 11'111);
  EXPECT_EQ(second.receive_utime, 1004);  // When the newest pose came in.
  EXPECT_EQ(second.skipped_pairs_total, 2);
  session_.FinishPair();
  ExpectAccounted();
  // The stream goes on from the newest pose.
  ASSERT_FALSE(OfferSeq(5));
  PosePair third = session_.TakePair();
  EXPECT_EQ(third.seq0, 4);
  EXPECT_EQ(third.seq1, 5);
  session_.FinishPair();
  EXPECT_EQ(session_.poses_accepted() - session_.streams_started(),
            session_.pairs_finished() + session_.pairs_skipped());
}

TEST_F(ClientSessionTest, LatestWinsBeforeAnyPairWasTaken) {
  for (int64_t k = 0; k <= 6; ++k) ASSERT_FALSE(OfferSeq(k));
  EXPECT_EQ(session_.pairs_skipped(), 5);
  PosePair p = session_.TakePair();
  EXPECT_EQ(p.seq0, 0);
  EXPECT_EQ(p.seq1, 6);
  ExpectAccounted();
}

TEST_F(ClientSessionTest, QuaternionsAreNormalised) {
  tracker_pose_t m = MakePose("a", 0, 1, 1.0);
  m.orientation[0] = {2, 0, 0, 0};
  m.orientation[1] = {0, 0, 0, 1e-3};
  Pose pose;
  ASSERT_FALSE(ValidateTrackerPose(m, 2, &pose));
  EXPECT_DOUBLE_EQ(pose.links[0].q.w(), 1.0);
  EXPECT_DOUBLE_EQ(pose.links[1].q.z(), 1.0);
  EXPECT_EQ(pose.utime, 1);
}

struct BadCase {
  const char* name;
  const char* code;
  void (*spoil)(tracker_pose_t*);
};

TEST_F(ClientSessionTest, EveryRejectionCodeAndRejectedPosesDoNotAdvance) {
  const BadCase cases[] = {
      {"fewer links", rejection_code::kWrongLinkCount,
       [](tracker_pose_t* m) {
         m->num_links = 1;
         m->position.resize(1);
         m->orientation.resize(1);
       }},
      {"more links", rejection_code::kWrongLinkCount,
       [](tracker_pose_t* m) {
         m->num_links = 3;
         m->position.push_back({0, 0, 0});
         m->orientation.push_back({1, 0, 0, 0});
       }},
      {"num_links disagrees with arrays", rejection_code::kWrongLinkCount,
       [](tracker_pose_t* m) { m->num_links = 3; }},
      {"short position row", rejection_code::kWrongLinkCount,
       [](tracker_pose_t* m) { m->position[1].resize(2); }},
      {"NaN position", rejection_code::kNonFinite,
       [](tracker_pose_t* m) { m->position[1][2] = std::numeric_limits<double>::quiet_NaN(); }},
      {"infinite quaternion", rejection_code::kNonFinite,
       [](tracker_pose_t* m) { m->orientation[0][3] = std::numeric_limits<double>::infinity(); }},
      {"NaN in a zero quaternion", rejection_code::kNonFinite,
       [](tracker_pose_t* m) {
         m->orientation[0] = {0, 0, 0, std::numeric_limits<double>::quiet_NaN()};
       }},
      {"far position", rejection_code::kPositionOutOfRange,
       [](tracker_pose_t* m) { m->position[0][0] = 2e9; }},
      {"zero quaternion", rejection_code::kZeroQuaternion,
       [](tracker_pose_t* m) {
         m->orientation[1] = {0, 0, 0, 0};
       }},
      {"tiny quaternion", rejection_code::kZeroQuaternion,
       [](tracker_pose_t* m) {
         m->orientation[1] = {1e-7, 0, 0, 0};
       }},
      {"same seq", rejection_code::kNonIncreasingSeq, [](tracker_pose_t* m) { m->seq = 1; }},
      {"smaller seq", rejection_code::kNonIncreasingSeq, [](tracker_pose_t* m) { m->seq = -5; }},
      {"same utime", rejection_code::kNonIncreasingUtime,
       [](tracker_pose_t* m) { m->utime = 1'000'000 + 11'111; }},
      {"smaller utime", rejection_code::kNonIncreasingUtime,
       [](tracker_pose_t* m) { m->utime = 5; }},
  };
  ASSERT_FALSE(OfferSeq(0));
  ASSERT_FALSE(OfferSeq(1));
  session_.TakePair();
  session_.FinishPair();
  for (const BadCase& c : cases) {
    SCOPED_TRACE(c.name);
    tracker_pose_t m = MakePose("a", 2, 1'000'000 + 2 * 11'111, test::Height(2));
    c.spoil(&m);
    const std::optional<Rejection> r = Offer(m);
    ASSERT_TRUE(r.has_value());
    EXPECT_EQ(r->reason, c.code);
    EXPECT_FALSE(r->message.empty());
    EXPECT_FALSE(session_.has_pending());
  }
  const int64_t num_cases = sizeof(cases) / sizeof(cases[0]);
  EXPECT_EQ(session_.rejected(), num_cases);
  EXPECT_EQ(session_.poses_received(), num_cases + 2);
  EXPECT_EQ(session_.poses_accepted(), 2);
  // The stream goes on from the last accepted pose.
  ASSERT_FALSE(OfferSeq(2));
  PosePair p = session_.TakePair();
  EXPECT_EQ(p.seq0, 1);
  EXPECT_EQ(p.seq1, 2);
  EXPECT_EQ(p.pair, 1);
  EXPECT_EQ(session_.pairs_skipped(), 0);
}

TEST_F(ClientSessionTest, RejectionMessagesNameTheValue) {
  tracker_pose_t m = MakePose("a", 0, 1, 1.0);
  m.num_links = 3;
  Pose pose;
  auto r = ValidateTrackerPose(m, 2, &pose);
  ASSERT_TRUE(r);
  EXPECT_NE(r->message.find("num_links is 3"), std::string::npos) << r->message;
  EXPECT_NE(r->message.find("has 2 links"), std::string::npos) << r->message;
  m = MakePose("a", 0, 1, 1.0);
  m.orientation[1] = {0, 0, 0, 0};
  r = ValidateTrackerPose(m, 2, &pose);
  ASSERT_TRUE(r);
  EXPECT_NE(r->message.find("link 1"), std::string::npos) << r->message;
}

// Sessions (docs/SERVICE.md): a restarted tracker numbers from 0 again under
// a greater session and is not locked out.
tracker_pose_t InSession(int64_t session, int64_t seq, int64_t utime) {
  tracker_pose_t m = MakePose("a", seq, utime, test::Height(seq));
  m.session = session;
  return m;
}

TEST_F(ClientSessionTest, GreaterSessionStartsANewStreamWithoutAPairAcross) {
  ASSERT_FALSE(Offer(InSession(5, 100, 9'000'000)));
  ASSERT_FALSE(Offer(InSession(5, 101, 9'010'000)));
  ASSERT_TRUE(session_.ready());
  PosePair old = session_.TakePair();
  EXPECT_EQ(old.session, 5);
  session_.FinishPair();
  // Restart: seq and utime from 0 again.
  ASSERT_FALSE(Offer(InSession(6, 0, 1'000)));
  EXPECT_FALSE(session_.ready());  // No pair (101 of session 5, 0 of session 6).
  EXPECT_EQ(session_.session(), 6);
  ASSERT_FALSE(Offer(InSession(6, 1, 2'000)));
  ASSERT_TRUE(session_.ready());
  const PosePair p = session_.TakePair();
  EXPECT_EQ(p.session, 6);
  EXPECT_EQ(p.seq0, 0);
  EXPECT_EQ(p.seq1, 1);
  session_.FinishPair();
  EXPECT_EQ(session_.streams_started(), 2);
  EXPECT_EQ(session_.seq_gaps(), 0);  // Not 0 - 101 across sessions.
  ExpectAccounted();
}

TEST_F(ClientSessionTest, SmallerSessionIsRefusedAsStale) {
  ASSERT_FALSE(Offer(InSession(7, 0, 1'000)));
  const auto r = Offer(InSession(6, 1, 2'000));
  ASSERT_TRUE(r);
  EXPECT_EQ(r->reason, rejection_code::kStaleSession);
  EXPECT_NE(r->message.find("session 6 is older than the current 7"), std::string::npos)
      << r->message;
  EXPECT_EQ(session_.rejected(), 1);
  ASSERT_FALSE(Offer(InSession(7, 1, 2'000)));  // The current stream goes on.
  ExpectAccounted();
}

TEST_F(ClientSessionTest, UtimeJumpBeyondTheHorizonIsRefused) {
  ASSERT_FALSE(Offer(InSession(1, 0, 1'000)));
  // INT64_MAX would lock the stream out for good; it is refused instead.
  auto r = Offer(InSession(1, 1, INT64_MAX));
  ASSERT_TRUE(r);
  EXPECT_EQ(r->reason, rejection_code::kUtimeJump);
  r = Offer(InSession(1, 2, 1'000 + kDefaultMaxUtimeJumpUs + 1));
  ASSERT_TRUE(r);
  EXPECT_EQ(r->reason, rejection_code::kUtimeJump);
  EXPECT_FALSE(Offer(InSession(1, 3, 1'000 + kDefaultMaxUtimeJumpUs)));  // At the horizon.
  ExpectAccounted();
}

TEST(ClientSessionHorizon, IsConfigurable) {
  ClientSession session("a", 2, 500);
  const auto now = SteadyClock::now();
  ASSERT_FALSE(session.OnPose(MakePose("a", 0, 1'000, 1.0), 0, now));
  EXPECT_TRUE(session.OnPose(MakePose("a", 1, 1'501, 1.0), 0, now));
  EXPECT_FALSE(session.OnPose(MakePose("a", 2, 1'500, 1.0), 0, now));
}

TEST_F(ClientSessionTest, PendingPairOfAnOldSessionIsReplacedNotExtended) {
  ASSERT_FALSE(Offer(InSession(1, 0, 1'000)));
  ASSERT_FALSE(Offer(InSession(1, 1, 2'000)));  // (0, 1) pending, not taken.
  ASSERT_FALSE(Offer(InSession(2, 0, 500)));     // New stream: (0, 1) still pending.
  ASSERT_TRUE(session_.has_pending());
  ASSERT_FALSE(Offer(InSession(2, 1, 600)));     // (0, 1) of session 1 replaced by (0, 1) of 2.
  ASSERT_TRUE(session_.ready());
  const PosePair p = session_.TakePair();
  EXPECT_EQ(p.session, 2);
  EXPECT_EQ(p.pose0.utime, 500);
  EXPECT_EQ(p.pose1.utime, 600);
  EXPECT_EQ(session_.pairs_skipped(), 1);
  ExpectAccounted();
}

// The service and `sweptccd query` apply one pose rule (core's
// FindPoseProblem): for random tracker messages with spoiled numbers, the
// service accepts exactly when core accepts the same numbers as a pose line,
// the normalised poses are bit-identical, and the rejection names the link
// core names.
TEST(TrackerPoseValidation, SameRuleAsThePoseLinesOfTheCli) {
  std::mt19937_64 rng(4242);
  const double specials[] = {std::numeric_limits<double>::quiet_NaN(),
                             std::numeric_limits<double>::infinity(),
                             -std::numeric_limits<double>::infinity(),
                             2e9, -1e9, 1e9, 1e-7, 0, 1e200};
  std::uniform_real_distribution<double> u(-2, 2);
  for (int trial = 0; trial < 4000; ++trial) {
    SCOPED_TRACE("trial " + std::to_string(trial));
    tracker_pose_t m = MakePose("a", 0, 1'000'000, u(rng), u(rng));
    for (int spoil = static_cast<int>(rng() % 3); spoil > 0; --spoil) {
      const size_t link = rng() % 2, k = rng() % 7;
      const double v = specials[rng() % std::size(specials)];
      if (k < 3) m.position[link][k] = v;
      if (k >= 3) m.orientation[link][k - 3] = v;
      if (rng() % 4 == 0) m.orientation[link] = {v * 1e-9, 0, 0, 0};
    }
    Pose from_message;
    const std::optional<Rejection> rejection = ValidateTrackerPose(m, 2, &from_message);
    Pose from_line;
    from_line.utime = m.utime;
    from_line.links.resize(2);
    for (int i = 0; i < 2; ++i) {
      const auto& p = m.position[i];
      const auto& q = m.orientation[i];
      from_line.links[i].p = {p[0], p[1], p[2]};
      from_line.links[i].q = Eigen::Quaterniond(q[0], q[1], q[2], q[3]);
    }
    const std::string core_error = ValidateAndNormalizePose(&from_line, 2);
    ASSERT_EQ(rejection.has_value(), !core_error.empty())
        << (rejection ? rejection->message : core_error);
    if (rejection) {
      const std::string link = core_error.substr(0, core_error.find(':'));  // "link N"
      EXPECT_EQ(rejection->message.rfind(link + ":", 0), 0u)
          << rejection->message << " vs " << core_error;
      continue;
    }
    for (int i = 0; i < 2; ++i) {
      EXPECT_EQ(from_message.links[i].p, from_line.links[i].p);
      EXPECT_EQ(from_message.links[i].q.coeffs(), from_line.links[i].q.coeffs());
    }
  }
}

// The wording of each kind of problem: the value, the place, the fix.
TEST(TrackerPoseValidation, RejectionWordingPerProblem) {
  Pose pose;
  tracker_pose_t m = MakePose("a", 0, 1, 1.0);
  m.position[1][2] = std::numeric_limits<double>::infinity();
  auto r = ValidateTrackerPose(m, 2, &pose);
  ASSERT_TRUE(r);
  EXPECT_EQ(r->message, "link 1: position[2] is inf; send finite numbers");
  m = MakePose("a", 0, 1, 1.0);
  m.orientation[0][1] = std::numeric_limits<double>::quiet_NaN();
  r = ValidateTrackerPose(m, 2, &pose);
  ASSERT_TRUE(r);
  EXPECT_EQ(r->message, "link 0: orientation[1] is nan; send finite numbers");
  m = MakePose("a", 0, 1, 1.0);
  m.position[0][0] = -2e9;
  r = ValidateTrackerPose(m, 2, &pose);
  ASSERT_TRUE(r);
  EXPECT_EQ(r->message, "link 0: position[0] is -2000000000 m, beyond 1e9 m; send metres in the "
                        "world frame");
  m = MakePose("a", 0, 1, 1.0);
  m.orientation[1] = {0, 0, 0, 0};
  r = ValidateTrackerPose(m, 2, &pose);
  ASSERT_TRUE(r);
  EXPECT_EQ(r->message, "link 1: quaternion norm 0 is below 1e-6; send a rotation as [w x y z]");
}

}  // namespace
}  // namespace sweptccd
