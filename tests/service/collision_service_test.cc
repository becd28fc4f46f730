// CollisionService with a capturing Publisher: ordering, latest-wins,
// rejections, isolation between clients, equality with CcdEngine, Stop().
#include "service/collision_service.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <chrono>
#include <map>
#include <set>
#include <thread>
#include <tuple>

#include "core/errors.h"
#include "service_test_util.h"

namespace sweptccd {
namespace {

using test::CapturingPublisher;
using test::Height;
using test::MakePose;

constexpr int64_t kDtUs = 11'111;  // 90 Hz.

tracker_pose_t Sample(const std::string& client, int64_t k) {
  return MakePose(client, k, 1'000'000 + k * kDtUs, Height(k), 0.2 * static_cast<double>(k));
}

class CollisionServiceTest : public ::testing::Test {
 protected:
  // The fake clock ticks 1 us a call, so the rate limits are set out of the
  // way here; the rate-limit tests set their own (MakeWith).
  std::unique_ptr<CollisionService> Make(std::vector<std::string> ids, int workers = 2,
                                         bool per_link = false) {
    ServiceOptions options;
    options.num_workers = workers;
    options.query.per_link = per_link;
    options.clock_utime = [this] { return ++fake_utime_; };
    options.max_pose_rate_hz = 1e6;
    options.pose_burst = 1 << 20;
    options.rejection_burst = 1 << 20;
    return MakeWith(std::move(ids), options);
  }

  // The shared world on, `workers` workers, the fake clock, the pose rate
  // limits out of the way and no cut by silence within a test.
  ServiceOptions SharedOptions(int workers) {
    ServiceOptions options;
    options.num_workers = workers;
    options.clock_utime = [this] { return ++fake_utime_; };
    options.max_pose_rate_hz = 1e6;
    options.pose_burst = 1 << 20;
    options.silence_timeout_ms = 3'600'000;
    options.shared_world = true;
    return options;
  }

  std::unique_ptr<CollisionService> MakeWith(std::vector<std::string> ids, ServiceOptions options) {
    std::vector<ClientConfig> clients;
    for (const std::string& id : ids) {
      ClientConfig c;
      c.client_id = id;
      c.skeleton = skeleton_;
      clients.push_back(c);
    }
    query_ = options.query;
    return std::make_unique<CollisionService>(env_, std::move(clients), options, &publisher_);
  }

