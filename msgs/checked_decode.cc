#include "msgs/checked_decode.h"

#include <cstring>

namespace sweptccd {

namespace {

constexpr size_t kMac = 32;               // byte mac[32], the last field of each type.
constexpr size_t kContactRecord = 104;    // contact_record_t: 2 int32, int64, 11 doubles.
constexpr size_t kEntityContact = 104;    // entity_contact_t: 2 int32, int64, 11 doubles.
constexpr size_t kLinkBracket = 4 + 32 + 3 + kContactRecord;  // link_bracket_t.
constexpr size_t kMinString = 5;          // int32 length + the NUL.
constexpr size_t kEntityLinkBracket = 4 + 32 + 3 + kEntityContact;  // entity_link_bracket_t.
// shared_entry_t with empty strings and no contacts nor links.
constexpr size_t kMinSharedEntry = kMinString + 1 + 2 * 8 + 1 + kMinString + 2 + 4 * 8 + 4 + 4 +
                                   8 + 1 + 8 + 8;

// A cursor over untrusted bytes. The first failure sticks: later reads do
// nothing and return zeros, so a walker reads as a plain list of fields.
class WireReader {
 public:
  WireReader(const void* data, size_t size)
      : data_(static_cast<const uint8_t*>(data)), size_(size) {}

  void Fingerprint(int64_t hash) {
    if (!Need(8, "fingerprint")) return;
    if (static_cast<uint64_t>(ReadBig(8)) != static_cast<uint64_t>(hash)) {
      Fail("fingerprint", 0, "is not this type's (another type or another version of msgs/)");
    }
  }
  void Fixed(const char* field, size_t bytes) {
    if (Need(bytes, field)) pos_ += bytes;
  }
  int32_t Int32(const char* field) {
    if (!Need(4, field)) return 0;
    return static_cast<int32_t>(static_cast<uint32_t>(ReadBig(4)));
  }
  // An LCM string: int32 length counting the NUL, the bytes, the NUL.
  void String(const char* field, int32_t limit) {
    const size_t at = pos_;
    const int32_t n = Int32(field);
    if (failed()) return;
    if (n < 1) return Fail(field, at, "has string length " + std::to_string(n) + " (must be >= 1)");
    if (n - 1 > limit) {
      return Fail(field, at, "is " + std::to_string(n - 1) + " bytes long, over the limit of " +
                             std::to_string(limit));
    }
    if (!Need(static_cast<size_t>(n), field)) return;
    if (data_[pos_ + n - 1] != 0) return Fail(field, at, "is not NUL-terminated");
    // An LCM string is a C string: an inner NUL is no encoder's output.
    if (std::memchr(data_ + pos_, 0, static_cast<size_t>(n - 1)) != nullptr) {
      return Fail(field, at, "holds a NUL byte before its end");
    }
    pos_ += static_cast<size_t>(n);
  }
  // An array count: >= 0, <= limit, and `min_element_bytes` each must fit.
  int32_t Count(const char* field, int32_t limit, size_t min_element_bytes) {
    const size_t at = pos_;
    const int32_t n = Int32(field);
    if (failed()) return 0;
    if (n < 0 || n > limit) {
      Fail(field, at, "is " + std::to_string(n) + ", outside [0, " + std::to_string(limit) + "]");
      return 0;
    }
    if (static_cast<size_t>(n) * min_element_bytes > size_ - pos_) {
      Fail(field, at, "is " + std::to_string(n) + " but only " + std::to_string(size_ - pos_) +
                      " bytes follow");
      return 0;
    }
    return n;
  }
  // Call last: the message must end exactly at `size`.
  std::string Finish() {
    if (!failed() && pos_ != size_) {
      Fail("end", pos_, std::to_string(size_ - pos_) + " bytes follow the message");
    }
    return problem_;
  }
  bool failed() const { return !problem_.empty(); }
  size_t pos() const { return pos_; }

 private:
  bool Need(size_t bytes, const char* field) {
    if (failed()) return false;
    if (bytes > size_ - pos_) {
      Fail(field, pos_, "needs " + std::to_string(bytes) + " bytes but " +
                      std::to_string(size_ - pos_) + " are left (truncated)");
      return false;
    }
    return true;
  }
  uint64_t ReadBig(size_t bytes) {
    uint64_t v = 0;
    for (size_t i = 0; i < bytes; ++i) v = (v << 8) | data_[pos_ + i];
    pos_ += bytes;
    return v;
  }
  void Fail(const char* field, size_t at, const std::string& what) {
    problem_ = std::string(field) + " at byte " + std::to_string(at) + " " + what;
  }

