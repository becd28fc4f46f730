// The wire walkers against lcm-gen's decoders: equal on valid messages,
// never a crash or an unbounded allocation on truncated, flipped or hostile
// bytes.

#include "msgs/checked_decode.h"

#include <gtest/gtest.h>

#include <atomic>
#include <cstdlib>
#include <cstring>
#include <new>

#include "tests/msgs/msgs_test_util.h"

// The replacement operator new/delete below pair malloc with free; GCC's
// inliner cannot see that and warns at each use.
#pragma GCC diagnostic ignored "-Wmismatched-new-delete"

namespace {

// The largest single allocation while tracking is on (this thread only).
thread_local bool g_tracking = false;
thread_local size_t g_largest = 0;
thread_local size_t g_fail_above = SIZE_MAX;  // While tracking: larger allocations throw.

}  // namespace

void* operator new(size_t n) {
  if (g_tracking && n > g_largest) g_largest = n;
  if (g_tracking && n > g_fail_above) throw std::bad_alloc();
  if (void* p = std::malloc(n == 0 ? 1 : n)) return p;
  throw std::bad_alloc();
}
void operator delete(void* p) noexcept { std::free(p); }
void operator delete(void* p, size_t) noexcept { std::free(p); }

namespace sweptccd {
namespace {

using testing::Encode;
using testing::RandomMessages;

tracker_pose_t Make(RandomMessages& r, const tracker_pose_t*) { return r.Pose(); }
contact_event_t Make(RandomMessages& r, const contact_event_t*) { return r.Contact(); }
rejection_t Make(RandomMessages& r, const rejection_t*) { return r.Rejection(); }
status_t Make(RandomMessages& r, const status_t*) { return r.Status(); }
join_request_t Make(RandomMessages& r, const join_request_t*) { return r.Join(); }
join_reply_t Make(RandomMessages& r, const join_reply_t*) { return r.JoinReply(); }
leave_t Make(RandomMessages& r, const leave_t*) { return r.Leave(); }
object_pose_t Make(RandomMessages& r, const object_pose_t*) { return r.ObjectPose(); }
shared_contact_t Make(RandomMessages& r, const shared_contact_t*) { return r.SharedContact(); }

template <class T>
class CheckedDecodeTest : public ::testing::Test {
 protected:
  T Random(RandomMessages& r) { return Make(r, static_cast<const T*>(nullptr)); }
  // Accepted bytes must decode to a message that encodes back to the same
  // bytes; refused bytes must carry a problem. Never crashes.
  void CheckBytes(const std::vector<uint8_t>& bytes) {
    const DecodeResult<T> got = DecodeChecked<T>(bytes.data(), bytes.size(), limits_);
    if (!got.ok()) {
      EXPECT_FALSE(got.problem.empty());
      EXPECT_EQ(got.problem.find('\n'), std::string::npos) << got.problem;
      return;
    }
    ++accepted_;
    EXPECT_EQ(Encode(*got.message), bytes);
  }
  WireLimits limits_;
  int accepted_ = 0;
};

using MessageTypes = ::testing::Types<tracker_pose_t, contact_event_t, rejection_t, status_t,
                                      join_request_t, join_reply_t, leave_t, object_pose_t,
                                      shared_contact_t>;
TYPED_TEST_SUITE(CheckedDecodeTest, MessageTypes);

TYPED_TEST(CheckedDecodeTest, ValidMessagesDecodeLikeTheGeneratedDecoder) {
  RandomMessages r(11);
  for (int i = 0; i < 300; ++i) {
    const TypeParam msg = this->Random(r);
    const std::vector<uint8_t> bytes = Encode(msg);
    const DecodeResult<TypeParam> got =
        DecodeChecked<TypeParam>(bytes.data(), bytes.size(), this->limits_);
    ASSERT_TRUE(got.ok()) << got.problem;
    TypeParam twin;
    ASSERT_EQ(twin.decode(bytes.data(), 0, static_cast<int>(bytes.size())),
              static_cast<int>(bytes.size()));
    EXPECT_EQ(Encode(*got.message), Encode(twin));
    EXPECT_EQ(Encode(*got.message), bytes);
  }
}

TYPED_TEST(CheckedDecodeTest, EveryTruncationIsRefused) {
  RandomMessages r(12);
  for (int i = 0; i < 20; ++i) {
    const std::vector<uint8_t> bytes = Encode(this->Random(r));
    for (size_t n = 0; n < bytes.size(); ++n) {
      const std::vector<uint8_t> cut(bytes.begin(), bytes.begin() + static_cast<long>(n));
      const DecodeResult<TypeParam> got =
          DecodeChecked<TypeParam>(cut.data(), cut.size(), this->limits_);
      EXPECT_FALSE(got.ok()) << "accepted " << n << " of " << bytes.size() << " bytes";
    }
  }
}

TYPED_TEST(CheckedDecodeTest, TrailingBytesAreRefused) {
  RandomMessages r(13);
  std::vector<uint8_t> bytes = Encode(this->Random(r));
  bytes.push_back(0);
  const DecodeResult<TypeParam> got =
      DecodeChecked<TypeParam>(bytes.data(), bytes.size(), this->limits_);
  ASSERT_FALSE(got.ok());
  EXPECT_NE(got.problem.find("1 bytes follow"), std::string::npos) << got.problem;
}

TYPED_TEST(CheckedDecodeTest, RandomByteFlipsNeverCrash) {
  RandomMessages r(14);
  for (int i = 0; i < 3000; ++i) {
    std::vector<uint8_t> bytes = Encode(this->Random(r));
    const int flips = 1 + r.Below(4);
    for (int k = 0; k < flips; ++k) {
      bytes[static_cast<size_t>(r.Below(static_cast<int>(bytes.size())))] =
          static_cast<uint8_t>(r.Below(256));
    }
    this->CheckBytes(bytes);
  }
  EXPECT_GT(this->accepted_, 0);  // Flips inside numbers are accepted.
}

TYPED_TEST(CheckedDecodeTest, Int32MinStringLengthIsRefused) {
  RandomMessages r(15);
  std::vector<uint8_t> bytes = Encode(this->Random(r));
  // The first string of every type follows the fingerprint and utime.
  bytes[16] = 0x80, bytes[17] = 0, bytes[18] = 0, bytes[19] = 0;
  const DecodeResult<TypeParam> got =
      DecodeChecked<TypeParam>(bytes.data(), bytes.size(), this->limits_);
  ASSERT_FALSE(got.ok());
  EXPECT_NE(got.problem.find("-2147483648"), std::string::npos) << got.problem;
}

TEST(CheckedDecode, The36ByteCrashDatagramIsRefused) {
  // fingerprint, utime, client_id length INT32_MIN, 16 more bytes: lcm-gen
  // 1.3.1's decoder reads past the buffer on this one.
  std::vector<uint8_t> bytes(36, 0);
  const uint64_t hash = static_cast<uint64_t>(tracker_pose_t::getHash());
  for (int i = 0; i < 8; ++i) bytes[i] = static_cast<uint8_t>(hash >> (56 - 8 * i));
  bytes[16] = 0x80;
  const DecodeResult<tracker_pose_t> got = DecodeChecked<tracker_pose_t>(bytes.data(), 36, {});
  ASSERT_FALSE(got.ok());
  EXPECT_EQ(got.problem, "client_id at byte 16 has string length -2147483648 (must be >= 1)");
}

TEST(CheckedDecode, StatusClientIdWithBadLengthIsRefused) {
  RandomMessages r(16);
  status_t s = r.Status();
  s.backend = "b", s.renderer = "", s.security = "signed";
  s.num_clients = 1;
  s.client_id = {"alice"};
  s.poses_received = s.pairs_answered = s.pairs_skipped = s.rejected = s.seq_gaps = s.rate_limited = {1};
  s.latency_median_us = s.latency_p99_us = {1.0};
  std::vector<uint8_t> bytes = Encode(s);
  // fingerprint 8, utime 8, "b" 6, "" 5, "signed" 11, count 4 -> client_id[0] at 42.
  bytes[42] = 0x80, bytes[43] = 0, bytes[44] = 0, bytes[45] = 0;
  EXPECT_FALSE(DecodeChecked<status_t>(bytes.data(), bytes.size(), {}).ok());
}

template <class T>
size_t LargestAllocationDecoding(const std::vector<uint8_t>& bytes, std::string* problem) {
  g_largest = 0;
  g_tracking = true;
  const DecodeResult<T> got = DecodeChecked<T>(bytes.data(), bytes.size(), WireLimits{});
  g_tracking = false;
  *problem = got.problem;
  return g_largest;
}

void PutInt32(std::vector<uint8_t>* bytes, size_t at, int32_t v) {
  for (int i = 0; i < 4; ++i) (*bytes)[at + i] = static_cast<uint8_t>(static_cast<uint32_t>(v) >> (24 - 8 * i));
}

TEST(CheckedDecode, HugeLinkCountIsRefusedWithoutAllocating) {
  tracker_pose_t m = RandomMessages(17).Pose();
  m.client_id = "alice";
  m.num_links = 0;
  m.position.clear(), m.orientation.clear();
  std::vector<uint8_t> bytes = Encode(m);  // 8 + 8 + 10 + 8 + 8 + 4 + 32 = 78 bytes.
  PutInt32(&bytes, 42, 1 << 26);
  std::string problem;
  EXPECT_LT(LargestAllocationDecoding<tracker_pose_t>(bytes, &problem), 1024u);
  EXPECT_NE(problem.find("num_links at byte 42 is 67108864, outside [0, 1024]"), std::string::npos)
      << problem;
  PutInt32(&bytes, 42, 1000);  // Within the limit but not within the bytes.
  EXPECT_LT(LargestAllocationDecoding<tracker_pose_t>(bytes, &problem), 1024u);
  EXPECT_NE(problem.find("only 32 bytes follow"), std::string::npos) << problem;
  PutInt32(&bytes, 42, -1);
  EXPECT_LT(LargestAllocationDecoding<tracker_pose_t>(bytes, &problem), 1024u);
  EXPECT_FALSE(problem.empty());
}

// A join of client "alice" with no links and no rules: every count at a
// known byte.
join_request_t EmptyJoin(uint64_t seed) {
  join_request_t j = RandomMessages(seed).Join();
  j.client_id = "alice";
  j.num_links = 0;
  j.link_name.clear(), j.parent.clear(), j.a.clear(), j.b.clear(), j.radius.clear();
  j.num_ignore = 0;
  j.ignore.clear();
  j.num_ignore_entities = 0;
  j.ignore_entity_link.clear(), j.ignore_entity.clear(), j.ignore_entity_other_link.clear();
  return j;
}

TEST(CheckedDecode, HugeJoinLinkCountIsRefusedWithoutAllocating) {
  std::vector<uint8_t> bytes = Encode(EmptyJoin(19));
  // fingerprint 8, utime 8, "alice" 10, nonce 8, public_key 32, motion 1, eps 8, delta 8.
  PutInt32(&bytes, 83, 1 << 26);
  std::string problem;
  EXPECT_LT(LargestAllocationDecoding<join_request_t>(bytes, &problem), 1024u);
  EXPECT_NE(problem.find("num_links at byte 83 is 67108864, outside [0, 1024]"), std::string::npos)
      << problem;
  PutInt32(&bytes, 83, 1000);  // Within the limit but not within the bytes.
  EXPECT_LT(LargestAllocationDecoding<join_request_t>(bytes, &problem), 1024u);
  EXPECT_NE(problem.find("bytes follow"), std::string::npos) << problem;
}

TEST(CheckedDecode, HugeJoinEntityRuleCountIsRefusedWithoutAllocating) {
  std::vector<uint8_t> bytes = Encode(EmptyJoin(23));
  ASSERT_TRUE(CheckWire(static_cast<const join_request_t*>(nullptr), bytes.data(), bytes.size(),
                        WireLimits{})
                  .empty());
  // As above, then num_links and num_ignore (4 bytes each): num_ignore_entities at 91.
  PutInt32(&bytes, 91, 1 << 26);
  std::string problem;
  EXPECT_LT(LargestAllocationDecoding<join_request_t>(bytes, &problem), 1024u);
  EXPECT_NE(problem.find("num_ignore_entities at byte 91 is 67108864, outside [0, 256]"),
            std::string::npos)
      << problem;
  PutInt32(&bytes, 91, 200);  // Within the limit, but 200 rules need 2400 bytes at least.
  EXPECT_LT(LargestAllocationDecoding<join_request_t>(bytes, &problem), 1024u);
  EXPECT_NE(problem.find("num_ignore_entities at byte 91 is 200 but only 32 bytes follow"),
            std::string::npos)
      << problem;
}

TEST(CheckedDecode, HugeClientCountIsRefusedWithoutAllocating) {
  status_t s = RandomMessages(18).Status();
  s.backend = "b", s.renderer = "", s.security = "signed";
  s.num_clients = 0;
  s.client_id.clear(), s.poses_received.clear(), s.pairs_answered.clear();
  s.pairs_skipped.clear(), s.rejected.clear(), s.seq_gaps.clear();
  s.latency_median_us.clear(), s.latency_p99_us.clear();
  std::vector<uint8_t> bytes = Encode(s);
  PutInt32(&bytes, 38, 1 << 24);
  std::string problem;
  EXPECT_LT(LargestAllocationDecoding<status_t>(bytes, &problem), 1024u);
  EXPECT_NE(problem.find("num_clients"), std::string::npos) << problem;
}

TEST(CheckedDecode, HugeContactCountIsRefusedWithoutAllocating) {
  contact_event_t e = RandomMessages(19).Contact();
  e.contacts.clear(), e.links.clear();
  e.num_contacts = e.num_links = 0;
  e.client_id = "a", e.error = "";
  std::vector<uint8_t> bytes = Encode(e);
  // 8 + 8 + 6 + 40 + 1 + 5 + 2 + 32 = 102: num_contacts.
  PutInt32(&bytes, 102, 1 << 26);
  std::string problem;
  EXPECT_LT(LargestAllocationDecoding<contact_event_t>(bytes, &problem), 1024u);
  EXPECT_NE(problem.find("num_contacts at byte 102 is 67108864"), std::string::npos) << problem;
}

TEST(CheckedDecode, HugeSharedEntryCountIsRefusedWithoutAllocating) {
  shared_contact_t e = RandomMessages(20).SharedContact();
  e.entries.clear();
  e.num_entries = 0;
  e.client_id = "a";
  std::vector<uint8_t> bytes = Encode(e);
  // 8 + 8 + 6 + 6 * 8 = 70: num_entries.
  PutInt32(&bytes, 70, 1 << 26);
  std::string problem;
  EXPECT_LT(LargestAllocationDecoding<shared_contact_t>(bytes, &problem), 1024u);
  EXPECT_NE(problem.find("num_entries at byte 70 is 67108864"), std::string::npos) << problem;
}

TEST(CheckedDecode, SharedEntriesOverTheLimitAreRefused) {
  shared_contact_t e = RandomMessages(21).SharedContact();
  e.client_id = "a";
  const shared_entry_t one = RandomMessages(22).SharedEntry();
  e.entries.assign(static_cast<size_t>(shared_contact_t::MAX_ENTRIES) + 1, one);
  e.num_entries = static_cast<int32_t>(e.entries.size());
  const std::vector<uint8_t> bytes = Encode(e);
  const DecodeResult<shared_contact_t> d =
      DecodeChecked<shared_contact_t>(bytes.data(), bytes.size(), WireLimits{});
  ASSERT_FALSE(d.ok());
  EXPECT_NE(d.problem.find("num_entries at byte 70 is 65, outside [0, 64]"), std::string::npos)
      << d.problem;
  e.entries.pop_back();
  e.num_entries = static_cast<int32_t>(e.entries.size());
  const std::vector<uint8_t> fits = Encode(e);
  EXPECT_TRUE((DecodeChecked<shared_contact_t>(fits.data(), fits.size(), WireLimits{}).ok()));
}

TEST(CheckedDecode, HugeContactCountInASharedEntryIsRefusedWithoutAllocating) {
  shared_contact_t e = RandomMessages(20).SharedContact();
  e.client_id = "a";
  shared_entry_t entry = RandomMessages(23).SharedEntry();
  entry.contacts.clear();
  entry.num_contacts = 0;
  entry.entity = "e", entry.error = "";
  e.entries = {entry};
  e.num_entries = 1;
  std::vector<uint8_t> bytes = Encode(e);
  // 70 + 4 (num_entries) + 6 (entity) + 17 + 1 + 5 (error) + 2 + 32 = 137: num_contacts.
  PutInt32(&bytes, 137, 1 << 26);
  std::string problem;
  EXPECT_LT(LargestAllocationDecoding<shared_contact_t>(bytes, &problem), 1024u);
  EXPECT_NE(problem.find("entries[].num_contacts at byte 137 is 67108864"), std::string::npos)
      << problem;
}

TEST(CheckedDecode, AllocationFailureIsARefusalNotAnAbort) {
  tracker_pose_t m = RandomMessages(23).Pose();
  m.client_id = "alice";
  m.num_links = 1000;
  m.position.assign(1000, std::vector<double>(3, 0.5));
  m.orientation.assign(1000, std::vector<double>(4, 0.5));
  const std::vector<uint8_t> bytes = Encode(m);
  g_fail_above = 4096;  // The decoder's vector of 1000 links needs more.
  g_tracking = true;
  const DecodeResult<tracker_pose_t> got = DecodeChecked<tracker_pose_t>(bytes.data(), bytes.size(), {});
  g_tracking = false;
  g_fail_above = SIZE_MAX;
  ASSERT_FALSE(got.ok());
  EXPECT_EQ(got.problem, "out of memory decoding " + std::to_string(bytes.size()) + " bytes");
  EXPECT_TRUE(DecodeChecked<tracker_pose_t>(bytes.data(), bytes.size(), {}).ok());
}

TEST(CheckedDecode, LimitsAreHonoured) {
  WireLimits limits;
  limits.max_links = 3;
  limits.max_id_bytes = 5;
  tracker_pose_t m = RandomMessages(20).Pose();
  m.client_id = "alice";
  m.num_links = 3;
  m.position.assign(3, std::vector<double>(3, 0.5));
  m.orientation.assign(3, std::vector<double>(4, 0.5));
  EXPECT_TRUE(DecodeChecked<tracker_pose_t>(Encode(m).data(), Encode(m).size(), limits).ok());
  m.num_links = 4;
  m.position.assign(4, std::vector<double>(3, 0.5));
  m.orientation.assign(4, std::vector<double>(4, 0.5));
  std::vector<uint8_t> bytes = Encode(m);
  EXPECT_FALSE(DecodeChecked<tracker_pose_t>(bytes.data(), bytes.size(), limits).ok());
  m.num_links = 3;
  m.position.resize(3), m.orientation.resize(3);
  m.client_id = "alice6";
  bytes = Encode(m);
  const auto got = DecodeChecked<tracker_pose_t>(bytes.data(), bytes.size(), limits);
  ASSERT_FALSE(got.ok());
  EXPECT_NE(got.problem.find("over the limit of 5"), std::string::npos) << got.problem;
  limits.max_message_bytes = bytes.size() - 1;
  limits.max_id_bytes = 64;
  EXPECT_FALSE(DecodeChecked<tracker_pose_t>(bytes.data(), bytes.size(), limits).ok());
}

TEST(CheckedDecode, WrongFingerprintAndInnerNulAreRefused) {
  RandomMessages r(21);
  const std::vector<uint8_t> pose = Encode(r.Pose());
  EXPECT_NE(DecodeChecked<rejection_t>(pose.data(), pose.size(), {}).problem.find("fingerprint"),
            std::string::npos);
  tracker_pose_t m = r.Pose();
  m.client_id = "ab";
  std::vector<uint8_t> bytes = Encode(m);
  bytes[20] = 0;  // "\0b"
  const auto got = DecodeChecked<tracker_pose_t>(bytes.data(), bytes.size(), {});
  ASSERT_FALSE(got.ok());
  EXPECT_NE(got.problem.find("NUL"), std::string::npos) << got.problem;
}

TEST(CheckedDecode, PeekPoseClientIdReadsTheId) {
  tracker_pose_t m = RandomMessages(22).Pose();
  m.client_id = "bob.2";
  const std::vector<uint8_t> bytes = Encode(m);
  EXPECT_EQ(PeekPoseClientId(bytes.data(), bytes.size()), "bob.2");
}

}  // namespace
}  // namespace sweptccd