  std::shared_ptr<const Skeleton> skeleton_ = test::TwoLinkSkeleton();
  std::shared_ptr<const Environment> env_ = test::FloorEnvironment();
  CapturingPublisher publisher_;
  QueryOptions query_;
  std::atomic<int64_t> fake_utime_{0};
};

TEST_F(CollisionServiceTest, AnswersEveryPairInOrderAndEqualToTheEngine) {
  auto service = Make({"a", "b"}, 3, /*per_link=*/true);
  constexpr int kPoses = 16;  // Heights 1.0 .. -0.05: free pairs, then contact.
  for (int64_t k = 0; k < kPoses; ++k) {
    service->OnPose(Sample("a", k));
    service->OnPose(Sample("b", k));
    service->WaitUntilIdle();  // No skipping: each pair is answered before the next pose.
  }
  service->Stop();
  int contacts = 0;
  for (const std::string id : {"a", "b"}) {
    const auto events = publisher_.contacts_of(id);
    ASSERT_EQ(events.size(), static_cast<size_t>(kPoses - 1));
    for (size_t i = 0; i < events.size(); ++i) {
      SCOPED_TRACE(id + " pair " + std::to_string(i));
      EXPECT_EQ(events[i].pair, static_cast<int64_t>(i));
      EXPECT_EQ(events[i].skipped_pairs_total, 0);
      EXPECT_GE(events[i].compute_us, 0);
      EXPECT_GE(events[i].queue_us, 0);
      EXPECT_GT(events[i].utime, events[i].receive_utime);
      test::ExpectMatchesEngine(events[i], Sample(id, i), Sample(id, i + 1), *skeleton_, *env_,
                                query_);
      if (events[i].result == contact_event_t::RESULT_CONTACT) ++contacts;
    }
  }
  EXPECT_GT(contacts, 0);  // The stream reaches the floor.
  EXPECT_TRUE(publisher_.rejections().empty());
  const status_t s = service->Status();
  ASSERT_EQ(s.num_clients, 2);
  for (int i = 0; i < 2; ++i) {
    EXPECT_EQ(s.poses_received[i], kPoses);
    EXPECT_EQ(s.pairs_answered[i], kPoses - 1);
    EXPECT_EQ(s.pairs_skipped[i], 0);
    EXPECT_EQ(s.rejected[i], 0);
    EXPECT_GT(s.latency_p99_us[i], 0);
    EXPECT_LE(s.latency_median_us[i], s.latency_p99_us[i]);
  }
  EXPECT_EQ(s.queue_depth, 0);
  EXPECT_EQ(s.dropped_total, 0);
  EXPECT_EQ(s.backend, "cpu");
}

TEST_F(CollisionServiceTest, PairsOfOneClientArePublishedInOrderWithManyWorkers) {
  // Without WaitUntilIdle between poses: latest-wins may skip, but whatever is
  // published is in pose order, chained, and every pair is accounted for.
  auto service = Make({"a", "b", "c"}, 4);
  constexpr int kPoses = 40;
  for (int64_t k = 0; k < kPoses; ++k) {
    for (const char* id : {"a", "b", "c"}) service->OnPose(Sample(id, k));
  }
  service->WaitUntilIdle();
  const status_t s = service->Status();
  for (int c = 0; c < 3; ++c) {
    const std::string id = s.client_id[c];
    const auto events = publisher_.contacts_of(id);
    ASSERT_FALSE(events.empty());
    EXPECT_EQ(events.front().seq0, 0);
    EXPECT_EQ(events.back().seq1, kPoses - 1);
    int64_t skipped = 0;
    for (size_t i = 0; i < events.size(); ++i) {
      EXPECT_EQ(events[i].pair, static_cast<int64_t>(i));
      if (i > 0) {
        EXPECT_EQ(events[i].seq0, events[i - 1].seq1);  // Chained: nothing lost.
        EXPECT_GE(events[i].skipped_pairs_total, events[i - 1].skipped_pairs_total);
      }
      skipped += events[i].seq1 - events[i].seq0 - 1;
      EXPECT_EQ(events[i].skipped_pairs_total, skipped);
      test::ExpectMatchesEngine(events[i], Sample(id, events[i].seq0), Sample(id, events[i].seq1),
                                *skeleton_, *env_, query_);
    }
    EXPECT_EQ(s.pairs_answered[c], static_cast<int64_t>(events.size()));
    EXPECT_EQ(s.pairs_skipped[c], skipped);
    EXPECT_EQ(s.pairs_answered[c] + s.pairs_skipped[c], kPoses - 1);
  }
}

TEST_F(CollisionServiceTest, LatestWinsWhileAWorkerIsBusy) {
  auto service = Make({"a"}, 1);
  publisher_.CloseGate();
  service->OnPose(Sample("a", 0));
  service->OnPose(Sample("a", 1));
  publisher_.WaitEntered(1);  // The worker holds (0, 1) inside PublishContact.
  for (int64_t k = 2; k <= 5; ++k) service->OnPose(Sample("a", k));  // Never blocks.
  status_t s = service->Status();
  EXPECT_EQ(s.pairs_skipped[0], 3);  // (1,2) (2,3) (3,4) (4,5) -> (1,5)
  EXPECT_EQ(s.dropped_total, 3);
  EXPECT_EQ(s.queue_depth, 1);
  EXPECT_EQ(s.pairs_answered[0], 0);
  publisher_.OpenGate();
  service->WaitUntilIdle();
  const auto events = publisher_.contacts();
  ASSERT_EQ(events.size(), 2u);
  EXPECT_EQ(events[0].seq0, 0);
  EXPECT_EQ(events[0].seq1, 1);
  EXPECT_EQ(events[0].skipped_pairs_total, 0);
  EXPECT_EQ(events[1].seq0, 1);
  EXPECT_EQ(events[1].seq1, 5);
  EXPECT_EQ(events[1].pair, 1);
  EXPECT_EQ(events[1].skipped_pairs_total, 3);
  test::ExpectMatchesEngine(events[1], Sample("a", 1), Sample("a", 5), *skeleton_, *env_, query_);
  s = service->Status();
  EXPECT_EQ(s.pairs_answered[0], 2);
  EXPECT_EQ(s.pairs_skipped[0], 3);
  EXPECT_EQ(s.queue_depth, 0);
}

TEST_F(CollisionServiceTest, OneBusyClientDoesNotHoldBackAnother) {
  // Two workers; client a's worker is held in PublishContact. Client b is
  // still answered by the other worker.
  auto service = Make({"a", "b"}, 2);
  publisher_.CloseGate();
  service->OnPose(Sample("a", 0));
  service->OnPose(Sample("a", 1));
  publisher_.WaitEntered(1);
  service->OnPose(Sample("b", 0));
  service->OnPose(Sample("b", 1));
  publisher_.WaitEntered(2);  // The second worker took b's pair while a's is held.
  publisher_.OpenGate();
  service->WaitUntilIdle();
  EXPECT_EQ(publisher_.contacts_of("a").size(), 1u);
  EXPECT_EQ(publisher_.contacts_of("b").size(), 1u);
}

// Live clients (docs/SERVICE.md, "Live clients"): a join and a leave never
// wait on a worker. The only worker is held inside PublishContact; joining,
// streaming into and leaving a live client all finish meanwhile (a join that
// waited on the workers would hang here). The left client's pending pair is
// dropped, never answered.
TEST_F(CollisionServiceTest, JoinAndLeaveProceedWhileEveryWorkerIsBusy) {
  ServiceOptions options;
  options.num_workers = 1;
  options.clock_utime = [this] { return ++fake_utime_; };
  options.max_pose_rate_hz = 1e6;
  options.pose_burst = 1 << 20;
  options.max_live_clients = 2;
  auto service = MakeWith({"a"}, options);
  publisher_.CloseGate();
  service->OnPose(Sample("a", 0));
  service->OnPose(Sample("a", 1));
  publisher_.WaitEntered(1);  // The worker is held.

  LiveJoinRequest join;
  join.config.client_id = "live";
  join.config.skeleton = skeleton_;
  join.nonce = 5;
  const LiveJoinOutcome joined = service->JoinLive(join, std::nullopt);
  ASSERT_EQ(joined.reason, +join_reply_t::REASON_ACCEPTED) << joined.message;
  EXPECT_EQ(service->live_clients(), 1);
  for (int64_t k = 0; k < 2; ++k) {
    tracker_pose_t p = Sample("live", k);
    p.session = joined.session;
    service->OnPose(p);
  }
  EXPECT_TRUE(publisher_.rejections().empty());
  EXPECT_FALSE(service->LeaveLive("live", joined.session + 1));  // Not its session.
  EXPECT_TRUE(service->LeaveLive("live", joined.session));
  EXPECT_EQ(service->live_clients(), 0);
  publisher_.OpenGate();
  service->WaitUntilIdle();
  EXPECT_EQ(publisher_.contacts_of("a").size(), 1u);
  EXPECT_TRUE(publisher_.contacts_of("live").empty());
  const status_t s = service->Status();
  EXPECT_EQ(s.live_joined, 1);
  EXPECT_EQ(s.live_left, 1);
}

TEST_F(CollisionServiceTest, SilenceExpiresLiveClientsOnlyAndTheIdIsFreeAgain) {
  ServiceOptions options;
  options.clock_utime = [this] { return ++fake_utime_; };
  options.max_live_clients = 4;
  options.silence_timeout_ms = 1000;
  auto service = MakeWith({"a"}, options);
  LiveJoinRequest join;
  join.config.client_id = "quiet";
  join.config.skeleton = skeleton_;
  const SteadyClock::time_point t0 = SteadyClock::now();
  ASSERT_EQ(service->JoinLive(join, std::nullopt).reason, +join_reply_t::REASON_ACCEPTED);
  EXPECT_TRUE(service->ExpireSilent(t0).empty());  // Not silent yet.
  const std::vector<std::string> expired = service->ExpireSilent(t0 + std::chrono::seconds(2));
  EXPECT_EQ(expired, (std::vector<std::string>{"quiet"}));  // "a" is configured: never.
  EXPECT_EQ(service->Status().live_expired, 1);
  EXPECT_EQ(service->Status().client_id, (std::vector<std::string>{"a"}));
  join.nonce = 9;
  EXPECT_EQ(service->JoinLive(join, std::nullopt).reason, +join_reply_t::REASON_ACCEPTED);
}

// A configured client joined through the WebSocket door (docs/WEBSOCKET.md
// "Configured clients"): only a join proven with its own key; its own
// skeleton and options; a new, greater session that makes older streams
// stale; one holder at a time; the hold ends with LeaveLive, the client
// stays; no live-client limit.
TEST_F(CollisionServiceTest, ConfiguredClientJoinsThroughTheDoorWithASessionOfItsOwn) {
  ServiceOptions options;
  options.clock_utime = [this] { return ++fake_utime_; };
  options.max_pose_rate_hz = 1e6;
  options.pose_burst = 1 << 20;
  options.rejection_burst = 1 << 20;
  options.max_live_clients = 0;  // Configured joins count against no limit.
  options.silence_timeout_ms = 3'600'000;
  auto service = MakeWith({"walker"}, options);
  // The configured stream of an LCM tracker first (its session: 7).
  for (int64_t k = 0; k < 2; ++k) {
    tracker_pose_t p = Sample("walker", k);
    p.session = 7;
    service->OnPose(p);
  }
  service->WaitUntilIdle();
  ASSERT_EQ(publisher_.contacts_of("walker").size(), 1u);

  LiveJoinRequest join;
  join.config.client_id = "walker";
  join.config.skeleton = skeleton_;
  join.nonce = 11;
  // An LCM join (room key only): refused as before.
  EXPECT_EQ(service->JoinLive(join, std::nullopt).reason, +join_reply_t::REASON_ID_IN_USE);
  join.proven_with_client_key = true;
  // Not its skeleton, motion, tolerances or filters.
  LiveJoinRequest other = join;
  std::vector<Link> links = skeleton_->links();
  links[1].radius *= 2;
  other.config.skeleton = std::make_shared<const Skeleton>(Skeleton::FromLinks("w", links, "t"));
  EXPECT_EQ(service->JoinLive(other, std::nullopt).reason, +join_reply_t::REASON_BAD_SKELETON);
  other = join;
  other.config.motion = MotionModel::kIndependent;
  EXPECT_EQ(service->JoinLive(other, std::nullopt).reason, +join_reply_t::REASON_BAD_OPTIONS);
  other = join;
  other.config.eps_s = 1e-3;
  EXPECT_EQ(service->JoinLive(other, std::nullopt).reason, +join_reply_t::REASON_BAD_OPTIONS);
  other = join;
  other.ignore_rules = 1;
  EXPECT_EQ(service->JoinLive(other, std::nullopt).reason, +join_reply_t::REASON_BAD_FILTER);

  const LiveJoinOutcome joined = service->JoinLive(join, std::nullopt);
  ASSERT_EQ(joined.reason, +join_reply_t::REASON_ACCEPTED) << joined.message;
  EXPECT_GT(joined.session, 7);
  EXPECT_FALSE(joined.key.has_value());
  EXPECT_EQ(service->live_clients(), 0);
  EXPECT_TRUE(service->IsConfigured("walker"));
  // Another instance while it is held: id in use.
  LiveJoinRequest second = join;
  second.nonce = 12;
  EXPECT_EQ(service->JoinLive(second, std::nullopt).reason, +join_reply_t::REASON_ID_IN_USE);
  // The door's stream: seq and utime may restart; the tracker's older
  // stream is stale now.
  for (int64_t k = 0; k < 2; ++k) {
    tracker_pose_t p = Sample("walker", k);
    p.session = joined.session;
    service->OnPose(p);
  }
  tracker_pose_t late = Sample("walker", 5);
  late.session = 7;
  service->OnPose(late);
  service->WaitUntilIdle();
  EXPECT_EQ(publisher_.contacts_of("walker").size(), 2u);
  ASSERT_EQ(publisher_.rejections().size(), 1u);
  EXPECT_EQ(publisher_.rejections()[0].reason, rejection_code::kStaleSession);
  // The hold ends; the client stays and another instance takes a greater session.
  EXPECT_FALSE(service->LeaveLive("walker", joined.session + 1));
  EXPECT_TRUE(service->LeaveLive("walker", joined.session));
  EXPECT_TRUE(service->IsConfigured("walker"));
  EXPECT_EQ(service->Status().client_id, (std::vector<std::string>{"walker"}));
  const LiveJoinOutcome again = service->JoinLive(second, std::nullopt);
  ASSERT_EQ(again.reason, +join_reply_t::REASON_ACCEPTED) << again.message;
  EXPECT_GT(again.session, joined.session);
  EXPECT_EQ(service->Status().live_joined, 0);
}

TEST_F(CollisionServiceTest, BadClientNeverDisturbsAnother) {
  auto service = Make({"good", "bad"}, 2);
  constexpr int kPoses = 12;
  std::vector<std::string> expected_reasons;
  for (int64_t k = 0; k < kPoses; ++k) {
    service->OnPose(Sample("good", k));
    // The bad client sends one good pose, then every kind of garbage.
    tracker_pose_t bad = Sample("bad", k);
    switch (k % 6) {
      case 0:
        break;
      case 1:
        bad.num_links = 5;
        expected_reasons.push_back(rejection_code::kWrongLinkCount);
        break;
      case 2:
        bad.position[0][1] = std::numeric_limits<double>::quiet_NaN();
        expected_reasons.push_back(rejection_code::kNonFinite);
        break;
      case 3:
        bad.orientation[0] = {0, 0, 0, 0};
        expected_reasons.push_back(rejection_code::kZeroQuaternion);
        break;
      case 4:
        bad.seq = -1;
        expected_reasons.push_back(rejection_code::kNonIncreasingSeq);
        break;
      case 5:
        bad.utime = 0;
        expected_reasons.push_back(rejection_code::kNonIncreasingUtime);
        break;
    }
    service->OnPose(bad);
    tracker_pose_t stranger = Sample("stranger", k);
    service->OnPose(stranger);
    expected_reasons.push_back(rejection_code::kUnknownClient);
    service->WaitUntilIdle();
  }
  service->OnUndecodable("SWEPTCCD_POSE", "test");
  expected_reasons.push_back(rejection_code::kDecodeError);
  service->WaitUntilIdle();

  const auto good = publisher_.contacts_of("good");
  ASSERT_EQ(good.size(), static_cast<size_t>(kPoses - 1));
  for (size_t i = 0; i < good.size(); ++i) {
    test::ExpectMatchesEngine(good[i], Sample("good", i), Sample("good", i + 1), *skeleton_, *env_,
                              query_);
  }
  // The bad client's good poses (k = 0, 6) still pair with each other.
  const auto bad = publisher_.contacts_of("bad");
  ASSERT_EQ(bad.size(), 1u);
  EXPECT_EQ(bad[0].seq0, 0);
  EXPECT_EQ(bad[0].seq1, 6);

  const auto rejections = publisher_.rejections();
  ASSERT_EQ(rejections.size(), expected_reasons.size());
  for (size_t i = 0; i < rejections.size(); ++i) {
    EXPECT_EQ(rejections[i].reason, expected_reasons[i]) << i;
    EXPECT_FALSE(rejections[i].message.empty());
    EXPECT_GT(rejections[i].utime, 0);
  }
  EXPECT_EQ(rejections.back().client_id, "");
  EXPECT_EQ(rejections.back().seq, -1);
  EXPECT_EQ(rejections[0].client_id, "stranger");
  EXPECT_EQ(rejections[1].client_id, "bad");

  const status_t s = service->Status();
  EXPECT_EQ(s.rejected[0], 0);
  EXPECT_EQ(s.rejected[1], 10);  // 12 poses, 2 good.
  EXPECT_EQ(s.poses_received[1], 12);
  EXPECT_EQ(s.rejected_unattributed, kPoses + 1);
  EXPECT_EQ(service->rejected_unattributed(), kPoses + 1);
}

// Finding 4 of the hostile-network issue: a client id with a newline and
// ANSI escapes forged log lines. It is refused before any lookup, never
// echoed in rejection_t.client_id, and shown escaped.
TEST_F(CollisionServiceTest, ClientIdBreakingTheRuleIsRefusedAndNotEchoed) {
  auto service = Make({"a"}, 1);
  service->OnPose(Sample("a\n[12:00:00.000] [info] \x1b[31mcontact", 0));
  service->OnPose(Sample(std::string(65, 'a'), 0));
  service->OnRefused("a", Rejection{rejection_code::kBadSignature, "forged"});
  service->WaitUntilIdle();
  const auto rejections = publisher_.rejections();
  ASSERT_EQ(rejections.size(), 3u);
  for (int i = 0; i < 2; ++i) {
    EXPECT_EQ(rejections[i].reason, rejection_code::kBadClientId);
    EXPECT_EQ(rejections[i].client_id, "");
    EXPECT_EQ(rejections[i].message.find('\n'), std::string::npos);
    EXPECT_EQ(rejections[i].message.find('\x1b'), std::string::npos);
  }
  EXPECT_NE(rejections[0].message.find("a\\n[12:00:00.000] [info] \\x1b[31mcontact"),
            std::string::npos)
      << rejections[0].message;
  EXPECT_EQ(rejections[2].reason, rejection_code::kBadSignature);
  EXPECT_EQ(rejections[2].client_id, "a");
  EXPECT_EQ(rejections[2].seq, -1);
  EXPECT_EQ(service->rejected_unattributed(), 3);
  const status_t s = service->Status();
  EXPECT_EQ(s.rejected[0], 0);  // Not alice's: the sender is unknown.
  EXPECT_EQ(s.security, "signed");
}

TEST_F(CollisionServiceTest, StopFinishesAndPublishesInFlightAndPendingWork) {
  auto service = Make({"a"}, 1);
  publisher_.CloseGate();
  service->OnPose(Sample("a", 0));
  service->OnPose(Sample("a", 1));
  publisher_.WaitEntered(1);        // (0, 1) in flight.
  service->OnPose(Sample("a", 2));  // (1, 2) pending.
  std::thread stopper([&] { service->Stop(); });
  // Stop() has to wait for the held worker; release it. Poses sent while
  // stopping may or may not be ignored, so none are sent here.
  publisher_.OpenGate();
  stopper.join();
  const auto events = publisher_.contacts();
  ASSERT_EQ(events.size(), 2u);
  EXPECT_EQ(events[0].seq1, 1);
  EXPECT_EQ(events[1].seq0, 1);
  EXPECT_EQ(events[1].seq1, 2);
  // After Stop, poses are ignored and counted, nothing is published.
  service->OnPose(Sample("a", 3));
  EXPECT_EQ(service->ignored_after_stop(), 1);
  EXPECT_EQ(publisher_.contacts().size(), 2u);
  service->Stop();  // Idempotent.
  service->WaitUntilIdle();
}

TEST_F(CollisionServiceTest, PublisherExceptionsAreCountedAndWorkGoesOn) {
  auto service = Make({"a"}, 2);
  publisher_.ThrowOnContact(true);
  for (int64_t k = 0; k < 4; ++k) {
    service->OnPose(Sample("a", k));
    service->WaitUntilIdle();
  }
  EXPECT_EQ(service->publish_errors(), 3);
  publisher_.ThrowOnContact(false);
  service->OnPose(Sample("a", 4));
  service->WaitUntilIdle();
  EXPECT_EQ(publisher_.contacts().size(), 4u);
  EXPECT_EQ(service->Status().pairs_answered[0], 4);
}

TEST_F(CollisionServiceTest, PublishStatusSendsTheSnapshot) {
  auto service = Make({"a", "b"}, 1);
  service->OnPose(Sample("a", 0));
  service->OnPose(Sample("a", 1));
  service->WaitUntilIdle();
  service->PublishStatus();
  const auto statuses = publisher_.statuses();
  ASSERT_EQ(statuses.size(), 1u);
  const status_t& s = statuses[0];
  ASSERT_EQ(s.num_clients, 2);
  ASSERT_EQ(s.client_id.size(), 2u);
  ASSERT_EQ(s.latency_p99_us.size(), 2u);
  EXPECT_EQ(s.client_id[0], "a");
  EXPECT_EQ(s.pairs_answered[0], 1);
  EXPECT_EQ(s.pairs_answered[1], 0);
  EXPECT_EQ(s.latency_median_us[1], 0);
}

TEST_F(CollisionServiceTest, BadConfigurationIsRefused) {
  ServiceOptions options;
  ClientConfig c;
  c.client_id = "a";
  c.skeleton = skeleton_;
  EXPECT_THROW(CollisionService(env_, {}, options, &publisher_), InputError);
  EXPECT_THROW(CollisionService(env_, {c, c}, options, &publisher_), InputError);
  ClientConfig unnamed = c;
  unnamed.client_id = "";
  EXPECT_THROW(CollisionService(env_, {unnamed}, options, &publisher_), InputError);
  ClientConfig spaced = c;
  spaced.client_id = "a b";
  EXPECT_THROW(CollisionService(env_, {spaced}, options, &publisher_), InputError);
  ServiceOptions no_horizon;
  no_horizon.max_utime_jump_us = 0;
  EXPECT_THROW(CollisionService(env_, {c}, no_horizon, &publisher_), InputError);
  ClientConfig no_skeleton = c;
  no_skeleton.skeleton = nullptr;
  EXPECT_THROW(CollisionService(env_, {no_skeleton}, options, &publisher_), InputError);
  ServiceOptions no_workers;
  no_workers.num_workers = 0;
  EXPECT_THROW(CollisionService(env_, {c}, no_workers, &publisher_), InputError);
  ServiceOptions bad_eps;
  bad_eps.query.eps_s = -1;
  EXPECT_THROW(CollisionService(env_, {c}, bad_eps, &publisher_), InputError);
  ServiceOptions no_window;
  no_window.latency_window = 0;
  EXPECT_THROW(CollisionService(env_, {c}, no_window, &publisher_), InputError);
  EXPECT_THROW(CollisionService(nullptr, {c}, options, &publisher_), InputError);
  EXPECT_THROW(CollisionService(env_, {c}, options, nullptr), InputError);
}

}  // namespace
}  // namespace sweptccd

