// Live clients (docs/SERVICE.md, "Live clients") on memq:// in one process:
// join, answers, leave, silence, every kind of refused join, two joins racing
// for one id, and the signed-mode key rules (a second party holding only the
// room key cannot take over a live id). Waits on WaitUntilIdle; the silence
// test waits for the drop with a deadline, never asserting on a time.
#include <gtest/gtest.h>

#include <array>
#include <chrono>
#include <lcm/lcm-cpp.hpp>
#include <map>
#include <mutex>
#include <thread>

#include "msgs/checked_decode.h"
#include "msgs/signing.h"
#include "service/collision_service.h"
#include "service/daemon/daemon.h"
#include "sweptccd/join_reply_t.hpp"
#include "sweptccd/join_request_t.hpp"
#include "sweptccd/leave_t.hpp"
#include "sweptccd/shared_contact_t.hpp"
#include "tests/service/service_test_util.h"

namespace sweptccd {
namespace {

using test::Sample;

int64_t Now() {
  return std::chrono::duration_cast<std::chrono::microseconds>(
             std::chrono::system_clock::now().time_since_epoch())
      .count();
}

struct Replies {
  void On(const lcm::ReceiveBuffer* rbuf, const std::string&) {
    DecodeResult<join_reply_t> r = DecodeChecked<join_reply_t>(rbuf->data, rbuf->data_size, {});
    ASSERT_TRUE(r.ok()) << r.problem;
    std::lock_guard<std::mutex> lock(mutex);
    replies.push_back(*r.message);
    raw.emplace_back(static_cast<const uint8_t*>(rbuf->data),
                     static_cast<const uint8_t*>(rbuf->data) + rbuf->data_size);
  }
  std::vector<join_reply_t> Get() {
    std::lock_guard<std::mutex> lock(mutex);
    return replies;
  }
  std::mutex mutex;
  std::vector<join_reply_t> replies;
  std::vector<std::vector<uint8_t>> raw;
};

class LiveSessionTest : public ::testing::Test {
 protected:
  void Configure(const std::string& name, bool signed_mode = false) {
    const std::string dir = test::TestDir("live_session_test_" + name);
    config_.security.room_key = dir + "/room.key";
    WriteNewKeyFile(config_.security.room_key);
    room_key_ = LoadKeyFile(config_.security.room_key);
    config_.lcm_url = "memq://";
    config_.environment = {test::WriteFloorObj(dir)};
    ClientSpec spec;
    spec.id = "a";
    spec.skeleton_path = test::WriteTwoLinkSkeleton(dir);
    config_.clients.push_back(spec);
    config_.backend = gpu::BackendKind::kCpu;
    config_.status_period_s = 3600;
    config_.log_level = "warn";
    config_.security.mode = signed_mode ? "signed" : "unsigned";
  }

  void Build() {
    ValidateServiceConfig(config_);
    daemon_ = std::make_unique<Daemon>(config_);
    listener_.SubscribeTo(daemon_->lcm());
    daemon_->lcm()->subscribe(kJoinReplyChannel, &Replies::On, &replies_);
  }

  join_request_t JoinOf(const std::string& id, int64_t nonce) {
    join_request_t j;
    j.utime = Now();
    j.client_id = id;
    j.nonce = nonce;
    std::fill(std::begin(j.public_key), std::end(j.public_key), uint8_t{0});
    j.motion = join_request_t::MOTION_ARTICULATED;
    j.eps_s = 0;
    j.delta_m = 0;
    const auto skeleton = test::TwoLinkSkeleton();
    j.num_links = skeleton->num_links();
    for (const Link& l : skeleton->links()) {
      j.link_name.push_back(l.name);
      j.parent.push_back(l.parent);
      j.a.push_back({l.a_L.x(), l.a_L.y(), l.a_L.z()});
      j.b.push_back({l.b_L.x(), l.b_L.y(), l.b_L.z()});
      j.radius.push_back(l.radius);
    }
    j.num_ignore = 0;
    j.num_ignore_entities = 0;
    return j;
  }

