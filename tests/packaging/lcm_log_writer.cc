// lcm_log_writer LCM_URL MANIFEST: publishes one message of every msgs/*.lcm
// type through the C++ LCM API (on a file:// URL: an LCM log, no network),
// on a channel named after its type, plus every type the daemon sends or
// reads on its daemon channel (msgs/channels.h); writes MANIFEST, one "CHANNEL TYPE"
// line per message, for DecodeLog.java (Packaging.JavaDecodesEveryType).
//
// Every field of every message holds a value other than its default (non-zero
// numbers, true booleans, non-empty strings and arrays, a real HMAC in `mac`),
// so the Java side can tell a field lost or shifted by either language.
// A new type needs: its name in SWEPTCCD_LCM_TYPES (msgs/CMakeLists.txt), which
// brings it here through all_lcm_types.h, and a Fill() overload below; until
// then it goes out default-valued and the Java side fails naming the type.
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <string>
#include <utility>
#include <vector>

#include <lcm/lcm-cpp.hpp>

#include "all_lcm_types.h"
#include "msgs/channels.h"
#include "msgs/signing.h"

namespace {

using namespace sweptccd;

const MacKey& TestKey() {
  static const MacKey key = ParseKeyHex(
      "00112233445566778899aabbccddeeff0123456789abcdeffedcba9876543210", "test key");
  return key;
}

// No Fill for a type: it stays value-initialized (DecodeLog.java fails it).
template <class T>
void Fill(T&) {}

void Fill(contact_record_t& m) {
  m.link = 3;
  m.object = 2;
  m.triangle = 123456789012LL;
  m.s = 0.375;
  for (int i = 0; i < 3; ++i) {
    m.point_link[i] = 1.5 + i;
    m.point_env[i] = -2.25 - i;
    m.normal[i] = 0.25 * (i + 1);
  }
  m.separation = -1.0e-4;
}

void Fill(link_bracket_t& m) {
  m.link = 5;
  m.s_lo = 0.125;
  m.s_hi = 0.1875;
  m.t_lo = 1.0e6 + 0.5;
  m.t_hi = 1.0e6 + 1.5;
  m.initially_colliding = 1;
  m.undecided = 1;
  m.has_witness = 1;
  Fill(m.witness);
}

void Fill(tracker_pose_t& m) {
  m.utime = 1700000000123456LL;
  m.client_id = "alice.left-hand_1";
  m.session = 42;
  m.seq = 7;
  m.num_links = 3;
  for (int l = 0; l < m.num_links; ++l) {
    m.position.push_back({0.5 + l, -1.25 * (l + 1), 2.0 + 0.001 * l});
    m.orientation.push_back({0.9 + 0.01 * l, 0.1, -0.2, 0.3 + l});
  }
}

void Fill(contact_event_t& m) {
  m.utime = 1700000000200000LL;
  m.client_id = "alice";
  m.seq0 = 7;
  m.seq1 = 8;
  m.pair = 6;
  m.utime0 = 1700000000100000LL;
  m.utime1 = 1700000000133333LL;
  m.result = contact_event_t::RESULT_CONTACT;
  m.error = "not an error: every field is set";
  m.initially_colliding = 1;
  m.undecided = 1;
  m.s_lo = 0.25;
  m.s_hi = 0.2501;
  m.t_lo = 1700000000108333.0;
  m.t_hi = 1700000000108336.5;
  m.num_contacts = 2;
  m.contacts.resize(2);
  for (auto& c : m.contacts) Fill(c);
  m.contacts[1].link = 4;
  m.num_links = 1;
  m.links.resize(1);
  Fill(m.links[0]);
  m.receive_utime = 1700000000150000LL;
  m.compute_us = 812.5;
  m.queue_us = 3.25;
  m.skipped_pairs_total = 11;
}

void Fill(rejection_t& m) {
  m.utime = 1700000000300000LL;
  m.client_id = "mallory";
  m.seq = 99;
  m.reason = "bad_signature";
  m.message = "the mac does not verify under the client's key";
  m.suppressed = 4;
}

void Fill(status_t& m) {
  m.utime = 1700000000400000LL;
  m.backend = "cpu";
  m.renderer = "llvmpipe (test)";
  m.security = "signed";
  m.num_clients = 2;
  m.client_id = {"alice", "bob"};
  m.poses_received = {100, 200};
  m.pairs_answered = {98, 197};
  m.pairs_skipped = {1, 2};
  m.rejected = {1, 3};
  m.seq_gaps = {5, 6};
  m.rate_limited = {7, 8};
  m.latency_median_us = {850.5, 900.25};
  m.latency_p99_us = {1500.5, 1600.75};
  m.queue_depth = 3;
  m.dropped_total = 3;
  m.rejected_unattributed = 9;
  m.rejections_suppressed = 10;
  m.instance = 1700000000000001LL;
  m.live_joined = 12;
  m.live_left = 13;
  m.live_expired = 14;
  m.shared_messages = 15;
  m.shared_entries = 16;
  m.shared_by_timeout = 17;
  m.shared_dropped = 18;
  m.shared_overflowed = 19;
  m.shared_cleared = 25;
  m.shared_pending = 20;
  m.shared_ready = 21;
  m.object_poses_received = 22;
  m.object_poses_rejected = 23;
  m.object_poses_rate_limited = 24;
}

void Fill(join_request_t& m) {
  m.utime = 1700000000500000LL;
  m.client_id = "carol";
  m.nonce = 0x1234567890LL;
  for (int i = 0; i < 32; ++i) m.public_key[i] = static_cast<uint8_t>(i + 1);
  m.motion = join_request_t::MOTION_INDEPENDENT;
  m.eps_s = 0.001;
  m.delta_m = 0.002;
  m.num_links = 2;
  m.link_name = {"pelvis", "thigh"};
  m.parent = {1, -1};  // Link 1 is the root (no field may be 0 here).
  m.a = {{0.01, 0.02, 0.1}, {0.03, 0.1, 0.04}};
  m.b = {{0.05, 0.06, 0.3}, {0.07, 0.4, 0.08}};
  m.radius = {0.12, 0.07};
  m.num_ignore = 1;
  m.ignore = {"{\"link\": \"thigh\", \"object\": 0}"};
  m.num_ignore_entities = 1;
  m.ignore_entity_link = {"thigh"};
  m.ignore_entity = {"bob"};
  m.ignore_entity_other_link = {"forearm"};
}

void Fill(join_reply_t& m) {
  m.utime = 1700000000600000LL;
  m.client_id = "carol";
  m.nonce = 0x1234567890LL;
  m.reason = join_reply_t::REASON_ID_IN_USE;
  m.message = "the id 'carol' is in use by another live session";
  m.session = 77;
  m.instance = 1700000000000001LL;
  m.silence_timeout_ms = 5000;
  m.sealed_key_size = 3;
  m.sealed_key = {9, 8, 7};
}

void Fill(leave_t& m) {
  m.utime = 1700000000700000LL;
  m.client_id = "carol";
  m.session = 77;
}

void Fill(object_pose_t& m) {
  m.utime = 1700000000800000LL;
  m.object_id = "cup";
  m.session = 78;
  m.seq = 11;
  for (int i = 0; i < 3; ++i) m.position[i] = 0.5 + i;
  m.orientation[0] = 0.5, m.orientation[1] = -0.5, m.orientation[2] = 0.5, m.orientation[3] = 0.5;
}

void Fill(entity_contact_t& m) {
  m.link = 4;
  m.other_link = 6;
  m.triangle = 98765432101LL;
  m.s = 0.625;
  for (int i = 0; i < 3; ++i) {
    m.point_link[i] = 3.5 + i;
    m.point_other[i] = -4.25 - i;
    m.normal[i] = 0.5 * (i + 1);
  }
  m.separation = -2.0e-4;
}

void Fill(entity_link_bracket_t& m) {
  m.link = 4;
  m.s_lo = 0.25;
  m.s_hi = 0.3125;
  m.t_lo = 1.7e15 + 2.5;
  m.t_hi = 1.7e15 + 3.5;
  m.initially_colliding = 1;
  m.undecided = 1;
  m.has_witness = 1;
  Fill(m.witness);
}

void Fill(shared_entry_t& m) {
  m.entity = "cup";
  m.entity_kind = shared_entry_t::KIND_OBJECT;
  m.t_from = 1700000000000002LL;
  m.t_to = 1700000000011111LL;
  m.result = shared_entry_t::RESULT_CONTACT;
  m.error = "no error, but every field set";
  m.initially_colliding = 1;
  m.undecided = 1;
  m.s_lo = 0.25;
  m.s_hi = 0.3125;
  m.t_lo = 1.7e15 + 2.5;
  m.t_hi = 1.7e15 + 3.5;
  m.num_contacts = 2;
  m.contacts.resize(2);
  Fill(m.contacts[0]);
  Fill(m.contacts[1]);
  m.num_links = 1;
  m.links.resize(1);
  Fill(m.links[0]);
  m.waited_us = 4321;
  m.ended_by_timeout = 1;
  m.compute_us = 17.25;
  m.queue_us = 40.5;
}

void Fill(shared_contact_t& m) {
  m.utime = 1700000000900000LL;
  m.client_id = "alice";
  m.seq0 = 21;
  m.seq1 = 22;
  m.pair = 20;
  m.utime0 = 1700000000000001LL;
  m.utime1 = 1700000000011112LL;
  m.receive_utime = 1700000000011200LL;
  m.num_entries = 2;
  m.entries.resize(2);
  Fill(m.entries[0]);
  Fill(m.entries[1]);
  m.entries[1].entity = "box";  // KIND_AVATAR (0) is the default value DecodeLog refuses.
}

// Encodes `m`, signs it when its type ends in `byte mac[32]`, publishes it.
template <class T>
auto Sign(std::vector<uint8_t>& bytes, int) -> decltype(std::declval<T&>().mac, void()) {
  SignEncoded(bytes.data(), bytes.size(), &TestKey());
}
template <class T>
void Sign(std::vector<uint8_t>&, long) {}

template <class T>
void Publish(lcm::LCM& lcm, std::ofstream& manifest, const std::string& channel,
             const std::string& type, const T& m) {
  std::vector<uint8_t> bytes(static_cast<size_t>(m.getEncodedSize()));
  if (m.encode(bytes.data(), 0, static_cast<int>(bytes.size())) != static_cast<int>(bytes.size())) {
    std::fprintf(stderr, "lcm_log_writer: cannot encode %s\n", type.c_str());
    std::exit(1);
  }
  Sign<T>(bytes, 0);
  if (lcm.publish(channel, bytes.data(), static_cast<unsigned>(bytes.size())) != 0) {
    std::fprintf(stderr, "lcm_log_writer: cannot publish %s\n", channel.c_str());
    std::exit(1);
  }
  manifest << channel << ' ' << type << '\n';
}

}  // namespace

