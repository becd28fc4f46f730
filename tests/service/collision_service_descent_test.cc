// CollisionService with the device descent (docs/SERVICE.md "The device
// descent"; llvmpipe in CI): the ready pairs of several clients go up in one
// device batch and every event equals the CPU engine's answer for its two
// poses; live clients with their own filters join and leave (their engines
// added to and removed from the descent, slots reused) and the clients after
// them still get the CPU's answers; a gather window answers a lone pair.
#include <gtest/gtest.h>

#include <atomic>
#include <memory>
#include <string>
#include <vector>

#include "core/errors.h"
#include "core/gpu/backend.h"
#include "core/gpu/device_descent.h"
#include "service/collision_service.h"
#include "service_test_util.h"

namespace sweptccd {
namespace {

using test::CapturingPublisher;
using test::Height;
using test::MakePose;

constexpr int64_t kDtUs = 11'111;  // 90 Hz.
constexpr int kPoses = 24;         // Heights 1.0 .. -0.61: the pelvis, then the arm, on the floor.

tracker_pose_t Sample(const std::string& client, int64_t k, int64_t session = 1) {
  tracker_pose_t m =
      MakePose(client, k, 1'000'000 + k * kDtUs, Height(k), 0.2 * static_cast<double>(k));
  m.session = session;
  return m;
}

class DeviceDescentServiceTest : public ::testing::Test {
 protected:
  void SetUp() override {
    gpu::BackendOptions o;
    o.backend = gpu::BackendKind::kGpu;
    backend_ = std::make_unique<gpu::Backend>(o);
    ASSERT_TRUE(backend_->gpu()) << backend_->reason();
    descent_ = backend_->MakeDescent(*env_, gpu::DescentOptions());
    ASSERT_NE(descent_, nullptr);
  }

  ServiceOptions Options(int workers) {
    ServiceOptions options;
    options.num_workers = workers;
    options.clock_utime = [this] { return ++fake_utime_; };
    options.max_pose_rate_hz = 1e6;
    options.pose_burst = 1 << 20;
    options.rejection_burst = 1 << 20;
    options.silence_timeout_ms = 3'600'000;
    options.device_descent = descent_;
    return options;
  }

  std::unique_ptr<CollisionService> Make(const std::vector<std::string>& ids,
                                         ServiceOptions options) {
    std::vector<ClientConfig> clients;
    for (const std::string& id : ids) {
      ClientConfig c;
      c.client_id = id;
      c.skeleton = skeleton_;
      clients.push_back(c);
    }
    return std::make_unique<CollisionService>(env_, std::move(clients), options, &publisher_);
  }

  // Every event of `id` equals the CPU engine (with `filter`) on its two
  // poses; the events chain the stream from pose 0 to pose last. Returns the
  // contacts.
  int ExpectEventsMatch(const std::string& id, int last,
                        const CollisionFilter& filter = CollisionFilter()) {
    const CcdEngine engine(*skeleton_, *env_, filter);
    const std::vector<contact_event_t> events = publisher_.contacts_of(id);
    EXPECT_FALSE(events.empty()) << id;
    int64_t seq = 0;
    int contacts = 0;
    for (const contact_event_t& e : events) {
      SCOPED_TRACE(id + " pair " + std::to_string(e.pair));
      EXPECT_EQ(e.seq0, seq);
      EXPECT_EQ(e.error, "");
      seq = e.seq1;
      const Pose p0 = test::ToPose(Sample(id, e.seq0), skeleton_->num_links());
      const Pose p1 = test::ToPose(Sample(id, e.seq1), skeleton_->num_links());
      const QueryResult r = engine.Query(p0, p1, QueryOptions());
      const int8_t expected = r.contact ? int8_t{contact_event_t::RESULT_CONTACT}
                                        : int8_t{contact_event_t::RESULT_FREE};
      EXPECT_EQ(e.result, expected);
      EXPECT_EQ(e.initially_colliding, r.initially_colliding);
      EXPECT_EQ(e.undecided, r.undecided);
      if (r.contact) {
        EXPECT_EQ(e.s_lo, r.s_lo);
        EXPECT_EQ(e.s_hi, r.s_hi);
        ++contacts;
      }
      EXPECT_EQ(e.num_contacts, static_cast<int>(r.contacts.size()));
      for (size_t i = 0; i < r.contacts.size() && i < e.contacts.size(); ++i) {
        EXPECT_EQ(e.contacts[i].link, r.contacts[i].link);
        EXPECT_EQ(e.contacts[i].triangle, r.contacts[i].triangle);
        EXPECT_EQ(e.contacts[i].s, r.contacts[i].s);
        EXPECT_EQ(e.contacts[i].separation, r.contacts[i].separation);
      }
    }
    EXPECT_EQ(seq, last) << id << ": the events end at the last pose";
    return contacts;
  }