  template <class T>
  void Send(const std::string& channel, const T& m, const MacKey* key = nullptr) {
    const std::vector<uint8_t> bytes = EncodeSigned(m, key);
    ASSERT_EQ(daemon_->lcm()->publish(channel, bytes.data(), static_cast<unsigned>(bytes.size())),
              0);
  }

  // Sends a join, waits, returns its reply (the last one).
  join_reply_t Join(const join_request_t& j, const MacKey* key = nullptr) {
    const size_t before = replies_.Get().size();
    Send(kJoinChannel, j, key);
    daemon_->WaitUntilIdle();
    const std::vector<join_reply_t> got = replies_.Get();
    EXPECT_EQ(got.size(), before + 1);
    return got.empty() ? join_reply_t{} : got.back();
  }

  std::vector<std::string> StatusIds() {
    const status_t s = daemon_->service()->Status();
    return s.client_id;
  }

  ServiceConfig config_;
  std::optional<MacKey> room_key_;
  std::unique_ptr<Daemon> daemon_;
  test::Listener listener_;
  Replies replies_;
};

TEST_F(LiveSessionTest, JoinAnswersExactlyLikeAConfiguredClientThenLeaves) {
  Configure("answers");
  Build();
  const join_reply_t reply = Join(JoinOf("live1", 7));
  ASSERT_EQ(reply.reason, +join_reply_t::REASON_ACCEPTED) << reply.message;
  EXPECT_EQ(reply.client_id, "live1");
  EXPECT_EQ(reply.nonce, 7);
  EXPECT_GT(reply.session, 0);
  EXPECT_EQ(reply.instance, daemon_->service()->instance());
  EXPECT_EQ(reply.silence_timeout_ms, config_.silence_timeout_ms);
  EXPECT_EQ(reply.sealed_key_size, 0);  // Unsigned mode.
  EXPECT_EQ(StatusIds(), (std::vector<std::string>{"a", "live1"}));

  for (int64_t k = 0; k < 16; ++k) {  // Contact from pose 13 on.
    tracker_pose_t live = Sample("live1", k);
    live.session = reply.session;
    Send(kPoseChannel, live);
    Send(kPoseChannel, Sample("a", k));
    daemon_->WaitUntilIdle();
  }
  ASSERT_TRUE(listener_.rejections().empty()) << listener_.rejections()[0].message;
  std::vector<contact_event_t> a, live;
  for (const contact_event_t& e : listener_.contacts()) (e.client_id == "a" ? a : live).push_back(e);
  ASSERT_EQ(live.size(), 15u);
  ASSERT_EQ(a.size(), 15u);
  int contacts = 0;
  for (size_t i = 0; i < a.size(); ++i) {
    EXPECT_EQ(live[i].pair, a[i].pair);
    EXPECT_EQ(live[i].result, a[i].result);
    EXPECT_EQ(live[i].s_lo, a[i].s_lo);
    EXPECT_EQ(live[i].s_hi, a[i].s_hi);
    EXPECT_EQ(live[i].num_contacts, a[i].num_contacts);
    contacts += live[i].result == contact_event_t::RESULT_CONTACT;
  }
  EXPECT_GT(contacts, 0);

  leave_t leave;
  leave.utime = Now();
  leave.client_id = "live1";
  leave.session = reply.session;
  Send(kLeaveChannel, leave);
  daemon_->WaitUntilIdle();
  EXPECT_EQ(StatusIds(), (std::vector<std::string>{"a"}));
  const status_t s = daemon_->service()->Status();
  EXPECT_EQ(s.live_joined, 1);
  EXPECT_EQ(s.live_left, 1);
  EXPECT_EQ(s.live_expired, 0);
  tracker_pose_t after = Sample("live1", 16);
  after.session = reply.session;
  Send(kPoseChannel, after);
  daemon_->WaitUntilIdle();
  ASSERT_EQ(listener_.rejections().size(), 1u);
  EXPECT_EQ(listener_.rejections()[0].reason, "unknown_client");
}

TEST_F(LiveSessionTest, AWrongSessionIsStaleAndTheSameNonceGetsTheSameSession) {
  Configure("session");
  Build();
  const join_reply_t first = Join(JoinOf("live1", 7));
  ASSERT_EQ(first.reason, +join_reply_t::REASON_ACCEPTED);
  const join_reply_t again = Join(JoinOf("live1", 7));  // A lost reply, asked again.
  ASSERT_EQ(again.reason, +join_reply_t::REASON_ACCEPTED);
  EXPECT_EQ(again.session, first.session);
  tracker_pose_t p = Sample("live1", 0);
  p.session = first.session + 1;
  Send(kPoseChannel, p);
  daemon_->WaitUntilIdle();
  ASSERT_EQ(listener_.rejections().size(), 1u);
  EXPECT_EQ(listener_.rejections()[0].reason, "stale_session");
  // A leave naming another session leaves nothing.
  leave_t leave;
  leave.utime = Now();
  leave.client_id = "live1";
  leave.session = first.session - 1;
  Send(kLeaveChannel, leave);
  daemon_->WaitUntilIdle();
  EXPECT_EQ(daemon_->service()->live_clients(), 1);
}

TEST_F(LiveSessionTest, SilenceDropsTheClientAndStatusSaysSo) {
  Configure("silence");
  config_.silence_timeout_ms = 100;
  Build();
  daemon_->Start();
  const join_reply_t reply = Join(JoinOf("quiet", 1));
  ASSERT_EQ(reply.reason, +join_reply_t::REASON_ACCEPTED);
  // Waits for the drop (at most 10 s: a hung daemon fails, a slow one passes).
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(10);
  while (daemon_->service()->live_clients() > 0 && std::chrono::steady_clock::now() < deadline) {
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
  }
  EXPECT_EQ(daemon_->service()->live_clients(), 0);
  const status_t s = daemon_->service()->Status();
  EXPECT_EQ(s.live_expired, 1);
  EXPECT_EQ(s.client_id, (std::vector<std::string>{"a"}));
  // The id is free again.
  EXPECT_EQ(Join(JoinOf("quiet", 2)).reason, +join_reply_t::REASON_ACCEPTED);
}

TEST_F(LiveSessionTest, EveryKindOfRefusalHasItsCodeAndOneLine) {
  Configure("refusals");
  config_.max_links = 2;
  config_.max_live_clients = 2;
  Build();
  ASSERT_EQ(Join(JoinOf("first", 1)).reason, +join_reply_t::REASON_ACCEPTED);

  struct Case {
    const char* what;
    join_request_t join;
    int8_t reason;
    const char* must_contain;
  };
  std::vector<Case> cases;
  join_request_t two_roots = JoinOf("x1", 2);
  two_roots.parent[1] = -1;
  cases.push_back({"two roots", two_roots, +join_reply_t::REASON_BAD_SKELETON, "root"});
  join_request_t bad_parent = JoinOf("x2", 2);
  bad_parent.parent[1] = 5;
  cases.push_back({"parent out of range", bad_parent, +join_reply_t::REASON_BAD_SKELETON,
                   "parent index 5"});
  join_request_t zero_radius = JoinOf("x3", 2);
  zero_radius.radius[0] = 0;
  cases.push_back({"radius 0", zero_radius, +join_reply_t::REASON_BAD_SKELETON, "radius"});
  cases.push_back({"id in use", JoinOf("first", 99), +join_reply_t::REASON_ID_IN_USE,
                   "in use by another live session"});
  cases.push_back({"configured id", JoinOf("a", 3), +join_reply_t::REASON_ID_IN_USE,
                   "configured client"});
  join_request_t three = JoinOf("x4", 2);
  three.num_links = 3;
  three.link_name.push_back("hand");
  three.parent.push_back(1);
  three.a.push_back({0, 0, 0});
  three.b.push_back({0.1, 0, 0});
  three.radius.push_back(0.03);
  cases.push_back({"too many links", three, +join_reply_t::REASON_TOO_MANY_LINKS, "max_links 2"});
  join_request_t filter = JoinOf("x5", 2);
  filter.num_ignore = 1;
  filter.ignore = {"nolink:0"};
  cases.push_back({"bad filter", filter, +join_reply_t::REASON_BAD_FILTER, "nolink"});
  join_request_t entity_filter = JoinOf("x9", 2);
  entity_filter.num_ignore_entities = 1;
  entity_filter.ignore_entity_link = {"arm"};
  entity_filter.ignore_entity = {"a"};
  entity_filter.ignore_entity_other_link = {""};
  cases.push_back({"entity filter, no shared world", entity_filter,
                   +join_reply_t::REASON_BAD_FILTER, "shared_world: false"});
  join_request_t motion = JoinOf("x6", 2);
  motion.motion = 5;
  cases.push_back({"bad motion", motion, +join_reply_t::REASON_BAD_OPTIONS, "motion 5"});
  join_request_t eps = JoinOf("x7", 2);
  eps.eps_s = -1;
  cases.push_back({"bad tolerance", eps, +join_reply_t::REASON_BAD_OPTIONS, "tolerances"});
  join_request_t stale = JoinOf("x8", 2);
  stale.utime = 1;
  cases.push_back({"stale request", stale, +join_reply_t::REASON_STALE_REQUEST, "clock"});
  for (const Case& c : cases) {
    const join_reply_t r = Join(c.join);
    EXPECT_EQ(r.reason, c.reason) << c.what << ": " << r.message;
    EXPECT_NE(r.message.find(c.must_contain), std::string::npos) << c.what << ": " << r.message;
    EXPECT_EQ(r.message.find('\n'), std::string::npos) << c.what;
    EXPECT_EQ(r.session, 0) << c.what;
  }
  ASSERT_EQ(Join(JoinOf("second", 1)).reason, +join_reply_t::REASON_ACCEPTED);
  const join_reply_t full = Join(JoinOf("third", 1));
  EXPECT_EQ(full.reason, +join_reply_t::REASON_TOO_MANY_CLIENTS) << full.message;
  EXPECT_EQ(daemon_->service()->live_clients(), 2);

  // An id breaking the rule gets no reply: a bad_client_id rejection.
  Send(kJoinChannel, JoinOf("bad id", 1));
  daemon_->WaitUntilIdle();
  ASSERT_FALSE(listener_.rejections().empty());
  EXPECT_EQ(listener_.rejections().back().reason, "bad_client_id");
}

struct SharedContacts {
  void On(const lcm::ReceiveBuffer* rbuf, const std::string&) {
    DecodeResult<shared_contact_t> r =
        DecodeChecked<shared_contact_t>(rbuf->data, rbuf->data_size, {});
    ASSERT_TRUE(r.ok()) << r.problem;
    std::lock_guard<std::mutex> lock(mutex);
    for (const shared_entry_t& e : r.message->entries) {
      results[{r.message->client_id, e.entity}].push_back(e.result);
    }
  }
  std::mutex mutex;
  std::map<std::pair<std::string, std::string>, std::vector<int8_t>> results;  // (A, E).
};

// A join's ignore_entity rules reach the shared world: resolved against the
// joining skeleton (and a configured client's, by name), applied to both
// avatars' answers; a rule that cannot be resolved is refused, naming it.
TEST_F(LiveSessionTest, AJoinsEntityFiltersApplyToTheSharedWorld) {
  Configure("entity_filters");
  config_.shared_world = true;
  Build();
  SharedContacts shared;
  daemon_->lcm()->subscribe(kSharedContactChannel, &SharedContacts::On, &shared);
  auto with_rules = [&](const std::string& id, std::vector<std::array<std::string, 3>> rules) {
    join_request_t j = JoinOf(id, 1);
    j.num_ignore_entities = static_cast<int32_t>(rules.size());
    for (const auto& r : rules) {
      j.ignore_entity_link.push_back(r[0]);
      j.ignore_entity.push_back(r[1]);
      j.ignore_entity_other_link.push_back(r[2]);
    }
    return j;
  };
  struct Refused {
    std::vector<std::array<std::string, 3>> rules;
    const char* must_contain;
  };
  const std::vector<Refused> refused = {
      {{{"nolink", "a", ""}}, "unknown link 'nolink' in skeleton 'bad'"},
      {{{"arm", "a", "nolink"}}, "other_link: unknown link 'nolink' in skeleton 'two'"},
      {{{"arm", "bad id", ""}}, "breaks the id rule"},
      {{{"arm", "live1", "arm"}}, "not a configured client; give an index"},
  };
  for (const Refused& r : refused) {
    const join_reply_t reply = Join(with_rules("bad", r.rules));
    EXPECT_EQ(reply.reason, +join_reply_t::REASON_BAD_FILTER) << reply.message;
    EXPECT_NE(reply.message.find(r.must_contain), std::string::npos) << reply.message;
  }
  // live1 ignores every link of a; live2 ignores each of the four link
  // pairs with a one by one (names, an index, "*"). At the same poses every
  // link of one touches every link of the other, so a rule that is lost or
  // resolved to the wrong link leaves a contact.
  const join_reply_t one = Join(with_rules("live1", {{"*", "a", ""}}));
  const join_reply_t two = Join(with_rules(
      "live2", {{"pelvis", "a", "pelvis"}, {"pelvis", "a", "1"}, {"arm", "a", "*"}}));
  ASSERT_EQ(one.reason, +join_reply_t::REASON_ACCEPTED) << one.message;
  ASSERT_EQ(two.reason, +join_reply_t::REASON_ACCEPTED) << two.message;
  for (int64_t k = 0; k < 6; ++k) {
    Send(kPoseChannel, Sample("a", k));
    for (const join_reply_t* live : {&one, &two}) {
      tracker_pose_t p = Sample(live->client_id, k);
      p.session = live->session;
      Send(kPoseChannel, p);
    }
    daemon_->WaitUntilIdle();
  }
  ASSERT_TRUE(listener_.rejections().empty()) << listener_.rejections()[0].message;
  std::lock_guard<std::mutex> lock(shared.mutex);
  const std::vector<int8_t> free(5, +shared_entry_t::RESULT_FREE);
  const std::vector<int8_t> contact(5, +shared_entry_t::RESULT_CONTACT);
  using Key = std::pair<std::string, std::string>;
  EXPECT_EQ(shared.results[Key("live1", "a")], free);
  EXPECT_EQ(shared.results[Key("a", "live1")], free);  // A rule of either avatar.
  EXPECT_EQ(shared.results[Key("live2", "a")], free);
  EXPECT_EQ(shared.results[Key("a", "live2")], free);
  EXPECT_EQ(shared.results[Key("live1", "live2")], contact);  // No rule between them.
  EXPECT_EQ(shared.results[Key("live2", "live1")], contact);
}

TEST_F(LiveSessionTest, TwoJoinsRacingForOneIdGetOneSession) {
  Configure("race");
  Build();
  const size_t before = replies_.Get().size();
  Send(kJoinChannel, JoinOf("contested", 1));
  Send(kJoinChannel, JoinOf("contested", 2));
  daemon_->WaitUntilIdle();
  const std::vector<join_reply_t> got = replies_.Get();
  ASSERT_EQ(got.size(), before + 2);
  int accepted = 0, in_use = 0;
  for (size_t i = before; i < got.size(); ++i) {
    accepted += got[i].reason == +join_reply_t::REASON_ACCEPTED;
    in_use += got[i].reason == +join_reply_t::REASON_ID_IN_USE;
  }
  EXPECT_EQ(accepted, 1);
  EXPECT_EQ(in_use, 1);
  EXPECT_EQ(daemon_->service()->live_clients(), 1);
}

TEST_F(LiveSessionTest, SignedModeOnlyTheSessionKeySpeaksForALiveId) {
  Configure("signed", /*signed_mode=*/true);
  Build();
  const MacKey& room = *room_key_;
  const BoxKeyPair pair = NewBoxKeyPair();
  join_request_t j = JoinOf("vr1", 11);
  std::copy(pair.public_key.begin(), pair.public_key.end(), j.public_key);
  // A join not signed with the room key: no reply, a bad_signature rejection.
  const MacKey stranger = NewRandomKey();
  Send(kJoinChannel, j, &stranger);
  daemon_->WaitUntilIdle();
  EXPECT_TRUE(replies_.Get().empty());
  ASSERT_EQ(listener_.rejections().size(), 1u);
  EXPECT_EQ(listener_.rejections()[0].reason, "bad_signature");

  const join_reply_t reply = Join(j, &room);
  ASSERT_EQ(reply.reason, +join_reply_t::REASON_ACCEPTED) << reply.message;
  ASSERT_EQ(reply.sealed_key_size, static_cast<int32_t>(kSealedKeyBytes));
  EXPECT_TRUE(VerifyEncoded(replies_.raw.back().data(), replies_.raw.back().size(), room));
  const std::optional<MacKey> session_key =
      OpenSealedKey(reply.sealed_key.data(), reply.sealed_key.size(), pair);
  ASSERT_TRUE(session_key.has_value());
  // Another key pair cannot open it.
  EXPECT_FALSE(OpenSealedKey(reply.sealed_key.data(), reply.sealed_key.size(), NewBoxKeyPair()));

  // A second party with the room key: its join is refused, its poses and
  // leave (room key) do not verify.
  const BoxKeyPair thief = NewBoxKeyPair();
  join_request_t hijack = JoinOf("vr1", 12);
  std::copy(thief.public_key.begin(), thief.public_key.end(), hijack.public_key);
  EXPECT_EQ(Join(hijack, &room).reason, +join_reply_t::REASON_ID_IN_USE);
  tracker_pose_t forged = Sample("vr1", 0);
  forged.session = reply.session;
  Send(kPoseChannel, forged, &room);
  leave_t leave;
  leave.utime = Now();
  leave.client_id = "vr1";
  leave.session = reply.session;
  Send(kLeaveChannel, leave, &room);
  daemon_->WaitUntilIdle();
  ASSERT_EQ(listener_.rejections().size(), 3u);
  EXPECT_EQ(listener_.rejections()[1].reason, "bad_signature");
  EXPECT_EQ(listener_.rejections()[2].reason, "bad_signature");
  EXPECT_EQ(daemon_->service()->live_clients(), 1);
  EXPECT_TRUE(listener_.contacts().empty());

  // The client itself, with the session key.
  for (int64_t k = 0; k < 3; ++k) {
    tracker_pose_t p = Sample("vr1", k);
    p.session = reply.session;
    Send(kPoseChannel, p, &*session_key);
    daemon_->WaitUntilIdle();
  }
  EXPECT_EQ(listener_.contacts().size(), 2u);
  Send(kLeaveChannel, leave, &*session_key);
  daemon_->WaitUntilIdle();
  EXPECT_EQ(daemon_->service()->live_clients(), 0);
  // The configured client keeps working with the room key.
  Send(kPoseChannel, Sample("a", 0), &room);
  Send(kPoseChannel, Sample("a", 1), &room);
  daemon_->WaitUntilIdle();
  EXPECT_EQ(listener_.contacts().size(), 3u);
  EXPECT_EQ(listener_.rejections().size(), 3u);
}

}  // namespace
}  // namespace sweptccd
