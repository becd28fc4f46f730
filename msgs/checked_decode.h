#pragma once
// Decoding that the wire cannot crash or make allocate: every message is
// walked over its raw bytes (fingerprint, string lengths, array counts, no
// trailing bytes) against its own byte count and configured limits BEFORE
// the lcm-gen decoder runs. lcm-gen 1.3.1's decoders trust lengths from the
// wire: a negative string length reads past the buffer (a segfault no
// try/catch stops) and array counts size allocations unchecked.

#include <cstddef>
#include <cstdint>
#include <new>
#include <optional>
#include <string>

#include "sweptccd/contact_event_t.hpp"
#include "sweptccd/join_reply_t.hpp"
#include "sweptccd/join_request_t.hpp"
#include "sweptccd/leave_t.hpp"
#include "sweptccd/object_pose_t.hpp"
#include "sweptccd/rejection_t.hpp"
#include "sweptccd/shared_contact_t.hpp"
#include "sweptccd/status_t.hpp"
#include "sweptccd/tracker_pose_t.hpp"

namespace sweptccd {

/// Bounds on what one message may carry. A message beyond any is refused
/// before decoding.
struct WireLimits {
  size_t max_message_bytes = 4 << 20;  // Whole datagram.
  int32_t max_id_bytes = 256;          // A client_id string (the id rule then asks for <= 64).
  int32_t max_text_bytes = 4096;       // Any other string (reason, message, error, backend).
  int32_t max_links = 1024;            // Links per skeleton (poses, per-link brackets).
  int32_t max_contacts = 4096;         // Witnesses in one contact event.
  int32_t max_clients = 4096;          // Clients in one status message.
  int32_t max_join_links = 1024;       // Links in one join_request_t (the daemon's max_links
                                       // then refuses more with a reply).
  int32_t max_ignore_rules = 256;      // Filter rules in one join_request_t.
  int32_t max_sealed_key_bytes = 128;  // join_reply_t.sealed_key.
  int32_t max_shared_entries = shared_contact_t::MAX_ENTRIES;  // Entries in one shared_contact_t.
};

/// The message, or a one-line problem naming the field, the value and the
/// byte offset. Exactly one of the two is set.
template <class T>
struct DecodeResult {
  std::optional<T> message;
  std::string problem;
  bool ok() const { return message.has_value(); }
};

/// Walks the encoding of one message type without decoding it: "" when the
/// bytes are a complete, well-formed message of that type within `limits`
/// (then the generated decoder reads exactly `size` bytes and allocates at
/// most what the limits allow), else the problem. Never allocates in
/// proportion to anything read from the bytes. Thread-safe.
std::string CheckWire(const tracker_pose_t*, const void* data, size_t size,
                      const WireLimits& limits);
std::string CheckWire(const contact_event_t*, const void* data, size_t size,
                      const WireLimits& limits);
std::string CheckWire(const rejection_t*, const void* data, size_t size, const WireLimits& limits);
std::string CheckWire(const status_t*, const void* data, size_t size, const WireLimits& limits);
std::string CheckWire(const join_request_t*, const void* data, size_t size,
                      const WireLimits& limits);
std::string CheckWire(const join_reply_t*, const void* data, size_t size,
                      const WireLimits& limits);
std::string CheckWire(const leave_t*, const void* data, size_t size, const WireLimits& limits);
std::string CheckWire(const object_pose_t*, const void* data, size_t size,
                      const WireLimits& limits);
std::string CheckWire(const shared_contact_t*, const void* data, size_t size,
                      const WireLimits& limits);

/// The client_id of an encoded tracker_pose_t, join_request_t or leave_t (all
/// three start with fingerprint, utime, client_id; so does object_pose_t's
/// object_id) that CheckWire accepted (to
/// pick the key before verifying). Precondition: CheckWire returned "".
std::string PeekPoseClientId(const void* data, size_t size);

/// The one entry point for incoming messages (daemon and tools): CheckWire,
/// then the generated decoder. Never throws and never aborts: allocation
/// failure or any exception becomes a problem. Thread-safe.
template <class T>
DecodeResult<T> DecodeChecked(const void* data, size_t size, const WireLimits& limits) {
  DecodeResult<T> result;
  try {
    result.problem = CheckWire(static_cast<const T*>(nullptr), data, size, limits);
    if (!result.problem.empty()) return result;
    T msg;
    const int read = msg.decode(data, 0, static_cast<int>(size));
    if (read != static_cast<int>(size)) {
      result.problem = "the decoder read " + std::to_string(read) + " of " +
                       std::to_string(size) + " bytes";
      return result;
    }
    result.message = std::move(msg);
  } catch (const std::bad_alloc&) {
    result.problem = "out of memory decoding " + std::to_string(size) + " bytes";
  } catch (const std::exception& e) {
    result.problem = std::string("decoding failed: ") + e.what();
  }
  return result;
}

}  // namespace sweptccd