  std::shared_ptr<const Skeleton> skeleton_ = test::TwoLinkSkeleton();
  std::shared_ptr<const Environment> env_ = test::FloorEnvironment();
  std::unique_ptr<gpu::Backend> backend_;
  std::shared_ptr<gpu::DeviceDescent> descent_;
  CapturingPublisher publisher_;
  std::atomic<int64_t> fake_utime_{0};
};

// One worker held in its first publication while five more clients' pairs
// become ready: the next batch takes all six clients' pairs at once. Every
// event equals the CPU engine's, per client in pose order.
TEST_F(DeviceDescentServiceTest, ReadyPairsOfAllClientsGoUpInOneBatchWithTheCpuAnswers) {
  const std::vector<std::string> ids = {"a", "b", "c", "d", "e", "f"};
  auto service = Make(ids, Options(/*workers=*/1));
  publisher_.CloseGate();
  service->OnPose(Sample("a", 0));
  service->OnPose(Sample("a", 1));
  publisher_.WaitEntered(1);  // The worker is held with a's first pair.
  for (const std::string& id : ids) {
    if (id != "a") service->OnPose(Sample(id, 0));
    service->OnPose(Sample(id, id == "a" ? 2 : 1));
  }
  const gpu::DescentStats before = descent_->stats();
  EXPECT_EQ(before.batches, 1);
  EXPECT_EQ(before.pairs, 1);
  publisher_.OpenGate();
  service->WaitUntilIdle();
  const gpu::DescentStats gathered = descent_->stats();
  EXPECT_EQ(gathered.batches, 2);
  EXPECT_EQ(gathered.pairs, 7);  // a's first pair, then the six clients' at once.
  for (int64_t k = 2; k < kPoses; ++k) {
    for (const std::string& id : ids) {
      if (!(id == "a" && k == 2)) service->OnPose(Sample(id, k));
    }
    service->WaitUntilIdle();
  }
  service->Stop();
  int contacts = 0;
  for (const std::string& id : ids) contacts += ExpectEventsMatch(id, kPoses - 1);
  EXPECT_GT(contacts, 0);
  const gpu::DescentStats after = descent_->stats();
  EXPECT_GT(after.pairs, after.batches);
  EXPECT_GT(after.cleared, 0);
  const status_t s = service->Status();
  for (size_t i = 0; i < ids.size(); ++i) {
    EXPECT_EQ(s.pairs_answered[i] + s.pairs_skipped[i], kPoses - 1) << ids[i];
  }
}

// Live clients come and go: one with a filter that ignores the pelvis against
// the floor (its own masks on the device) leaves; the clients that join
// after it (its slot reused) get the unfiltered CPU answers, and it got the
// filtered ones while it was there.
TEST_F(DeviceDescentServiceTest, LiveClientsJoinAndLeaveWithTheirOwnFilters) {
  ServiceOptions options = Options(/*workers=*/2);
  options.max_live_clients = 4;
  auto service = Make({"a"}, options);
  CollisionFilter pelvis_free(skeleton_->num_links(), env_->num_objects());
  pelvis_free.Ignore(LinkIndex(0), ObjectIndex(0));
  auto join = [&](const std::string& id, int64_t nonce, const CollisionFilter& filter) {
    LiveJoinRequest request;
    request.config.client_id = id;
    request.config.skeleton = skeleton_;
    request.config.filter = filter;
    request.nonce = nonce;
    const LiveJoinOutcome joined = service->JoinLive(request, std::nullopt);
    EXPECT_EQ(joined.reason, +join_reply_t::REASON_ACCEPTED) << joined.message;
    return joined.session;
  };
  auto stream = [&](const std::vector<std::pair<std::string, int64_t>>& clients) {
    for (int64_t k = 0; k < kPoses; ++k) {
      for (const auto& [id, session] : clients) service->OnPose(Sample(id, k, session));
      service->WaitUntilIdle();
    }
  };
  const int64_t filtered = join("filtered", 1, pelvis_free);
  stream({{"a", 1}, {"filtered", filtered}});
  const int filtered_contacts = ExpectEventsMatch("filtered", kPoses - 1, pelvis_free);
  EXPECT_GT(filtered_contacts, 0);  // The arm reaches the floor.
  EXPECT_TRUE(service->LeaveLive("filtered", filtered));
  const int64_t l1 = join("after1", 2, CollisionFilter());
  const int64_t l2 = join("after2", 3, CollisionFilter());
  stream({{"after1", l1}, {"after2", l2}});
  service->Stop();
  // The unfiltered clients touch earlier than the filtered one (the pelvis).
  for (const std::string id : {"after1", "after2"}) {
    EXPECT_GT(ExpectEventsMatch(id, kPoses - 1), filtered_contacts) << id;
  }
  EXPECT_TRUE(publisher_.rejections().empty());
}

// A gather window in a room of several clients: a lone pair is answered
// (after the window at most), the same answer.
TEST_F(DeviceDescentServiceTest, AGatherWindowStillAnswersALonePair) {
  ServiceOptions options = Options(/*workers=*/1);
  options.descent_gather_us = 20'000;
  auto service = Make({"a", "b"}, options);
  for (int64_t k = 0; k < 4; ++k) {
    service->OnPose(Sample("a", k));
    service->WaitUntilIdle();
  }
  service->Stop();
  ExpectEventsMatch("a", 3);
  EXPECT_TRUE(publisher_.contacts_of("b").empty());
  EXPECT_EQ(descent_->stats().pairs, 3);
}

TEST(DeviceDescentServiceOptionsTest, OutOfRangeBatchOrWindowIsRefused) {
  CapturingPublisher publisher;
  ClientConfig c;
  c.client_id = "a";
  c.skeleton = test::TwoLinkSkeleton();
  for (const auto& [batch, window] :
       std::vector<std::pair<int, int64_t>>{{0, 0}, {4097, 0}, {16, -1}, {16, 100001}}) {
    ServiceOptions options;
    options.descent_max_batch = batch;
    options.descent_gather_us = window;
    EXPECT_THROW(CollisionService(test::FloorEnvironment(), {c}, options, &publisher), InputError)
        << batch << " " << window;
  }
}

}  // namespace
}  // namespace sweptccd
