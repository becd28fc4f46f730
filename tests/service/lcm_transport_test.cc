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

using test::Height;
using test::MakePose;

const char kRoomHex[] = "8f1e2d3c4b5a69788796a5b4c3d2e1f00f1e2d3c4b5a69788796a5b4c3d2e1f0";
const char kOtherHex[] = "0000000000000000000000000000000000000000000000000000000000000001";

tracker_pose_t Sample(const std::string& client, int64_t k) {
  return MakePose(client, k, 2'000'000 + k * 8'333, Height(k), 0.1 * static_cast<double>(k));
}

// Collects what the service publishes, from the same memq:// instance.
struct Listener {
  std::vector<contact_event_t> contacts;
  std::vector<rejection_t> rejections;
  std::vector<status_t> statuses;
  void OnContact(const lcm::ReceiveBuffer*, const std::string&, const contact_event_t* m) {
    contacts.push_back(*m);
  }
  void OnReject(const lcm::ReceiveBuffer*, const std::string&, const rejection_t* m) {
    rejections.push_back(*m);
  }
  void OnStatus(const lcm::ReceiveBuffer*, const std::string&, const status_t* m) {
    statuses.push_back(*m);
  }
};

class LcmTransportTest : public ::testing::Test {
 protected:
  void SetUp() override {
    ASSERT_TRUE(lcm_.good());
    TransportSecurity security;
    security.keys.SetRoomKey(room_key_);
    transport_ = std::make_unique<LcmTransport>(&lcm_, LcmChannels{}, std::move(security));
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
    lcm_.subscribe(kContactChannel, &Listener::OnContact, &listener_);
    lcm_.subscribe(kRejectChannel, &Listener::OnReject, &listener_);
    lcm_.subscribe(kStatusChannel, &Listener::OnStatus, &listener_);
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

  // Publishes a pose signed with `key` (the room key by default).
  void Send(const tracker_pose_t& m, const MacKey* key = nullptr) {
    const std::vector<uint8_t> bytes = EncodeSigned(m, key ? key : &room_key_);
    ASSERT_EQ(lcm_.publish(kPoseChannel, bytes.data(), static_cast<unsigned>(bytes.size())), 0);
  }

  MacKey room_key_ = ParseKeyHex(kRoomHex, "room");
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
      Send(Sample(id, k));
    }
    Pump();
  }
  EXPECT_EQ(transport_->messages_received(), 2 * kPoses);
  EXPECT_EQ(transport_->callback_errors(), 0);
  EXPECT_TRUE(listener_.rejections.empty());
  ASSERT_EQ(listener_.contacts.size(), static_cast<size_t>(2 * (kPoses - 1)));
  QueryOptions query;
  int contact = 0;
  for (const char* id : {"a", "b"}) {
    int64_t next = 0;
    for (const contact_event_t& e : listener_.contacts) {
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
  ASSERT_EQ(lcm_.publish(kPoseChannel, garbage, sizeof(garbage)), 0);
  rejection_t other;
  other.utime = 1;
  other.seq = 2;
  ASSERT_EQ(lcm_.publish(kPoseChannel, &other), 0);
  const tracker_pose_t good = Sample("a", 0);
  std::vector<uint8_t> buf(good.getEncodedSize());
  ASSERT_EQ(good.encode(buf.data(), 0, static_cast<int>(buf.size())), static_cast<int>(buf.size()));
  ASSERT_EQ(lcm_.publish(kPoseChannel, buf.data(), static_cast<unsigned>(buf.size() / 2)), 0);
  // The encoder cannot write a negative count, so patch the encoded pose:
  // hash (8) + utime (8) + string length (4) + "a\0" (2) + session (8) + seq (8) = 38.
  std::vector<uint8_t> negative = buf;
  const uint8_t minus_three[4] = {0xff, 0xff, 0xff, 0xfd};  // Big-endian int32 -3.
  std::copy(minus_three, minus_three + 4, negative.begin() + 38);
  ASSERT_EQ(lcm_.publish(kPoseChannel, negative.data(), static_cast<unsigned>(negative.size())),
            0);
  Pump();
  ASSERT_EQ(listener_.rejections.size(), 4u);
  for (const rejection_t& r : listener_.rejections) {
    EXPECT_EQ(r.reason, rejection_code::kDecodeError) << r.message;
    EXPECT_EQ(r.seq, -1);
    EXPECT_NE(r.message.find("SWEPTCCD_POSE"), std::string::npos) << r.message;
  }
  EXPECT_EQ(transport_->callback_errors(), 0);
  // The service goes on.
  for (int64_t k = 0; k < 3; ++k) {
    Send(Sample("a", k));
    Pump();  // One pose at a time: no latest-wins skipping.
  }
  EXPECT_EQ(listener_.contacts.size(), 2u);
  EXPECT_EQ(service_->rejected_unattributed(), 4);
}

TEST_F(LcmTransportTest, RejectionsAndStatusGoOutOnTheirChannels) {
  tracker_pose_t m = Sample("nobody", 0);
  Send(m);
  m = Sample("a", 0);
  m.orientation[1] = {0, 0, 0, 0};
  Send(m);
  Pump();
  ASSERT_EQ(listener_.rejections.size(), 2u);
  EXPECT_EQ(listener_.rejections[0].reason, rejection_code::kUnknownClient);
  EXPECT_EQ(listener_.rejections[0].client_id, "nobody");
  EXPECT_EQ(listener_.rejections[1].reason, rejection_code::kZeroQuaternion);
  EXPECT_EQ(listener_.rejections[1].client_id, "a");
  EXPECT_EQ(listener_.rejections[1].seq, 0);
  service_->PublishStatus();
  Pump();
  ASSERT_EQ(listener_.statuses.size(), 1u);
  const status_t& s = listener_.statuses[0];
  EXPECT_EQ(s.num_clients, 2);
  EXPECT_EQ(s.client_id[0], "a");
  EXPECT_EQ(s.rejected[0], 1);
  EXPECT_EQ(s.rejected_unattributed, 1);
  EXPECT_EQ(s.backend, "cpu");
}

// Finding 1 of the hostile-network issue: 36 bytes (fingerprint, utime, a
// client_id length of INT32_MIN) made lcm-gen's decoder read past the buffer.
TEST_F(LcmTransportTest, The36ByteCrashDatagramIsRefused) {
  std::vector<uint8_t> bytes(36, 0);
  const uint64_t hash = static_cast<uint64_t>(tracker_pose_t::getHash());
  for (int i = 0; i < 8; ++i) bytes[i] = static_cast<uint8_t>(hash >> (56 - 8 * i));
  bytes[16] = 0x80;
  ASSERT_EQ(lcm_.publish(kPoseChannel, bytes.data(), 36), 0);
  // And a 78-byte pose claiming 2^26 links (finding 2).
  tracker_pose_t empty = Sample("a", 0);
  empty.num_links = 0;
  empty.position.clear(), empty.orientation.clear();
  std::vector<uint8_t> huge = EncodeSigned(empty, &room_key_);
  huge[38] = 0x04;  // num_links = 0x04000000
  ASSERT_EQ(lcm_.publish(kPoseChannel, huge.data(), static_cast<unsigned>(huge.size())), 0);
  Pump();
  ASSERT_EQ(listener_.rejections.size(), 2u);
  EXPECT_EQ(listener_.rejections[0].reason, rejection_code::kDecodeError);
  EXPECT_NE(listener_.rejections[0].message.find("client_id at byte 16 has string length "
                                                 "-2147483648"),
            std::string::npos)
      << listener_.rejections[0].message;
  EXPECT_NE(listener_.rejections[1].message.find("num_links at byte 38 is 67108864"),
            std::string::npos)
      << listener_.rejections[1].message;
  EXPECT_EQ(transport_->callback_errors(), 0);
  Send(Sample("a", 0));
  Send(Sample("a", 1));
  Pump();
  EXPECT_EQ(listener_.contacts.size(), 1u);
}

// Finding 3: nothing said who sent a pose.
TEST_F(LcmTransportTest, UnsignedOrBadlySignedPosesAreRefused) {
  const tracker_pose_t m = Sample("a", 0);
  const std::vector<uint8_t> unsigned_bytes = EncodeSigned(m, nullptr);
  ASSERT_EQ(lcm_.publish(kPoseChannel, unsigned_bytes.data(),
                         static_cast<unsigned>(unsigned_bytes.size())),
            0);
  const MacKey other = ParseKeyHex(kOtherHex, "other");
  Send(m, &other);
  std::vector<uint8_t> flipped = EncodeSigned(m, &room_key_);
  flipped[25] ^= 1;  // One bit of the session.
  ASSERT_EQ(lcm_.publish(kPoseChannel, flipped.data(), static_cast<unsigned>(flipped.size())), 0);
  tracker_pose_t bad_id = Sample("a\x1b[31m", 0);
  Send(bad_id);
  Pump();
  ASSERT_EQ(listener_.rejections.size(), 4u);
  for (int i = 0; i < 3; ++i) {
    EXPECT_EQ(listener_.rejections[i].reason, rejection_code::kBadSignature) << i;
    EXPECT_EQ(listener_.rejections[i].client_id, "a");
  }
  EXPECT_EQ(listener_.rejections[3].reason, rejection_code::kBadClientId);
  EXPECT_EQ(listener_.rejections[3].client_id, "");
  EXPECT_NE(listener_.rejections[3].message.find("a\\x1b[31m"), std::string::npos);
  EXPECT_EQ(service_->Status().poses_received[0], 0);  // Never reached alice's session.
  EXPECT_EQ(service_->rejected_unattributed(), 4);
}

// Collects the raw bytes published on the service's channels.
struct RawListener {
  std::vector<std::vector<uint8_t>> messages;
  void On(const lcm::ReceiveBuffer* rbuf, const std::string&) {
    const auto* b = static_cast<const uint8_t*>(rbuf->data);
    messages.emplace_back(b, b + rbuf->data_size);
  }
};

TEST_F(LcmTransportTest, WhatThePublisherSendsIsSignedWithTheServiceKey) {
  RawListener raw;
  for (const char* channel : {kContactChannel, kRejectChannel, kStatusChannel}) {
    lcm_.subscribe(channel, &RawListener::On, &raw);
  }
  Send(Sample("a", 0));
  Send(Sample("a", 1));
  Send(Sample("nobody", 0));
  Pump();
  service_->PublishStatus();
  Pump();
  ASSERT_EQ(raw.messages.size(), 3u);
  const MacKey other = ParseKeyHex(kOtherHex, "other");
  for (const auto& m : raw.messages) {
    EXPECT_TRUE(VerifyEncoded(m.data(), m.size(), room_key_));
    EXPECT_FALSE(VerifyEncoded(m.data(), m.size(), other));
  }
  const auto status = DecodeChecked<status_t>(raw.messages[2].data(), raw.messages[2].size(), {});
  ASSERT_TRUE(status.ok()) << status.problem;
  EXPECT_EQ(status.message->security, "signed");
}

TEST(LcmTransportConstruction, UnsignedModeAcceptsUnsignedPosesAndSendsZeroMacs) {
  lcm::LCM lcm("memq://");
  TransportSecurity bench;
  bench.signed_mode = false;
  LcmTransport transport(&lcm, LcmChannels{}, std::move(bench));
  ClientConfig a;
  a.client_id = "a";
  a.skeleton = test::TwoLinkSkeleton();
  ServiceOptions options;
  options.security = "unsigned";
  CollisionService service(test::FloorEnvironment(), {a}, options, &transport);
  transport.Subscribe(&service);
  RawListener raw;
  lcm.subscribe(kContactChannel, &RawListener::On, &raw);
  for (int64_t k = 0; k < 2; ++k) {
    const std::vector<uint8_t> bytes = EncodeSigned(Sample("a", k), nullptr);
    ASSERT_EQ(lcm.publish(kPoseChannel, bytes.data(), static_cast<unsigned>(bytes.size())), 0);
    while (lcm.handleTimeout(0) > 0) {
    }
  }
  service.WaitUntilIdle();
  while (lcm.handleTimeout(0) > 0) {
  }
  transport.Unsubscribe();
  service.Stop();
  ASSERT_EQ(raw.messages.size(), 1u);
  const auto& m = raw.messages[0];
  EXPECT_TRUE(std::all_of(m.end() - kMacBytes, m.end(), [](uint8_t b) { return b == 0; }));
}

TEST(LcmTransportConstruction, SignedModeNeedsAKeyToSignWith) {
  lcm::LCM lcm("memq://");
  EXPECT_THROW(LcmTransport(&lcm, LcmChannels{}, TransportSecurity{}), InputError);
}

TEST(LcmTransportConstruction, RefusesAnUnusableLcm) {
  EXPECT_THROW(LcmTransport(nullptr), InputError);
}

}  // namespace
}  // namespace sweptccd