int main(int argc, char** argv) {
  if (argc != 3) {
    std::fprintf(stderr, "usage: lcm_log_writer LCM_URL MANIFEST\n");
    return 2;
  }
  lcm::LCM lcm(argv[1]);
  if (!lcm.good()) {
    std::fprintf(stderr, "lcm_log_writer: cannot open LCM URL %s\n", argv[1]);
    return 1;
  }
  std::ofstream manifest(argv[2]);
  int count = 0;
#define SWEPTCCD_PUBLISH_TYPE(type)                     \
  {                                                     \
    sweptccd::type m{};                                     \
    Fill(m);                                            \
    Publish(lcm, manifest, #type, #type, m);            \
    ++count;                                            \
  }
  SWEPTCCD_FOR_EACH_LCM_TYPE(SWEPTCCD_PUBLISH_TYPE)
#undef SWEPTCCD_PUBLISH_TYPE
  // What the daemon and trackers publish, on the daemon's channels.
  tracker_pose_t pose{};
  Fill(pose);
  Publish(lcm, manifest, kPoseChannel, "tracker_pose_t", pose);
  contact_event_t event{};
  Fill(event);
  Publish(lcm, manifest, kContactChannel, "contact_event_t", event);
  rejection_t rejection{};
  Fill(rejection);
  Publish(lcm, manifest, kRejectChannel, "rejection_t", rejection);
  status_t status{};
  Fill(status);
  Publish(lcm, manifest, kStatusChannel, "status_t", status);
  join_request_t join{};
  Fill(join);
  Publish(lcm, manifest, kJoinChannel, "join_request_t", join);
  join_reply_t reply{};
  Fill(reply);
  Publish(lcm, manifest, kJoinReplyChannel, "join_reply_t", reply);
  leave_t leave{};
  Fill(leave);
  Publish(lcm, manifest, kLeaveChannel, "leave_t", leave);
  object_pose_t object_pose{};
  Fill(object_pose);
  Publish(lcm, manifest, kObjectPoseChannel, "object_pose_t", object_pose);
  shared_contact_t shared{};
  Fill(shared);
  Publish(lcm, manifest, kSharedContactChannel, "shared_contact_t", shared);
  manifest.close();
  if (!manifest) {
    std::fprintf(stderr, "lcm_log_writer: cannot write %s\n", argv[2]);
    return 1;
  }
  std::printf("lcm_log_writer: %d types, %d messages\n", count, count + 9);
  return 0;
}