  const uint8_t* data_;
  size_t size_;
  size_t pos_ = 0;
  std::string problem_;
};

std::string TooLong(size_t size, const WireLimits& limits) {
  if (size <= limits.max_message_bytes && size <= static_cast<size_t>(INT32_MAX)) return "";
  return "message of " + std::to_string(size) + " bytes is over the limit of " +
         std::to_string(limits.max_message_bytes);
}

}  // namespace

std::string CheckWire(const tracker_pose_t*, const void* data, size_t size,
                      const WireLimits& limits) {
  if (std::string p = TooLong(size, limits); !p.empty()) return p;
  WireReader r(data, size);
  r.Fingerprint(tracker_pose_t::getHash());
  r.Fixed("utime", 8);
  r.String("client_id", limits.max_id_bytes);
  r.Fixed("session", 8);
  r.Fixed("seq", 8);
  const int32_t n = r.Count("num_links", limits.max_links, 7 * 8);
  r.Fixed("position", static_cast<size_t>(n) * 3 * 8);
  r.Fixed("orientation", static_cast<size_t>(n) * 4 * 8);
  r.Fixed("mac", kMac);
  return r.Finish();
}

std::string CheckWire(const contact_event_t*, const void* data, size_t size,
                      const WireLimits& limits) {
  if (std::string p = TooLong(size, limits); !p.empty()) return p;
  WireReader r(data, size);
  r.Fingerprint(contact_event_t::getHash());
  r.Fixed("utime", 8);
  r.String("client_id", limits.max_id_bytes);
  r.Fixed("seq0..utime1", 5 * 8);
  r.Fixed("result", 1);
  r.String("error", limits.max_text_bytes);
  r.Fixed("initially_colliding..t_hi", 2 + 4 * 8);
  const int32_t contacts = r.Count("num_contacts", limits.max_contacts, kContactRecord);
  r.Fixed("contacts", static_cast<size_t>(contacts) * kContactRecord);
  const int32_t links = r.Count("num_links", limits.max_links, kLinkBracket);
  r.Fixed("links", static_cast<size_t>(links) * kLinkBracket);
  r.Fixed("receive_utime..skipped_pairs_total", 4 * 8);
  r.Fixed("mac", kMac);
  return r.Finish();
}

std::string CheckWire(const rejection_t*, const void* data, size_t size, const WireLimits& limits) {
  if (std::string p = TooLong(size, limits); !p.empty()) return p;
  WireReader r(data, size);
  r.Fingerprint(rejection_t::getHash());
  r.Fixed("utime", 8);
  r.String("client_id", limits.max_id_bytes);
  r.Fixed("seq", 8);
  r.String("reason", limits.max_text_bytes);
  r.String("message", limits.max_text_bytes);
  r.Fixed("suppressed", 8);
  r.Fixed("mac", kMac);
  return r.Finish();
}

std::string CheckWire(const status_t*, const void* data, size_t size, const WireLimits& limits) {
  if (std::string p = TooLong(size, limits); !p.empty()) return p;
  WireReader r(data, size);
  r.Fingerprint(status_t::getHash());
  r.Fixed("utime", 8);
  r.String("backend", limits.max_text_bytes);
  r.String("renderer", limits.max_text_bytes);
  r.String("security", limits.max_text_bytes);
  // Per client: one string and eight 8-byte numbers.
  const int32_t n = r.Count("num_clients", limits.max_clients, kMinString + 8 * 8);
  for (int32_t i = 0; i < n && !r.failed(); ++i) r.String("client_id[]", limits.max_id_bytes);
  r.Fixed("poses_received..latency_p99_us", static_cast<size_t>(n) * 8 * 8);
  r.Fixed("queue_depth", 4);
  r.Fixed("dropped_total, rejected_unattributed, rejections_suppressed", 3 * 8);
  r.Fixed("instance, live_joined, live_left, live_expired", 4 * 8);
  r.Fixed("shared_messages..shared_cleared", 6 * 8);
  r.Fixed("shared_pending, shared_ready", 2 * 4);
  r.Fixed("object_poses_received..object_poses_rate_limited", 3 * 8);
  r.Fixed("mac", kMac);
  return r.Finish();
}

std::string CheckWire(const join_request_t*, const void* data, size_t size,
                      const WireLimits& limits) {
  if (std::string p = TooLong(size, limits); !p.empty()) return p;
  WireReader r(data, size);
  r.Fingerprint(join_request_t::getHash());
  r.Fixed("utime", 8);
  r.String("client_id", limits.max_id_bytes);
  r.Fixed("nonce", 8);
  r.Fixed("public_key", 32);
  r.Fixed("motion, eps_s, delta_m", 1 + 2 * 8);
  // Per link: a name and 4 + 7 * 8 bytes.
  const int32_t n = r.Count("num_links", limits.max_join_links, kMinString + 4 + 7 * 8);
  for (int32_t i = 0; i < n && !r.failed(); ++i) r.String("link_name[]", limits.max_id_bytes);
  r.Fixed("parent", static_cast<size_t>(n) * 4);
  r.Fixed("a, b, radius", static_cast<size_t>(n) * 7 * 8);
  const int32_t k = r.Count("num_ignore", limits.max_ignore_rules, kMinString);
  for (int32_t i = 0; i < k && !r.failed(); ++i) r.String("ignore[]", limits.max_text_bytes);
  // Per entity rule: three strings (a link, an id, a link or empty).
  const int32_t e = r.Count("num_ignore_entities", limits.max_ignore_rules, 3 * kMinString);
  for (int32_t i = 0; i < e && !r.failed(); ++i) {
    r.String("ignore_entity_link[]", limits.max_id_bytes);
  }
  for (int32_t i = 0; i < e && !r.failed(); ++i) r.String("ignore_entity[]", limits.max_id_bytes);
  for (int32_t i = 0; i < e && !r.failed(); ++i) {
    r.String("ignore_entity_other_link[]", limits.max_id_bytes);
  }
  r.Fixed("mac", kMac);
  return r.Finish();
}

std::string CheckWire(const join_reply_t*, const void* data, size_t size,
                      const WireLimits& limits) {
  if (std::string p = TooLong(size, limits); !p.empty()) return p;
  WireReader r(data, size);
  r.Fingerprint(join_reply_t::getHash());
  r.Fixed("utime", 8);
  r.String("client_id", limits.max_id_bytes);
  r.Fixed("nonce, reason", 8 + 1);
  r.String("message", limits.max_text_bytes);
  r.Fixed("session, instance, silence_timeout_ms", 3 * 8);
  const int32_t n = r.Count("sealed_key_size", limits.max_sealed_key_bytes, 1);
  r.Fixed("sealed_key", static_cast<size_t>(n));
  r.Fixed("mac", kMac);
  return r.Finish();
}

std::string CheckWire(const leave_t*, const void* data, size_t size, const WireLimits& limits) {
  if (std::string p = TooLong(size, limits); !p.empty()) return p;
  WireReader r(data, size);
  r.Fingerprint(leave_t::getHash());
  r.Fixed("utime", 8);
  r.String("client_id", limits.max_id_bytes);
  r.Fixed("session", 8);
  r.Fixed("mac", kMac);
  return r.Finish();
}

std::string CheckWire(const object_pose_t*, const void* data, size_t size,
                      const WireLimits& limits) {
  if (std::string p = TooLong(size, limits); !p.empty()) return p;
  WireReader r(data, size);
  r.Fingerprint(object_pose_t::getHash());
  r.Fixed("utime", 8);
  r.String("object_id", limits.max_id_bytes);
  r.Fixed("session", 8);
  r.Fixed("seq", 8);
  r.Fixed("position", 3 * 8);
  r.Fixed("orientation", 4 * 8);
  r.Fixed("mac", kMac);
  return r.Finish();
}

std::string CheckWire(const shared_contact_t*, const void* data, size_t size,
                      const WireLimits& limits) {
  if (std::string p = TooLong(size, limits); !p.empty()) return p;
  WireReader r(data, size);
  r.Fingerprint(shared_contact_t::getHash());
  r.Fixed("utime", 8);
  r.String("client_id", limits.max_id_bytes);
  r.Fixed("seq0..receive_utime", 6 * 8);
  const int32_t n = r.Count("num_entries", limits.max_shared_entries, kMinSharedEntry);
  for (int32_t i = 0; i < n && !r.failed(); ++i) {
    r.String("entries[].entity", limits.max_id_bytes);
    r.Fixed("entries[].entity_kind..t_to", 1 + 2 * 8);
    r.Fixed("entries[].result", 1);
    r.String("entries[].error", limits.max_text_bytes);
    r.Fixed("entries[].initially_colliding..t_hi", 2 + 4 * 8);
    const int32_t contacts =
        r.Count("entries[].num_contacts", limits.max_contacts, kEntityContact);
    r.Fixed("entries[].contacts", static_cast<size_t>(contacts) * kEntityContact);
    const int32_t links = r.Count("entries[].num_links", limits.max_links, kEntityLinkBracket);
    r.Fixed("entries[].links", static_cast<size_t>(links) * kEntityLinkBracket);
    r.Fixed("entries[].waited_us..queue_us", 8 + 1 + 8 + 8);
  }
  r.Fixed("mac", kMac);
  return r.Finish();
}

std::string PeekPoseClientId(const void* data, size_t size) {
  const auto* bytes = static_cast<const uint8_t*>(data);
  // Fingerprint (8), utime (8), then the string's length.
  if (size < 20) return "";
  const int32_t n = static_cast<int32_t>((uint32_t{bytes[16]} << 24) | (uint32_t{bytes[17]} << 16) |
                                         (uint32_t{bytes[18]} << 8) | uint32_t{bytes[19]});
  if (n < 1 || static_cast<size_t>(n) > size - 20) return "";
  return std::string(reinterpret_cast<const char*>(bytes + 20), static_cast<size_t>(n - 1));
}

}  // namespace sweptccd
