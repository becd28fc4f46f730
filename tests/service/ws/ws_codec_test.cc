// The WebSocket door's codec (service/ws): proofs (the worked example of
// docs/WEBSOCKET.md section 4), every LCM type through JSON and back equal
// byte for byte under the LCM encoder for seeded random messages, every
// error code of the client message decoder, the send queue, static files,
// the display scene and the door's options.

#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <random>

#include "service/ws/client_message.h"
#include "service/ws/door_options.h"
#include "service/ws/json_fields.h"
#include "service/ws/lcm_json.h"
#include "service/ws/proof.h"
#include "service/ws/scene.h"
#include "service/ws/send_queue.h"
#include "service/ws/static_files.h"

namespace sweptccd::ws {
namespace {

MacKey ExampleKey() {
  std::array<uint8_t, kKeyBytes> bytes{};
  for (size_t i = 0; i < bytes.size(); ++i) bytes[i] = static_cast<uint8_t>(i);
  return MacKey(bytes);
}

const char* kChallenge = "00112233445566778899aabbccddeeff00112233445566778899aabbccddeeff";

TEST(WsProof, WorkedExample) {
  const MacKey key = ExampleKey();
  EXPECT_EQ(ProofMessage(ProofKind::kJoin, kChallenge, "alice"),
            std::string("sweptccd-ws-v1 join\n") + kChallenge + "\nalice");
  EXPECT_EQ(ComputeProof(key, ProofKind::kJoin, kChallenge, "alice"),
            "e6bd9e779431f0b57eefbb0ff3014338726980284db0c9faa24c73edcfbbe43a");
  EXPECT_EQ(ComputeProof(key, ProofKind::kSubscribe, kChallenge, ""),
            "2be968d980c0efd035390f7580e7e47ee8712d12a5958cd6a1b0475285f22249");
  EXPECT_EQ(ComputeProof(key, ProofKind::kObject, kChallenge, "ball"),
            "c4186d0519862a982fb5265688bcc74de86705923a38735cb8d8e4ea18a21e0a");
}

TEST(WsProof, VerifiesOnlyTheRightProof) {
  const MacKey key = ExampleKey();
  const std::string proof = ComputeProof(key, ProofKind::kJoin, kChallenge, "alice");
  EXPECT_TRUE(VerifyProof(key, ProofKind::kJoin, kChallenge, "alice", proof));
  std::string upper = proof;
  for (char& c : upper) c = static_cast<char>(std::toupper(static_cast<unsigned char>(c)));
  EXPECT_TRUE(VerifyProof(key, ProofKind::kJoin, kChallenge, "alice", upper));
  EXPECT_FALSE(VerifyProof(key, ProofKind::kJoin, kChallenge, "bob", proof));
  EXPECT_FALSE(VerifyProof(key, ProofKind::kSubscribe, kChallenge, "alice", proof));
  EXPECT_FALSE(VerifyProof(key, ProofKind::kJoin, std::string(64, '0'), "alice", proof));
  EXPECT_FALSE(VerifyProof(key, ProofKind::kJoin, kChallenge, "alice", ""));
  EXPECT_FALSE(VerifyProof(key, ProofKind::kJoin, kChallenge, "alice", proof.substr(1)));
  std::string flipped = proof;
  flipped[10] = flipped[10] == '0' ? '1' : '0';
  EXPECT_FALSE(VerifyProof(key, ProofKind::kJoin, kChallenge, "alice", flipped));
  std::string bad = proof;
  bad[0] = 'g';
  EXPECT_FALSE(VerifyProof(key, ProofKind::kJoin, kChallenge, "alice", bad));
  std::array<uint8_t, kKeyBytes> other{};
  other[0] = 1;
  EXPECT_FALSE(VerifyProof(MacKey(other), ProofKind::kJoin, kChallenge, "alice", proof));
  const std::string a = NewChallenge(), b = NewChallenge();
  EXPECT_EQ(a.size(), 64u);
  EXPECT_NE(a, b);
  EXPECT_EQ(a.find_first_not_of("0123456789abcdef"), std::string::npos);
}

// Seeded random messages.
class Gen {
 public:
  explicit Gen(uint32_t seed) : rng_(seed) {}
  int64_t Int(int64_t lo, int64_t hi) {
    return std::uniform_int_distribution<int64_t>(lo, hi)(rng_);
  }
  int64_t Any() { return Int(-kMaxSafeInteger, kMaxSafeInteger); }
  int32_t I32() { return static_cast<int32_t>(Int(INT32_MIN, INT32_MAX)); }
  int8_t I8() { return static_cast<int8_t>(Int(-128, 127)); }
  int8_t Bool() { return static_cast<int8_t>(Int(0, 1)); }
  double Real() {
    switch (Int(0, 4)) {
      case 0:
        return 0.0;
      case 1:
        return static_cast<double>(Int(-1000, 1000));
      case 2:
        return std::ldexp(std::uniform_real_distribution<double>(-1, 1)(rng_),
                          static_cast<int>(Int(-300, 300)));
      default:
        return std::uniform_real_distribution<double>(-10, 10)(rng_);
    }
  }
  std::string Text(size_t max) {
    std::string s(static_cast<size_t>(Int(0, static_cast<int64_t>(max))), ' ');
    for (char& c : s) c = static_cast<char>(Int(0x20, 0x7e));
    if (Int(0, 3) == 0 && !s.empty()) s[0] = static_cast<char>(Int(1, 0x1f));  // Controls too.
    return s;
  }
  void Reals(double* out, int n) {
    for (int i = 0; i < n; ++i) out[i] = Real();
  }
  std::vector<double> Row(int n) {
    std::vector<double> v(static_cast<size_t>(n));
    Reals(v.data(), n);
    return v;
  }
  contact_record_t Record() {
    contact_record_t c{};
    c.link = I32();
    c.object = I32();
    c.triangle = Any();
    c.s = Real();
    Reals(c.point_link, 3);
    Reals(c.point_env, 3);
    Reals(c.normal, 3);
    c.separation = Real();
    return c;
  }
  entity_contact_t EntityRecord() {
    entity_contact_t c{};
    c.link = I32();
    c.other_link = I32();
    c.triangle = Any();
    c.s = Real();
    Reals(c.point_link, 3);
    Reals(c.point_other, 3);
    Reals(c.normal, 3);
    c.separation = Real();
    return c;
  }
  std::mt19937 rng_;
};

contact_event_t RandomContact(Gen& g) {
  contact_event_t m{};
  m.utime = g.Any();
  m.client_id = g.Text(64);
  m.seq0 = g.Any();
  m.seq1 = g.Any();
  m.pair = g.Any();
  m.utime0 = g.Any();
  m.utime1 = g.Any();
  m.result = g.I8();
  m.error = g.Text(100);
  m.initially_colliding = g.Bool();
  m.undecided = g.Bool();
  m.s_lo = g.Real();
  m.s_hi = g.Real();
  m.t_lo = g.Real();
  m.t_hi = g.Real();
  m.num_contacts = static_cast<int32_t>(g.Int(0, 5));
  for (int i = 0; i < m.num_contacts; ++i) m.contacts.push_back(g.Record());
  m.num_links = static_cast<int32_t>(g.Int(0, 4));
  for (int i = 0; i < m.num_links; ++i) {
    link_bracket_t b{};
    b.link = g.I32();
    b.s_lo = g.Real();
    b.s_hi = g.Real();
    b.t_lo = g.Real();
    b.t_hi = g.Real();
    b.initially_colliding = g.Bool();
    b.undecided = g.Bool();
    b.has_witness = g.Bool();
    b.witness = g.Record();
    m.links.push_back(b);
  }
  m.receive_utime = g.Any();
  m.compute_us = g.Real();
  m.queue_us = g.Real();
  m.skipped_pairs_total = g.Any();
  return m;
}

shared_contact_t RandomShared(Gen& g) {
  shared_contact_t m{};
  m.utime = g.Any();
  m.client_id = g.Text(64);
  m.seq0 = g.Any();
  m.seq1 = g.Any();
  m.pair = g.Any();
  m.utime0 = g.Any();
  m.utime1 = g.Any();
  m.receive_utime = g.Any();
  m.num_entries = static_cast<int32_t>(g.Int(0, 4));
  for (int i = 0; i < m.num_entries; ++i) {
    shared_entry_t e{};
    e.entity = g.Text(64);
    e.entity_kind = g.I8();
    e.t_from = g.Any();
    e.t_to = g.Any();
    e.result = g.I8();
    e.error = g.Text(50);
    e.initially_colliding = g.Bool();
    e.undecided = g.Bool();
    e.s_lo = g.Real();
    e.s_hi = g.Real();
    e.t_lo = g.Real();
    e.t_hi = g.Real();
    e.num_contacts = static_cast<int32_t>(g.Int(0, 3));
    for (int k = 0; k < e.num_contacts; ++k) e.contacts.push_back(g.EntityRecord());
    e.num_links = static_cast<int32_t>(g.Int(0, 3));
    for (int k = 0; k < e.num_links; ++k) {
      entity_link_bracket_t b{};
      b.link = g.I32();
      b.s_lo = g.Real();
      b.s_hi = g.Real();
      b.t_lo = g.Real();
      b.t_hi = g.Real();
      b.initially_colliding = g.Bool();
      b.undecided = g.Bool();
      b.has_witness = g.Bool();
      b.witness = g.EntityRecord();
      e.links.push_back(b);
    }
    e.waited_us = g.Any();
    e.ended_by_timeout = g.Bool();
    e.compute_us = g.Real();
    e.queue_us = g.Real();
    m.entries.push_back(e);
  }
  return m;
}

rejection_t RandomRejection(Gen& g) {
  rejection_t m{};
  m.utime = g.Any();
  m.client_id = g.Text(64);
  m.seq = g.Any();
  m.reason = g.Text(30);
  m.message = g.Text(200);
  m.suppressed = g.Any();
  return m;
}

status_t RandomStatus(Gen& g) {
  status_t m{};
  m.utime = g.Any();
  m.backend = g.Text(40);
  m.renderer = g.Text(40);
  m.security = g.Text(10);
  m.num_clients = static_cast<int32_t>(g.Int(0, 5));
  for (int i = 0; i < m.num_clients; ++i) {
    m.client_id.push_back(g.Text(64));
    m.poses_received.push_back(g.Any());
    m.pairs_answered.push_back(g.Any());
    m.pairs_skipped.push_back(g.Any());
    m.rejected.push_back(g.Any());
    m.seq_gaps.push_back(g.Any());
    m.rate_limited.push_back(g.Any());
    m.latency_median_us.push_back(g.Real());
    m.latency_p99_us.push_back(g.Real());
  }
  m.queue_depth = g.I32();
  m.dropped_total = g.Any();
  m.rejected_unattributed = g.Any();
  m.rejections_suppressed = g.Any();
  m.instance = g.Any();
  m.live_joined = g.Any();
  m.live_left = g.Any();
  m.live_expired = g.Any();
  m.shared_messages = g.Any();
  m.shared_entries = g.Any();
  m.shared_by_timeout = g.Any();
  m.shared_dropped = g.Any();
  m.shared_overflowed = g.Any();
  m.shared_cleared = g.Any();
  m.shared_pending = g.I32();
  m.shared_ready = g.I32();
  m.object_poses_received = g.Any();
  m.object_poses_rejected = g.Any();
  m.object_poses_rate_limited = g.Any();
  return m;
}

join_reply_t RandomJoinReply(Gen& g) {
  join_reply_t m{};
  m.utime = g.Any();
  m.client_id = g.Text(64);
  m.nonce = g.Any();
  m.reason = g.I8();
  m.message = g.Text(100);
  m.session = g.Any();
  m.instance = g.Any();
  m.silence_timeout_ms = g.Any();
  m.sealed_key_size = 0;
  return m;
}

join_request_t RandomJoin(Gen& g) {
  join_request_t m{};
  m.utime = g.Any();
  m.client_id = g.Text(64);
  m.nonce = g.Any();
  m.motion = g.I8();
  m.eps_s = g.Real();
  m.delta_m = g.Real();
  m.num_links = static_cast<int32_t>(g.Int(1, 6));
  for (int i = 0; i < m.num_links; ++i) {
    m.link_name.push_back(g.Text(20));
    m.parent.push_back(g.I32());
    m.a.push_back(g.Row(3));
    m.b.push_back(g.Row(3));
    m.radius.push_back(g.Real());
  }
  m.num_ignore = static_cast<int32_t>(g.Int(0, 3));
  for (int i = 0; i < m.num_ignore; ++i) m.ignore.push_back(g.Text(20));
  m.num_ignore_entities = static_cast<int32_t>(g.Int(0, 3));
  for (int i = 0; i < m.num_ignore_entities; ++i) {
    m.ignore_entity_link.push_back(g.Text(10));
    m.ignore_entity.push_back(g.Text(10));
    m.ignore_entity_other_link.push_back(g.Text(10));
  }
  return m;
}

tracker_pose_t RandomPose(Gen& g) {
  tracker_pose_t m{};
  m.utime = g.Any();
  m.client_id = g.Text(64);
  m.session = g.Any();
  m.seq = g.Any();
  m.num_links = static_cast<int32_t>(g.Int(0, 8));
  for (int i = 0; i < m.num_links; ++i) {
    m.position.push_back(g.Row(3));
    m.orientation.push_back(g.Row(4));
  }
  return m;
}

leave_t RandomLeave(Gen& g) {
  leave_t m{};
  m.utime = g.Any();
  m.client_id = g.Text(64);
  m.session = g.Any();
  return m;
}

object_pose_t RandomObjectPose(Gen& g) {
  object_pose_t m{};
  m.utime = g.Any();
  m.object_id = g.Text(64);
  m.session = g.Any();
  m.seq = g.Any();
  g.Reals(m.position, 3);
  g.Reals(m.orientation, 4);
  return m;
}

template <class T>
std::vector<uint8_t> Lcm(const T& m) {
  std::vector<uint8_t> bytes(static_cast<size_t>(m.getEncodedSize()));
  EXPECT_EQ(m.encode(bytes.data(), 0, static_cast<int>(bytes.size())),
            static_cast<int>(bytes.size()));
  return bytes;
}

WireLimits Limits() { return WireLimits{}; }

// JSON text and back, compared as LCM bytes.
template <class T, class Make>
void RoundTrips(Make make, uint32_t seed) {
  Gen g(seed);
  for (int i = 0; i < 300; ++i) {
    const T m = make(g);
    const std::string text = ToJson(m).dump();
    T back{};
    FromJson(nlohmann::json::parse(text), Limits(), &back);
    ASSERT_EQ(Lcm(m), Lcm(back)) << "seed " << seed << " message " << i << ": " << text;
  }
}

TEST(WsCodec, ServerMessagesRoundTripAsLcm) {
  RoundTrips<contact_event_t>(RandomContact, 1);
  RoundTrips<shared_contact_t>(RandomShared, 2);
  RoundTrips<rejection_t>(RandomRejection, 3);
  RoundTrips<status_t>(RandomStatus, 4);
  RoundTrips<join_reply_t>(RandomJoinReply, 5);
  RoundTrips<leave_t>(RandomLeave, 6);
  RoundTrips<object_pose_t>(RandomObjectPose, 7);
}

TEST(WsCodec, ClientMessagesRoundTripThroughTheDecoder) {
  Gen g(11);
  for (int i = 0; i < 300; ++i) {
    const join_request_t m = RandomJoin(g);
    const std::string proof =
        i % 2 ? ComputeProof(ExampleKey(), ProofKind::kJoin, kChallenge, "x") : "";
    const ClientDecodeResult r = DecodeClientMessage(ToJson(m, proof).dump(), Limits());
    ASSERT_TRUE(r.ok()) << r.problem;
    ASSERT_EQ(r.message->kind, ClientMessage::Kind::kJoin);
    EXPECT_EQ(r.message->proof, proof);
    ASSERT_EQ(Lcm(m), Lcm(r.message->join)) << i;
  }
  for (int i = 0; i < 300; ++i) {
    const tracker_pose_t m = RandomPose(g);
    const ClientDecodeResult r = DecodeClientMessage(ToJson(m).dump(), Limits());
    ASSERT_TRUE(r.ok()) << r.problem;
    ASSERT_EQ(r.message->kind, ClientMessage::Kind::kPose);
    ASSERT_EQ(Lcm(m), Lcm(r.message->pose)) << i;
  }
  for (int i = 0; i < 100; ++i) {
    const leave_t m = RandomLeave(g);
    const ClientDecodeResult r = DecodeClientMessage(ToJson(m).dump(), Limits());
    ASSERT_TRUE(r.ok()) << r.problem;
    ASSERT_EQ(Lcm(m), Lcm(r.message->leave));
    const object_pose_t o = RandomObjectPose(g);
    const ClientDecodeResult ro = DecodeClientMessage(ToJson(o).dump(), Limits());
    ASSERT_TRUE(ro.ok()) << ro.problem;
    ASSERT_EQ(Lcm(o), Lcm(ro.message->object_pose));
  }
}

TEST(WsCodec, ReadableTwinsAndNull) {
  contact_event_t m{};
  m.result = contact_event_t::RESULT_CONTACT;
  m.s_lo = std::numeric_limits<double>::quiet_NaN();
  const std::string text = ToJson(m).dump();
  EXPECT_NE(text.find("\"type\":\"contact_event\""), std::string::npos);
  EXPECT_NE(text.find("\"result_name\":\"contact\""), std::string::npos);
  EXPECT_NE(text.find("\"s_lo\":null"), std::string::npos);  // Non-finite: null.
  contact_event_t back{};
  FromJson(nlohmann::json::parse(text), Limits(), &back);
  EXPECT_TRUE(std::isnan(back.s_lo));
  join_reply_t r{};
  r.reason = join_reply_t::REASON_ID_IN_USE;
  EXPECT_NE(ToJson(r).dump().find("\"reason_name\":\"id_in_use\""), std::string::npos);
  for (int i = 0; i <= 10; ++i) EXPECT_STRNE(JoinReasonName(i), "unknown");
  EXPECT_STREQ(JoinReasonName(11), "unknown");
  EXPECT_STREQ(JoinReasonName(-1), "unknown");
}

std::string GoodPose() {
  return R"({"type":"tracker_pose","utime":1000,"client_id":"alice","session":5,"seq":0,)"
         R"("position":[[0,1,0],[0,1.2,0]],"orientation":[[1,0,0,0],[1,0,0,0]]})";
}

std::string GoodJoin() {
  return R"({"type":"join_request","utime":1,"client_id":"alice","nonce":7,"motion":0,)"
         R"("eps_s":0,"delta_m":0,"link_name":["p","s"],"parent":[-1,0],)"
         R"("a":[[0,0,0],[0,0,0]],"b":[[0,0.2,0],[0,0.3,0]],"radius":[0.1,0.1],"proof":""})";
}

// `text` with `from` replaced by `to` (once, must be present).
std::string With(std::string text, const std::string& from, const std::string& to) {
  const size_t at = text.find(from);
  EXPECT_NE(at, std::string::npos) << from;
  return text.replace(at, from.size(), to);
}

void ExpectError(const std::string& text, const std::string& code, const std::string& mention,
                 WireLimits limits = WireLimits{}) {
  const ClientDecodeResult r = DecodeClientMessage(text, limits);
  EXPECT_FALSE(r.ok()) << text;
  EXPECT_EQ(r.code, code) << text << " -> " << r.problem;
  EXPECT_NE(r.problem.find(mention), std::string::npos) << r.problem;
}

TEST(WsCodec, GoodMessagesDecode) {
  EXPECT_TRUE(DecodeClientMessage(GoodPose(), Limits()).ok());
  EXPECT_TRUE(DecodeClientMessage(GoodJoin(), Limits()).ok());
  EXPECT_TRUE(DecodeClientMessage(With(GoodJoin(), R"(,"proof":"")", ""), Limits()).ok());
  const ClientDecodeResult s =
      DecodeClientMessage(R"({"type":"subscribe","proof":"ab"})", Limits());
  ASSERT_TRUE(s.ok());
  EXPECT_EQ(s.message->kind, ClientMessage::Kind::kSubscribe);
  EXPECT_EQ(s.message->proof, "ab");
  const ClientDecodeResult a =
      DecodeClientMessage(R"({"type":"object_attach","object_id":"ball"})", Limits());
  ASSERT_TRUE(a.ok());
  EXPECT_EQ(a.message->object_id, "ball");
  // Unknown fields are ignored.
  EXPECT_TRUE(
      DecodeClientMessage(With(GoodPose(), R"("seq":0)", R"("seq":0,"extra":[1])"), Limits()).ok());
}

TEST(WsCodec, EveryErrorCode) {
  WireLimits small;
  small.max_message_bytes = 64;
  ExpectError(GoodPose(), "too_big", "over the limit 64", small);
  ExpectError("not json", "bad_json", "not valid JSON");
  ExpectError("[1,2]", "bad_json", "not a JSON object");
  ExpectError(std::string(40, '[') + std::string(40, ']'), "bad_json", "nested deeper");
  ExpectError(R"({"type":"hello"})", "unknown_type", "'hello' is not a client message");
  ExpectError(R"({"typo":"x"})", "bad_message", "type");
  ExpectError(R"({"type":7})", "bad_message", "type");
  ExpectError(With(GoodPose(), R"("utime":1000,)", ""), "bad_message",
              "tracker_pose.utime: missing");
  ExpectError(With(GoodPose(), R"("utime":1000)", R"("utime":"1000")"), "bad_message",
              "tracker_pose.utime: expected an integer, got string");
  ExpectError(With(GoodPose(), R"("utime":1000)", R"("utime":1000.5)"), "bad_message",
              "tracker_pose.utime: expected an integer");
  ExpectError(With(GoodPose(), R"("utime":1000)", R"("utime":9007199254740992)"), "bad_message",
              "beyond 2^53-1");
  ExpectError(With(GoodPose(), R"("utime":1000)", R"("utime":-9007199254740992)"), "bad_message",
              "beyond 2^53-1");
  ExpectError(With(GoodPose(), R"("utime":1000)", R"("utime":18446744073709551615)"), "bad_message",
              "beyond 2^53-1");
  ExpectError(With(GoodPose(), R"([0,1.2,0])", R"([0,1.2])"), "bad_message",
              "tracker_pose.position[1]: expected an array of 3 numbers");
  ExpectError(With(GoodPose(), R"([0,1.2,0])", R"([0,"1.2",0])"), "bad_message",
              "tracker_pose.position[1][1]: expected a number, got string");
  ExpectError(With(GoodPose(), R"(,[1,0,0,0]])", "]"), "bad_message",
              "tracker_pose.orientation: expected 2 rows, got 1");
  ExpectError(With(GoodPose(), R"("client_id":"alice")", R"("client_id":5)"), "bad_message",
              "tracker_pose.client_id: expected a string");
  ExpectError(
      With(GoodPose(), R"("client_id":"alice")", "\"client_id\":\"" + std::string(300, 'a') + "\""),
      "bad_message", "over the limit 256");
  WireLimits two_links;
  two_links.max_links = 1;
  ExpectError(GoodPose(), "bad_message",
              "tracker_pose.position: array of 2 elements, over the limit 1", two_links);
  // Joins: every array checked against the link count and the limits.
  ExpectError(With(GoodJoin(), R"("parent":[-1,0])", R"("parent":[-1])"), "bad_message",
              "join_request.parent: expected 2 elements, got 1");
  ExpectError(With(GoodJoin(), R"("radius":[0.1,0.1])", R"("radius":[0.1,true])"), "bad_message",
              "join_request.radius[1]: expected a number, got boolean");
  ExpectError(With(GoodJoin(), R"("link_name":["p","s"])", R"("link_name":[])"), "bad_message",
              "at least one link");
  ExpectError(With(GoodJoin(), R"("motion":0)", R"("motion":300)"), "bad_message",
              "join_request.motion: 300 outside [-128, 127]");
  ExpectError(With(GoodJoin(), R"("parent":[-1,0])", R"("parent":[-1,2147483648])"), "bad_message",
              "join_request.parent[1]");
  ExpectError(With(GoodJoin(), R"("proof":"")", R"("proof":")" + std::string(65, 'a') + "\""),
              "bad_message", "join_request.proof");
  ExpectError(With(GoodJoin(), R"("proof":"")", R"("ignore_entity":["x"])"), "bad_message",
              "differ in length");
  WireLimits one_link;
  one_link.max_join_links = 1;
  ExpectError(GoodJoin(), "bad_message",
              "join_request.link_name: array of 2 elements, over the limit 1", one_link);
  WireLimits no_rules;
  no_rules.max_ignore_rules = 0;
  ExpectError(With(GoodJoin(), R"("proof":"")", R"("ignore":["a:b"])"), "bad_message",
              "join_request.ignore: array of 1 elements, over the limit 0", no_rules);
  ExpectError(R"({"type":"object_attach"})", "bad_message", "object_attach.object_id: missing");
  ExpectError(
      R"({"type":"object_pose","utime":1,"object_id":"b","session":1,"seq":1,"position":[1,2],"orientation":[1,0,0,0]})",
      "bad_message", "object_pose.position: expected an array of 3 numbers");
  ExpectError(R"({"type":"leave","utime":1,"client_id":"a"})", "bad_message",
              "leave.session: missing");
}

TEST(WsCodec, JsonDepthIgnoresStrings) {
  EXPECT_EQ(JsonDepth(R"({"a":[[1]]})", 32), 3);
  EXPECT_EQ(JsonDepth(R"({"a":"[[[[[[\"[["})", 32), 1);
  EXPECT_EQ(JsonDepth(std::string(100, '['), 32), 33);
}

TEST(WsSendQueue, CapsLatestWinsAndForced) {
  SendQueue q(3, 1000);
  auto f = [](const std::string& s) { return std::make_shared<const std::string>(s); };
  EXPECT_TRUE(q.Push(f("a")));
  EXPECT_TRUE(q.Push(f("b")));
  EXPECT_TRUE(q.Push(f("c")));
  EXPECT_FALSE(q.Push(f("d")));  // Message cap.
  q.PushLatest("status", f("s1"));
  q.PushLatest("status", f("s2"));  // Replaces s1 in place.
  q.PushLatest("pose:x", f("p1"));
  EXPECT_EQ(q.messages(), 5u);
  std::vector<std::string> out;
  while (Frame x = q.Pop()) out.push_back(*x);
  EXPECT_EQ(out, (std::vector<std::string>{"a", "s2", "b", "p1", "c"}));
  EXPECT_TRUE(q.empty());
  SendQueue bytes(100, 10);
  EXPECT_TRUE(bytes.Push(f("12345")));
  EXPECT_FALSE(bytes.Push(f("123456")));  // Byte cap.
  bytes.PushForced(f("123456"));
  EXPECT_EQ(bytes.messages(), 2u);
  EXPECT_EQ(bytes.fifo_bytes(), 11u);
}

TEST(WsStaticFiles, OnlyRegularFilesInside) {
  const auto dir = std::filesystem::temp_directory_path() / ("ws_view_" + std::to_string(getpid()));
  std::filesystem::create_directories(dir / "assets");
  std::ofstream(dir / "index.html") << "<html></html>";
  std::ofstream(dir / "assets" / "main.js") << "1";
  std::ofstream(dir / ".secret") << "x";
  std::ofstream(dir.string() + "_outside.txt") << "x";
  std::filesystem::create_symlink(dir.string() + "_outside.txt", dir / "link.txt");
  const std::string d = dir.string();
  EXPECT_EQ(ResolveViewFile(d, "/").value_or(""), (dir / "index.html").string());
  EXPECT_EQ(ResolveViewFile(d, "/view/").value_or(""), (dir / "index.html").string());
  EXPECT_EQ(ResolveViewFile(d, "/assets/main.js?v=1").value_or(""),
            (dir / "assets/main.js").string());
  EXPECT_EQ(ResolveViewFile(d, "/view/assets/main.js").value_or(""),
            (dir / "assets/main.js").string());
  for (const char* bad :
       {"/assets", "/assets/", "/../x", "/assets/../index.html", "/.secret", "/%2e%2e/x",
        "/link.txt", "//etc/passwd", "/missing.js", "x", "", "/a\\b", "/view/../../etc/passwd"}) {
    EXPECT_FALSE(ResolveViewFile(d, bad).has_value()) << bad;
  }
  EXPECT_FALSE(ResolveViewFile("", "/").has_value());
  EXPECT_STREQ(ContentTypeOf("a/index.html"), "text/html; charset=utf-8");
  EXPECT_STREQ(ContentTypeOf("main.js"), "text/javascript; charset=utf-8");
  EXPECT_STREQ(ContentTypeOf("m.mjs"), "text/javascript; charset=utf-8");
  EXPECT_STREQ(ContentTypeOf("s.css"), "text/css; charset=utf-8");
  EXPECT_STREQ(ContentTypeOf("x.json"), "application/json");
  EXPECT_STREQ(ContentTypeOf("x.wasm"), "application/wasm");
  EXPECT_STREQ(ContentTypeOf("x.png"), "image/png");
  EXPECT_STREQ(ContentTypeOf("x.bin"), "application/octet-stream");
  std::filesystem::remove_all(dir);
  std::filesystem::remove(dir.string() + "_outside.txt");
}

uint32_t U32At(const std::string& s, size_t at) {
  uint32_t v = 0;
  for (int i = 3; i >= 0; --i)
    v = v << 8 | static_cast<unsigned char>(s[at + static_cast<size_t>(i)]);
  return v;
}

TEST(WsScene, WeldsAndDecimatesUnderTheCap) {
  // A 40 x 40 grid of quads: 3200 triangles, 1681 shared vertices.
  TriangleMesh mesh;
  const int n = 40;
  for (int y = 0; y <= n; ++y) {
    for (int x = 0; x <= n; ++x) mesh.vertices.emplace_back(0.05f * x, 0.05f * y, 0.f);
  }
  for (int y = 0; y < n; ++y) {
    for (int x = 0; x < n; ++x) {
      const uint32_t i = static_cast<uint32_t>(y * (n + 1) + x);
      for (uint32_t v : {i, i + 1, i + n + 2, i, i + n + 2, i + n + 1}) mesh.indices.push_back(v);
    }
  }
  Environment env;
  env.AddMesh(mesh, "/srv/scenes/grid.obj");
  const Scene full = BuildScene(env, {}, 100000);
  ASSERT_EQ(full.meshes.size(), 1u);
  EXPECT_EQ(full.meshes[0].triangles, 3200u);
  EXPECT_EQ(full.meshes[0].vertices, 1681u);  // Welded.
  const Scene small = BuildScene(env, {}, 500);
  const SceneMesh& m = small.meshes[0];
  EXPECT_LE(m.triangles, 500u);
  EXPECT_GT(m.triangles, 50u);
  EXPECT_EQ(m.source_triangles, 3200u);
  ASSERT_EQ(m.bin.size(), 16 + 12 * size_t{m.vertices} + 12 * size_t{m.triangles});
  EXPECT_EQ(m.bin.substr(0, 4), "SCM1");
  EXPECT_EQ(U32At(m.bin, 4), m.vertices);
  EXPECT_EQ(U32At(m.bin, 8), m.triangles);
  for (size_t k = 0; k < 3 * size_t{m.triangles}; ++k) {
    EXPECT_LT(U32At(m.bin, 16 + 12 * size_t{m.vertices} + 4 * k), m.vertices);
  }
  const nlohmann::json j = nlohmann::json::parse(small.json);
  EXPECT_EQ(j["max_triangles"], 500);
  EXPECT_EQ(j["meshes"][0]["kind"], "environment");
  EXPECT_EQ(j["meshes"][0]["name"], "grid.obj");  // No server path.
  EXPECT_EQ(j["meshes"][0]["url"], "/scene/0.bin");
  EXPECT_EQ(j["meshes"][0]["source_triangles"], 3200);
}

TEST(WsDoorOptions, LoopbackAndValidation) {
  EXPECT_TRUE(IsLoopbackListen("127.0.0.1:8765"));
  EXPECT_TRUE(IsLoopbackListen("127.1.2.3:1"));
  EXPECT_TRUE(IsLoopbackListen("[::1]:8765"));
  EXPECT_TRUE(IsLoopbackListen("localhost:80"));
  EXPECT_FALSE(IsLoopbackListen("0.0.0.0:8765"));
  EXPECT_FALSE(IsLoopbackListen("192.168.1.2:8765"));
  EXPECT_FALSE(IsLoopbackListen("[::]:8765"));
  EXPECT_FALSE(IsLoopbackListen("nonsense"));
  WsDoorOptions o;
  EXPECT_EQ(ValidateWsDoorOptions(o), "");  // Off.
  o.listen = "127.0.0.1:0";
  EXPECT_EQ(ValidateWsDoorOptions(o), "");
  o.listen = "127.0.0.1";
  EXPECT_NE(ValidateWsDoorOptions(o).find("HOST:PORT"), std::string::npos);
  o.listen = "127.0.0.1:99999";
  EXPECT_NE(ValidateWsDoorOptions(o), "");
  o.listen = "127.0.0.1:1";
  o.cert_path = "c.pem";
  EXPECT_NE(ValidateWsDoorOptions(o).find("both --ws-cert and --ws-key"), std::string::npos);
  o.key_path = "k.pem";
  EXPECT_EQ(ValidateWsDoorOptions(o), "");
  o.max_connections = 0;
  EXPECT_NE(ValidateWsDoorOptions(o), "");
}

}  // namespace
}  // namespace sweptccd::ws
