#pragma once
// Seeded random valid messages of every type the service sends or receives.

#include <cstdint>
#include <random>
#include <string>
#include <vector>

#include "sweptccd/contact_event_t.hpp"
#include "sweptccd/join_reply_t.hpp"
#include "sweptccd/join_request_t.hpp"
#include "sweptccd/leave_t.hpp"
#include "sweptccd/object_pose_t.hpp"
#include "sweptccd/shared_contact_t.hpp"
#include "sweptccd/rejection_t.hpp"
#include "sweptccd/status_t.hpp"
#include "sweptccd/tracker_pose_t.hpp"

namespace sweptccd::testing {

class RandomMessages {
 public:
  explicit RandomMessages(uint64_t seed) : rng_(seed) {}

  int64_t Int() { return static_cast<int64_t>(rng_()); }
  double Real() { return std::uniform_real_distribution<double>(-1e3, 1e3)(rng_); }
  int Below(int n) { return static_cast<int>(rng_() % static_cast<uint64_t>(n)); }
  // Printable and hostile bytes alike, but no NUL (LCM strings are C strings).
  std::string Text(int max_length) {
    std::string s(static_cast<size_t>(Below(max_length + 1)), 'x');
    for (char& c : s) c = static_cast<char>(1 + Below(255));
    return s;
  }
  void Mac(uint8_t mac[32]) {
    for (int i = 0; i < 32; ++i) mac[i] = static_cast<uint8_t>(Below(256));
  }

  tracker_pose_t Pose() {
    tracker_pose_t m;
    m.utime = Int();
    m.client_id = Text(20);
    m.session = Int();
    m.seq = Int();
    m.num_links = Below(6);
    m.position.assign(m.num_links, std::vector<double>(3));
    m.orientation.assign(m.num_links, std::vector<double>(4));
    for (auto& p : m.position) for (double& v : p) v = Real();
    for (auto& q : m.orientation) for (double& v : q) v = Real();
    Mac(m.mac);
    return m;
  }
  contact_record_t Record() {
    contact_record_t r;
    r.link = static_cast<int32_t>(Int());
    r.object = static_cast<int32_t>(Int());
    r.triangle = Int();
    r.s = Real();
    for (int k = 0; k < 3; ++k) {
      r.point_link[k] = Real();
      r.point_env[k] = Real();
      r.normal[k] = Real();
    }
    r.separation = Real();
    return r;
  }
  contact_event_t Contact() {
    contact_event_t e;
    e.utime = Int();
    e.client_id = Text(20);
    e.seq0 = Int(), e.seq1 = Int(), e.pair = Int(), e.utime0 = Int(), e.utime1 = Int();
    e.result = static_cast<int8_t>(Below(3));
    e.error = Text(30);
    e.initially_colliding = Below(2), e.undecided = Below(2);
    e.s_lo = Real(), e.s_hi = Real(), e.t_lo = Real(), e.t_hi = Real();
    e.num_contacts = Below(4);
    for (int i = 0; i < e.num_contacts; ++i) e.contacts.push_back(Record());
    e.num_links = Below(4);
    for (int i = 0; i < e.num_links; ++i) {
      link_bracket_t b;
      b.link = static_cast<int32_t>(Int());
      b.s_lo = Real(), b.s_hi = Real(), b.t_lo = Real(), b.t_hi = Real();
      b.initially_colliding = Below(2), b.undecided = Below(2), b.has_witness = Below(2);
      b.witness = Record();
      e.links.push_back(b);
    }
    e.receive_utime = Int();
    e.compute_us = Real(), e.queue_us = Real();
    e.skipped_pairs_total = Int();
    Mac(e.mac);
    return e;
  }
  rejection_t Rejection() {
    rejection_t r;
    r.utime = Int();
    r.client_id = Text(20);
    r.seq = Int();
    r.reason = Text(20);
    r.message = Text(60);
    r.suppressed = Int();
    Mac(r.mac);
    return r;
  }
  status_t Status() {
    status_t s;
    s.utime = Int();
    s.backend = Text(10);
    s.renderer = Text(10);
    s.security = Text(8);
    s.num_clients = Below(5);
    for (int i = 0; i < s.num_clients; ++i) {
      s.client_id.push_back(Text(12));
      s.poses_received.push_back(Int());
      s.pairs_answered.push_back(Int());
      s.pairs_skipped.push_back(Int());
      s.rejected.push_back(Int());
      s.seq_gaps.push_back(Int());
      s.rate_limited.push_back(Int());
      s.latency_median_us.push_back(Real());
      s.latency_p99_us.push_back(Real());
    }
    s.queue_depth = static_cast<int32_t>(Int());
    s.dropped_total = Int();
    s.rejected_unattributed = Int();
    s.rejections_suppressed = Int();
    s.instance = Int();
    s.live_joined = Int();
    s.live_left = Int();
    s.live_expired = Int();
    Mac(s.mac);
    return s;
  }
  join_request_t Join() {
    join_request_t j;
    j.utime = Int();
    j.client_id = Text(20);
    j.nonce = Int();
    Mac(j.public_key);
    j.motion = static_cast<int8_t>(Below(3));
    j.eps_s = Real();
    j.delta_m = Real();
    j.num_links = Below(6);
    for (int i = 0; i < j.num_links; ++i) {
      j.link_name.push_back(Text(12));
      j.parent.push_back(static_cast<int32_t>(Below(8)) - 1);
      j.a.push_back({Real(), Real(), Real()});
      j.b.push_back({Real(), Real(), Real()});
      j.radius.push_back(Real());
    }
    j.num_ignore = Below(4);
    for (int i = 0; i < j.num_ignore; ++i) j.ignore.push_back(Text(16));
    j.num_ignore_entities = Below(4);
    for (int i = 0; i < j.num_ignore_entities; ++i) {
      j.ignore_entity_link.push_back(Text(12));
      j.ignore_entity.push_back(Text(20));
      j.ignore_entity_other_link.push_back(Text(12));
    }
    Mac(j.mac);
    return j;
  }
  join_reply_t JoinReply() {
    join_reply_t j;
    j.utime = Int();
    j.client_id = Text(20);
    j.nonce = Int();
    j.reason = static_cast<int8_t>(Below(11));
    j.message = Text(40);
    j.session = Int();
    j.instance = Int();
    j.silence_timeout_ms = Int();
    j.sealed_key_size = Below(2) * 80;
    j.sealed_key.resize(static_cast<size_t>(j.sealed_key_size));
    for (uint8_t& b : j.sealed_key) b = static_cast<uint8_t>(Below(256));
    Mac(j.mac);
    return j;
  }
  leave_t Leave() {
    leave_t l;
    l.utime = Int();
    l.client_id = Text(20);
    l.session = Int();
    Mac(l.mac);
    return l;
  }
  object_pose_t ObjectPose() {
    object_pose_t m;
    m.utime = Int();
    m.object_id = Text(20);
    m.session = Int();
    m.seq = Int();
    for (double& v : m.position) v = Real();
    for (double& v : m.orientation) v = Real();
    Mac(m.mac);
    return m;
  }
  shared_contact_t SharedContact() {
    shared_contact_t m;
    m.utime = Int();
    m.client_id = Text(20);
    m.seq0 = Int(), m.seq1 = Int(), m.pair = Int(), m.utime0 = Int(), m.utime1 = Int();
    m.receive_utime = Int();
    m.num_entries = Below(4);
    for (int j = 0; j < m.num_entries; ++j) m.entries.push_back(SharedEntry());
    Mac(m.mac);
    return m;
  }

