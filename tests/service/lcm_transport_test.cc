// LcmTransport over memq:// (in-process, never the network): decoding,
// decode errors, publishing on the service's channels.
#include "service/lcm_transport.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <lcm/lcm-cpp.hpp>

#include "core/errors.h"
#include "service/collision_service.h"
#include "service_test_util.h"

namespace sweptccd {
namespace {

using test::Listener;
using test::Sample;

class LcmTransportTest : public ::testing::Test {
 protected:
  void SetUp() override {
    ASSERT_TRUE(lcm_.good());
    transport_ = std::make_unique<LcmTransport>(&lcm_);
    ClientConfig a;
    a.client_id = "a";
    a.skeleton = skeleton_;
    ClientConfig b = a;
    b.client_id = "b";
    ServiceOptions options;
    options.num_workers = 2;
    service_ = std::make_unique<CollisionService>(env_, std::vector<ClientConfig>{a, b}, options,
                                                  transport_.get());
    transport_->Subscribe(service_.get());
    listener_.SubscribeTo(&lcm_);
  }
  void TearDown() override {
    transport_->Unsubscribe();
    service_->Stop();
  }

  // Delivers everything queued in memq:// (handleTimeout(0) returns 0 when
  // nothing is left), lets the service finish, and delivers its answers.
  void Pump() {
    while (lcm_.handleTimeout(0) > 0) {
    }
    service_->WaitUntilIdle();
    while (lcm_.handleTimeout(0) > 0) {
    }
  }

  lcm::LCM lcm_{"memq://"};
  std::shared_ptr<const Skeleton> skeleton_ = test::TwoLinkSkeleton();
  std::shared_ptr<const Environment> env_ = test::FloorEnvironment();
  std::unique_ptr<LcmTransport> transport_;
  std::unique_ptr<CollisionService> service_;
  Listener listener_;
};

TEST_F(LcmTransportTest, PosesInContactEventsOut) {
  constexpr int kPoses = 16;
  for (int64_t k = 0; k < kPoses; ++k) {
    for (const char* id : {"a", "b"}) {
      const tracker_pose_t m = Sample(id, k);
      ASSERT_EQ(lcm_.publish("SWEPTCCD_POSE", &m), 0);
    }
    Pump();
  }
  EXPECT_EQ(transport_->messages_received(), 2 * kPoses);
  EXPECT_EQ(transport_->callback_errors(), 0);
  EXPECT_TRUE(listener_.rejections().empty());
  ASSERT_EQ(listener_.contacts().size(), static_cast<size_t>(2 * (kPoses - 1)));
  QueryOptions query;
  int contact = 0;
  for (const char* id : {"a", "b"}) {
    int64_t next = 0;
    for (const contact_event_t& e : listener_.contacts()) {
      if (e.client_id != id) continue;
      SCOPED_TRACE(std::string(id) + " pair " + std::to_string(next));
      EXPECT_EQ(e.pair, next);
      // Through encode/decode, the doubles are bit-exact.
      test::ExpectMatchesEngine(e, Sample(id, next), Sample(id, next + 1), *skeleton_, *env_,
                                query);
      if (e.result == contact_event_t::RESULT_CONTACT) ++contact;
      ++next;
    }
    EXPECT_EQ(next, kPoses - 1);
  }
  EXPECT_GT(contact, 0);
}

TEST_F(LcmTransportTest, UndecodableMessagesAreRejectedNotFatal) {
  // Garbage bytes, a message of another type (wrong fingerprint), a truncated
  // pose, and a pose claiming a negative link count.
  const char garbage[] = "definitely not a tracker pose";
  ASSERT_EQ(lcm_.publish("SWEPTCCD_POSE", garbage, sizeof(garbage)), 0);
  rejection_t other;
  other.utime = 1;
  other.seq = 2;
  ASSERT_EQ(lcm_.publish("SWEPTCCD_POSE", &other), 0);
  const tracker_pose_t good = Sample("a", 0);
  std::vector<uint8_t> buf(good.getEncodedSize());
  ASSERT_EQ(good.encode(buf.data(), 0, static_cast<int>(buf.size())), static_cast<int>(buf.size()));
  ASSERT_EQ(lcm_.publish("SWEPTCCD_POSE", buf.data(), static_cast<unsigned>(buf.size() / 2)), 0);
  // The encoder cannot write a negative count, so patch the encoded pose:
  // hash (8) + utime (8) + string length (4) + "a\0" (2) + seq (8) = 30.
  std::vector<uint8_t> negative = buf;
  const uint8_t minus_three[4] = {0xff, 0xff, 0xff, 0xfd};  // Big-endian int32 -3.
  std::copy(minus_three, minus_three + 4, negative.begin() + 30);
  ASSERT_EQ(lcm_.publish("SWEPTCCD_POSE", negative.data(), static_cast<unsigned>(negative.size())),
            0);
  Pump();
  ASSERT_EQ(listener_.rejections().size(), 4u);
  for (const rejection_t& r : listener_.rejections()) {
    EXPECT_EQ(r.reason, rejection_code::kDecodeError) << r.message;
    EXPECT_EQ(r.seq, -1);
    EXPECT_NE(r.message.find("SWEPTCCD_POSE"), std::string::npos) << r.message;
  }
  EXPECT_EQ(transport_->callback_errors(), 0);
  // The service goes on.
  for (int64_t k = 0; k < 3; ++k) {
    const tracker_pose_t m = Sample("a", k);
    lcm_.publish("SWEPTCCD_POSE", &m);
    Pump();  // One pose at a time: no latest-wins skipping.
  }
  EXPECT_EQ(listener_.contacts().size(), 2u);
  EXPECT_EQ(service_->rejected_unattributed(), 4);
}

TEST_F(LcmTransportTest, RejectionsAndStatusGoOutOnTheirChannels) {
  tracker_pose_t m = Sample("nobody", 0);
  lcm_.publish("SWEPTCCD_POSE", &m);
  m = Sample("a", 0);
  m.orientation[1] = {0, 0, 0, 0};
  lcm_.publish("SWEPTCCD_POSE", &m);
  Pump();
  ASSERT_EQ(listener_.rejections().size(), 2u);
  EXPECT_EQ(listener_.rejections()[0].reason, rejection_code::kUnknownClient);
  EXPECT_EQ(listener_.rejections()[0].client_id, "nobody");
  EXPECT_EQ(listener_.rejections()[1].reason, rejection_code::kZeroQuaternion);
  EXPECT_EQ(listener_.rejections()[1].client_id, "a");
  EXPECT_EQ(listener_.rejections()[1].seq, 0);
  service_->PublishStatus();
  Pump();
  ASSERT_EQ(listener_.statuses().size(), 1u);
  const status_t s = listener_.statuses()[0];
  EXPECT_EQ(s.num_clients, 2);
  EXPECT_EQ(s.client_id[0], "a");
  EXPECT_EQ(s.rejected[0], 1);
  EXPECT_EQ(s.rejected_unattributed, 1);
  EXPECT_EQ(s.backend, "cpu");
}

TEST(LcmTransportConstruction, RefusesAnUnusableLcm) {
  EXPECT_THROW(LcmTransport(nullptr), InputError);
}

}  // namespace
}  // namespace sweptccd
