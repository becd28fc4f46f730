#pragma once
// One text message from a WebSocket client (docs/WEBSOCKET.md section 6),
// decoded with every check before anything is sized from it: the byte count,
// the nesting depth, the JSON syntax (nlohmann-json), the type, then every
// field (lcm_json.h).

#include <optional>
#include <string>
#include <string_view>

#include "msgs/checked_decode.h"
#include "sweptccd/join_request_t.hpp"
#include "sweptccd/leave_t.hpp"
#include "sweptccd/object_pose_t.hpp"
#include "sweptccd/tracker_pose_t.hpp"

namespace sweptccd::ws {

/// Deepest nesting of arrays and objects a message may have (a join's `a`
/// is 3 deep).
inline constexpr int kMaxJsonDepth = 32;

struct ClientMessage {
  enum class Kind { kJoin, kPose, kLeave, kSubscribe, kObjectAttach, kObjectPose, kPing };
  Kind kind = Kind::kPose;
  join_request_t join;        // kJoin.
  tracker_pose_t pose;        // kPose.
  leave_t leave;              // kLeave.
  object_pose_t object_pose;  // kObjectPose.
  std::string object_id;      // kObjectAttach.
  std::string proof;          // kJoin, kSubscribe, kObjectAttach ("" when absent).
  int64_t ping_utime = 0;     // kPing: the client's utime, echoed (0 when absent).
};

/// The message, or an error code of docs/WEBSOCKET.md (bad_json,
/// bad_message, unknown_type, too_big) with one line naming the problem.
struct ClientDecodeResult {
  std::optional<ClientMessage> message;
  std::string code;
  std::string problem;
  bool ok() const { return message.has_value(); }
};

/// Decodes one message. `limits.max_message_bytes` caps the text. Never
/// throws. Thread-safe.
ClientDecodeResult DecodeClientMessage(std::string_view text, const WireLimits& limits);

/// The deepest nesting of [ and { outside strings in `text`, stopping once
/// it passes `limit` (then returns limit + 1).
int JsonDepth(std::string_view text, int limit);

}  // namespace sweptccd::ws