  entity_contact_t EntityContact() {
    entity_contact_t c;
    c.link = static_cast<int32_t>(Int());
    c.other_link = static_cast<int32_t>(Int());
    c.triangle = Int();
    c.s = Real();
    for (int k = 0; k < 3; ++k) {
      c.point_link[k] = Real();
      c.point_other[k] = Real();
      c.normal[k] = Real();
    }
    c.separation = Real();
    return c;
  }

  shared_entry_t SharedEntry() {
    shared_entry_t e;
    e.entity = Text(20);
    e.entity_kind = static_cast<int8_t>(Below(2));
    e.t_from = Int(), e.t_to = Int();
    e.result = static_cast<int8_t>(Below(3));
    e.error = Text(30);
    e.initially_colliding = Below(2), e.undecided = Below(2);
    e.s_lo = Real(), e.s_hi = Real(), e.t_lo = Real(), e.t_hi = Real();
    e.num_contacts = Below(4);
    for (int i = 0; i < e.num_contacts; ++i) e.contacts.push_back(EntityContact());
    e.num_links = Below(3);
    for (int i = 0; i < e.num_links; ++i) {
      entity_link_bracket_t b;
      b.link = static_cast<int32_t>(Int());
      b.s_lo = Real(), b.s_hi = Real(), b.t_lo = Real(), b.t_hi = Real();
      b.initially_colliding = Below(2), b.undecided = Below(2), b.has_witness = Below(2);
      b.witness = EntityContact();
      e.links.push_back(b);
    }
    e.waited_us = Int();
    e.ended_by_timeout = Below(2);
    e.compute_us = Real();
    return e;
  }

 private:
  std::mt19937_64 rng_;
};

template <class T>
std::vector<uint8_t> Encode(const T& msg) {
  std::vector<uint8_t> bytes(static_cast<size_t>(msg.getEncodedSize()));
  msg.encode(bytes.data(), 0, static_cast<int>(bytes.size()));
  return bytes;
}

}  // namespace sweptccd::testing