namespace sweptccd {
namespace {

// Finding 6 of the hostile-network issue: a registered client flooding.
// Rate limits with a clock the test sets (microseconds).
class RateLimitTest : public CollisionServiceTest {
 protected:
  ServiceOptions LimitedOptions() {
    ServiceOptions options;
    options.num_workers = 2;
    options.clock_utime = [this] { return now_us_.load(); };
    options.max_pose_rate_hz = 100;
    options.pose_burst = 4;
    options.rejection_rate_hz = 10;
    options.rejection_burst = 10;
    return options;
  }
  int64_t SuppressedSum() {
    int64_t sum = 0;
    for (const rejection_t& r : publisher_.rejections()) sum += r.suppressed;
    return sum;
  }
  std::atomic<int64_t> now_us_{1'000'000};
};

TEST_F(RateLimitTest, ClientAtTenTimesItsRateGetsExactlyTheBucketsAdmissions) {
  const ServiceOptions options = LimitedOptions();
  auto service = MakeWith({"flood"}, options);
  TokenBucket twin(options.max_pose_rate_hz, options.pose_burst);
  constexpr int kPoses = 1000;  // 1 s at 1 kHz, 10x the limit.
  std::vector<int64_t> admitted;
  for (int64_t k = 0; k < kPoses; ++k) {
    now_us_ = 1'000'000 + k * 1000;
    if (twin.TryTake(now_us_)) admitted.push_back(k);
    service->OnPose(Sample("flood", k));
    service->WaitUntilIdle();  // No latest-wins skipping: every admitted pair is answered.
  }
  // 4 at once, then one every 10 ms over the remaining 999 ms.
  ASSERT_EQ(admitted.size(), 4u + 99u);
  const auto events = publisher_.contacts_of("flood");
  ASSERT_EQ(events.size(), admitted.size() - 1);
  for (size_t i = 0; i < events.size(); ++i) {
    EXPECT_EQ(events[i].seq0, admitted[i]);
    EXPECT_EQ(events[i].seq1, admitted[i + 1]);
    test::ExpectMatchesEngine(events[i], Sample("flood", admitted[i]),
                              Sample("flood", admitted[i + 1]), *skeleton_, *env_, query_);
  }
  const status_t s = service->Status();
  const int64_t shed = kPoses - static_cast<int64_t>(admitted.size());
  EXPECT_EQ(s.rate_limited[0], shed);
  EXPECT_EQ(s.poses_received[0], kPoses);
  EXPECT_EQ(s.rejected[0], 0);  // Shed before validation, so never validated.
  EXPECT_EQ(s.pairs_answered[0], static_cast<int64_t>(events.size()));
  // rate_limited rejections go through the throttle: 10 at once, 10 a second.
  const auto rejections = publisher_.rejections();
  EXPECT_LE(rejections.size(), 10u + 10u);
  for (const rejection_t& r : rejections) EXPECT_EQ(r.reason, rejection_code::kRateLimited);
  EXPECT_EQ(static_cast<int64_t>(rejections.size()) + s.rejections_suppressed, shed);
}

TEST_F(RateLimitTest, TenThousandUnknownPosesPublishABoundedCountThatAddsUp) {
  auto service = MakeWith({"good"}, LimitedOptions());
  constexpr int kPoses = 10'000;  // 1 s at 10 kHz.
  for (int64_t k = 0; k < kPoses; ++k) {
    now_us_ = 1'000'000 + k * 100;
    service->OnPose(Sample("stranger", k));
  }
  // Two seconds later one more: published, carrying the count held back.
  now_us_ = 3'000'000;
  service->OnPose(Sample("stranger", kPoses));
  const auto rejections = publisher_.rejections();
  // Burst 10, then 10 a second over 1 s, then the last one.
  EXPECT_LE(rejections.size(), 10u + 10u + 1u);
  EXPECT_GE(rejections.size(), 10u);
  for (const rejection_t& r : rejections) EXPECT_EQ(r.reason, rejection_code::kUnknownClient);
  EXPECT_GT(rejections.back().suppressed, 0);
  EXPECT_EQ(static_cast<int64_t>(rejections.size()) + SuppressedSum(), kPoses + 1);
  const status_t s = service->Status();
  EXPECT_EQ(s.rejected_unattributed, kPoses + 1);
  EXPECT_EQ(s.rejections_suppressed, SuppressedSum());
  EXPECT_EQ(service->rejections_suppressed(), SuppressedSum());
}

// Unknown ids and forged signatures in a registered client's name share the
// key "": they cannot spend that client's own budget.
TEST_F(RateLimitTest, AFloodOfUnknownIdsAndForgeriesDoesNotSilenceAClientsRejections) {
  auto service = MakeWith({"good"}, LimitedOptions());
  for (int64_t k = 0; k < 1000; ++k) {
    now_us_ = 1'000'000 + k * 100;
    service->OnPose(Sample("stranger", k));
    service->OnRefused("good", Rejection{rejection_code::kBadSignature, "forged"});
  }
  service->OnPose(Sample("good", 5));
  tracker_pose_t replay = Sample("good", 5);
  replay.utime += 1;
  service->OnPose(replay);
  const auto rejections = publisher_.rejections();
  ASSERT_FALSE(rejections.empty());
  EXPECT_EQ(rejections.back().client_id, "good");
  EXPECT_EQ(rejections.back().reason, rejection_code::kNonIncreasingSeq);
  EXPECT_EQ(rejections.back().suppressed, 0);
}

// A cube of 0.4 m, one object (the tracked object of the shared-world tests).
std::shared_ptr<const Environment> CubeObject() {
  TriangleMesh cube;
  for (int c = 0; c < 8; ++c) {
    cube.vertices.emplace_back((c & 1) ? 0.2f : -0.2f, (c & 2) ? 0.2f : -0.2f,
                               (c & 4) ? 0.2f : -0.2f);
  }
  cube.indices = {0, 1, 3, 0, 3, 2, 4, 6, 7, 4, 7, 5, 0, 4, 5, 0, 5, 1,
                  2, 3, 7, 2, 7, 6, 0, 2, 6, 0, 6, 4, 1, 5, 7, 1, 7, 3};
  auto mesh = std::make_shared<Environment>();
  mesh->AddMesh(cube, "cube");
  return mesh;
}

object_pose_t BoxPose(int64_t seq, int64_t utime) {
  object_pose_t o{};
  o.utime = utime;
  o.object_id = "box";
  o.session = 1;
  o.seq = seq;
  o.position[2] = 0.6;
  o.orientation[0] = 1;
  return o;
}

// The per-object input rate limit: the same token bucket as a client's,
// checked first; what it sheds is counted, refused through the throttled
// rejection path, and never reaches the shared world.
TEST_F(RateLimitTest, ObjectAtTenTimesItsRateGetsExactlyTheBucketsAdmissions) {
  ServiceOptions options = LimitedOptions();
  options.shared_world = true;
  options.objects = {{"box", CubeObject()}};
  options.max_object_pose_rate_hz = 50;
  options.object_pose_burst = 3;
  auto service = MakeWith({"a"}, options);
  TokenBucket twin(options.max_object_pose_rate_hz, options.object_pose_burst);
  constexpr int kPoses = 500;  // 1 s at 500 Hz, 10x the limit.
  int64_t admitted = 0;
  for (int64_t k = 0; k < kPoses; ++k) {
    now_us_ = 1'000'000 + k * 2000;
    admitted += twin.TryTake(now_us_);
    // utimes 1 us apart: a pose that got through the bucket is used.
    service->OnObjectPose(BoxPose(k, 1'000'000 + k));
  }
  service->WaitUntilIdle();
  ASSERT_EQ(admitted, 3 + 49);
  const status_t s = service->Status();
  EXPECT_EQ(s.object_poses_received, kPoses);
  EXPECT_EQ(s.object_poses_rate_limited, kPoses - admitted);
  EXPECT_EQ(s.object_poses_rejected, 0) << "shed ones are never validated";
  const auto rejections = publisher_.rejections();
  EXPECT_LE(rejections.size(), 10u + 10u);
  EXPECT_GE(rejections.size(), 10u);
  for (const rejection_t& r : rejections) {
    EXPECT_EQ(r.reason, rejection_code::kRateLimited);
    EXPECT_EQ(r.client_id, "box");
  }
  EXPECT_EQ(static_cast<int64_t>(rejections.size()) + s.rejections_suppressed, kPoses - admitted);
  // An unknown object is not limited by any configured object's bucket.
  service->OnObjectPose([] {
    object_pose_t o = BoxPose(1, 5'000'000);
    o.object_id = "ghost";
    return o;
  }());
  EXPECT_EQ(service->Status().object_poses_rejected, 1);
  EXPECT_EQ(publisher_.rejections().back().reason, rejection_code::kUnknownObject);
}

TEST_F(RateLimitTest, BadObjectRatesAreRefused) {
  ServiceOptions options = LimitedOptions();
  options.shared_world = true;
  options.max_object_pose_rate_hz = 0;
  EXPECT_THROW(MakeWith({"a"}, options), InputError);
  options.max_object_pose_rate_hz = 10;
  options.object_pose_burst = 0;
  EXPECT_THROW(MakeWith({"a"}, options), InputError);
}

TEST_F(RateLimitTest, BadRatesAreRefused) {
  ServiceOptions options = LimitedOptions();
  options.max_pose_rate_hz = 0;
  EXPECT_THROW(MakeWith({"a"}, options), InputError);
  options = LimitedOptions();
  options.pose_burst = 0;
  EXPECT_THROW(MakeWith({"a"}, options), InputError);
  options = LimitedOptions();
  options.rejection_max_keys = 0;
  EXPECT_THROW(MakeWith({"a"}, options), InputError);
}

}  // namespace

// One message per (pair, batch): a's pair is covered by b, c and the box
// at once (their samples are ahead of it), so its three entries are due
// together and published as one shared_contact_t, each with its own window
// and waited_us.
TEST_F(CollisionServiceTest, SharedEntriesDueTogetherArePublishedAsOneMessage) {
  ServiceOptions options = SharedOptions(2);
  options.max_object_pose_rate_hz = 1e6;
  options.object_pose_burst = 1 << 20;
  options.objects = {{"box", CubeObject()}};
  auto service = MakeWith({"a", "b", "c"}, options);
  for (int64_t k = 0; k < 4; ++k) {
    service->OnPose(Sample("b", k));
    service->WaitUntilIdle();
    service->OnPose(Sample("c", k));
    service->WaitUntilIdle();
    service->OnObjectPose(BoxPose(k, 1'000'000 + k * kDtUs));
    service->WaitUntilIdle();
  }
  const size_t before = publisher_.shared_messages().size();
  service->OnPose(Sample("a", 0));
  service->OnPose(Sample("a", 1));
  service->WaitUntilIdle();
  std::vector<shared_contact_t> of_a;
  for (const shared_contact_t& m : publisher_.shared_messages()) {
    if (m.client_id == "a") of_a.push_back(m);
  }
  ASSERT_EQ(of_a.size(), 1u) << "one message for a's pair";
  // And a's sample 1, stamped at the utime1 of b's and c's pair 0, covers
  // their windows against a: one message each.
  const std::vector<shared_contact_t> all = publisher_.shared_messages();
  ASSERT_EQ(all.size(), before + 3);
  std::set<std::string> newly;
  for (size_t i = before; i < all.size(); ++i) {
    if (all[i].client_id == "a") continue;
    EXPECT_EQ(all[i].pair, 0) << all[i].client_id;
    ASSERT_EQ(all[i].entries.size(), 1u) << all[i].client_id;
    EXPECT_EQ(all[i].entries[0].entity, "a") << all[i].client_id;
    newly.insert(all[i].client_id);
  }
  EXPECT_EQ(newly, (std::set<std::string>{"b", "c"}));
  const shared_contact_t& m = of_a[0];
  EXPECT_EQ(m.seq0, 0);
  EXPECT_EQ(m.seq1, 1);
  ASSERT_EQ(m.num_entries, 3);
  ASSERT_EQ(m.entries.size(), 3u);
  EXPECT_EQ(m.entries[0].entity, "b");
  EXPECT_EQ(m.entries[1].entity, "c");
  EXPECT_EQ(m.entries[2].entity, "box");
  EXPECT_EQ(m.entries[2].entity_kind, +shared_entry_t::KIND_OBJECT);
  for (const shared_entry_t& e : m.entries) {
    EXPECT_FALSE(e.ended_by_timeout) << e.entity;
    EXPECT_EQ(e.t_from, m.utime0) << e.entity;
    EXPECT_EQ(e.t_to, m.utime1) << e.entity;
    EXPECT_EQ(e.waited_us, 0) << e.entity << ": covered before the pair formed";
  }
  const status_t s = service->Status();
  EXPECT_EQ(s.shared_messages, service->shared_published_messages());
  EXPECT_EQ(s.shared_entries, service->shared_published());
  EXPECT_GT(s.shared_entries, s.shared_messages);
  service->Stop();
  // Every entry once, whatever message it came in.
  std::set<std::tuple<std::string, int64_t, std::string>> keys;
  for (const auto& x : publisher_.shared()) {
    EXPECT_TRUE(keys.insert({x.client_id, x.pair, x.entry.entity}).second) << "published twice";
  }
}

// status_t.shared_cleared counts the entries the broad phase cleared: every
// entry between the far client (20 m away along x) and the two others, none
// between the two near ones; each cleared entry is published `free`.
TEST_F(CollisionServiceTest, TheStatusCountsTheEntriesTheBroadPhaseCleared) {
  ServiceOptions options = SharedOptions(2);
  auto service = MakeWith({"a", "near", "far"}, options);
  for (int64_t k = 0; k < 5; ++k) {
    tracker_pose_t far = Sample("far", k);
    for (auto& x : far.position) x[0] += 20.0;
    service->OnPose(Sample("a", k));
    service->OnPose(Sample("near", k));
    service->OnPose(far);
    service->WaitUntilIdle();
  }
  service->Stop();
  int64_t with_far = 0, without_far = 0;
  for (const auto& x : publisher_.shared()) {
    if (x.client_id == "far" || x.entry.entity == "far") {
      ++with_far;
      EXPECT_EQ(x.entry.result, +shared_entry_t::RESULT_FREE) << x.client_id << " " << x.pair;
    } else {
      ++without_far;
    }
  }
  EXPECT_EQ(with_far, 4 * 4) << "4 pairs of each client, far against 2, 2 against far";
  EXPECT_EQ(without_far, 4 * 2);
  const status_t s = service->Status();
  EXPECT_EQ(s.shared_cleared, with_far);
  EXPECT_EQ(s.shared_entries, with_far + without_far);
}

// shared_entry_t.queue_us is the wait for a worker: an entry that becomes
// due while the only worker is held for 30 ms says at least that; one
// answered with the worker free says at most the time from its due pose to
// its answer, measured around it by the test (so no comparison of two
// measured times that a loaded machine could flip: each bound holds on any
// machine, steady_clock being monotonic).
TEST_F(CollisionServiceTest, SharedQueueTimeIsTheWaitForAWorker) {
  ServiceOptions options = SharedOptions(1);
  auto service = MakeWith({"a", "b"}, options);
  for (int64_t k = 0; k < 2; ++k) {
    service->OnPose(Sample("a", k));
    service->WaitUntilIdle();
  }
  service->OnPose(Sample("b", 0));
  service->WaitUntilIdle();
  publisher_.CloseGate();
  const int entered = publisher_.entered();
  service->OnPose(Sample("a", 2));
  publisher_.WaitEntered(entered + 1);  // The worker is held on a's pair (1, 2).
  const auto held_from = std::chrono::steady_clock::now();
  service->OnPose(Sample("b", 1));  // Covers a's pair 0 against b: due now.
  std::this_thread::sleep_for(std::chrono::milliseconds(30));
  publisher_.OpenGate();
  service->WaitUntilIdle();
  const double held_us =
      std::chrono::duration<double, std::micro>(std::chrono::steady_clock::now() - held_from)
          .count();
  const auto free_from = std::chrono::steady_clock::now();
  service->OnPose(Sample("b", 2));  // Covers a's pair 1, with the worker free.
  service->WaitUntilIdle();
  const double free_us =
      std::chrono::duration<double, std::micro>(std::chrono::steady_clock::now() - free_from)
          .count();
  std::map<int64_t, double> queue_of_a;  // Pair: queue_us against b.
  for (const auto& x : publisher_.shared()) {
    if (x.client_id == "a" && x.entry.entity == "b") queue_of_a[x.pair] = x.entry.queue_us;
  }
  ASSERT_EQ(queue_of_a.count(0), 1u);
  ASSERT_EQ(queue_of_a.count(1), 1u);
  // Due while the worker was held: at least the 30 ms hold, at most the
  // whole held phase.
  EXPECT_GE(queue_of_a[0], 30'000.0);
  EXPECT_LE(queue_of_a[0], held_us);
  // Due with the worker free: within the free phase, so it does not count
  // the earlier hold (which it would if it ran from a's pose, received
  // before the hold).
  EXPECT_GE(queue_of_a[1], 0.0);
  EXPECT_LE(queue_of_a[1], free_us);
  service->Stop();
}

// The shared world (docs/SERVICE.md "Shared world"): two clients whose
// streams interleave and a tracked object; every pair answered once against
// each overlapping entity, after its environment part; what the last samples
// cannot cover waits until Stop() cuts it (ended_by_timeout).
TEST_F(CollisionServiceTest, SharedWorldAnswersEachPairAgainstEveryOtherEntityOnce) {
  ServiceOptions options = SharedOptions(2);
  TriangleMesh cube;
  for (int c = 0; c < 8; ++c) {
    cube.vertices.emplace_back((c & 1) ? 0.2f : -0.2f, (c & 2) ? 0.2f : -0.2f,
                               (c & 4) ? 0.2f : -0.2f);
  }
  cube.indices = {0, 1, 3, 0, 3, 2, 4, 6, 7, 4, 7, 5, 0, 4, 5, 0, 5, 1,
                  2, 3, 7, 2, 7, 6, 0, 2, 6, 0, 6, 4, 1, 5, 7, 1, 7, 3};
  auto mesh = std::make_shared<Environment>();
  mesh->AddMesh(cube, "cube");
  options.objects = {{"box", mesh}};
  auto service = MakeWith({"a", "b"}, options);
  // a at 90 Hz from 1.0 s, b at 90 Hz from 1.003 s, the box at 50 Hz.
  struct Msg {
    int64_t utime;
    int who;
    int64_t k;
  };
  std::vector<Msg> msgs;
  for (int64_t k = 0; k < 10; ++k) msgs.push_back({1'000'000 + k * kDtUs, 0, k});
  for (int64_t k = 0; k < 10; ++k) msgs.push_back({1'003'000 + k * kDtUs, 1, k});
  for (int64_t k = 0; k < 7; ++k) msgs.push_back({1'000'000 + k * 20'000, 2, k});
  std::stable_sort(msgs.begin(), msgs.end(),
                   [](const Msg& x, const Msg& y) { return x.utime < y.utime; });
  for (const Msg& m : msgs) {
    if (m.who == 2) {
      object_pose_t o{};
      o.utime = m.utime;
      o.object_id = "box";
      o.session = 1;
      o.seq = m.k;
      o.position[0] = 0.1 * static_cast<double>(m.k), o.position[2] = 0.6;
      o.orientation[0] = 1;
      service->OnObjectPose(o);
    } else {
      tracker_pose_t p = Sample(m.who == 0 ? "a" : "b", m.k);
      p.utime = m.utime;
      service->OnPose(p);
    }
    service->WaitUntilIdle();  // One pose at a time: no pair merged by latest-wins.
  }
  // b's last pair ends after a's last sample: it waits for a.
  EXPECT_EQ(service->shared_pending(), 1u);
  // An object pose for an unknown object: one rejection, nothing else.
  const size_t published = publisher_.shared().size();
  const int64_t unattributed = service->rejected_unattributed();
  object_pose_t cup{};
  cup.utime = 2'000'000, cup.object_id = "cup", cup.session = 1, cup.seq = 1;
  cup.orientation[0] = 1;
  service->OnObjectPose(cup);
  service->WaitUntilIdle();
  ASSERT_EQ(publisher_.rejections().size(), 1u);
  EXPECT_EQ(publisher_.rejections()[0].reason, "unknown_object");
  EXPECT_EQ(publisher_.rejections()[0].client_id, "cup");
  EXPECT_EQ(service->rejected_unattributed(), unattributed + 1);
  EXPECT_EQ(publisher_.shared().size(), published);
  EXPECT_EQ(service->shared_pending(), 1u);
  service->Stop();

  const auto shared = publisher_.shared();
  EXPECT_EQ(publisher_.shared_before_contact(), 0);
  EXPECT_EQ(service->shared_published(), static_cast<int64_t>(shared.size()));
  EXPECT_EQ(service->shared_published_messages(),
            static_cast<int64_t>(publisher_.shared_messages().size()));
  for (const shared_contact_t& m : publisher_.shared_messages()) {
    EXPECT_GE(m.num_entries, 1);
    EXPECT_LE(m.num_entries, +shared_contact_t::MAX_ENTRIES);
    EXPECT_EQ(m.num_entries, static_cast<int32_t>(m.entries.size()));
  }
  std::set<std::tuple<std::string, int64_t, std::string>> keys;
  int cut = 0, contacts = 0;
  for (const auto& x : shared) {
    const shared_entry_t& s = x.entry;
    EXPECT_TRUE(keys.insert({x.client_id, x.pair, s.entity}).second) << "published twice";
    EXPECT_NE(x.client_id, s.entity);
    EXPECT_EQ(s.entity_kind == shared_entry_t::KIND_OBJECT, s.entity == "box");
    EXPECT_LE(s.t_from, s.t_to);
    EXPECT_GE(s.t_from, x.utime0);
    EXPECT_LE(s.t_to, x.utime1);
    EXPECT_EQ(s.error, "");
    cut += s.ended_by_timeout;
    contacts += s.result == 1;
    if (!s.ended_by_timeout) {
      EXPECT_EQ(s.t_to, x.utime1) << "covered: the whole pair";
    }
  }
  // 9 pairs each of a and b, against the other avatar and the box.
  EXPECT_EQ(shared.size(), 36u);
  EXPECT_EQ(cut, 1) << "b's last pair against a, cut at a's last sample";
  EXPECT_GT(contacts, 0) << "the two avatars walk the same path";
  EXPECT_EQ(service->shared_pending(), 0u);
  const status_t status = service->Status();
  EXPECT_EQ(status.shared_entries, 36);
  EXPECT_EQ(status.shared_messages, service->shared_published_messages());
  EXPECT_EQ(status.shared_by_timeout, 1);
  EXPECT_EQ(status.shared_dropped, 0);
  EXPECT_EQ(status.shared_pending, 0);
  EXPECT_EQ(status.shared_ready, 0);
  EXPECT_EQ(status.object_poses_received, 8);
  EXPECT_EQ(status.object_poses_rejected, 1);
  EXPECT_EQ(status.object_poses_rate_limited, 0);
}

}  // namespace sweptccd
