#pragma once
// The JSON mirror of the LCM types (docs/WEBSOCKET.md sections 5-6): every
// field of msgs/*.lcm under the same name, arrays for the `num_*` counts,
// nested records as objects; without `mac`, `public_key`, `sealed_key`.
// ToJson writes "type" first for top-level messages; FromJson checks every
// field (json_fields.h) against WireLimits before sizing anything.

#include <nlohmann/json.hpp>

#include "msgs/checked_decode.h"
#include "sweptccd/contact_event_t.hpp"
#include "sweptccd/join_reply_t.hpp"
#include "sweptccd/join_request_t.hpp"
#include "sweptccd/leave_t.hpp"
#include "sweptccd/object_pose_t.hpp"
#include "sweptccd/rejection_t.hpp"
#include "sweptccd/shared_contact_t.hpp"
#include "sweptccd/status_t.hpp"
#include "sweptccd/tracker_pose_t.hpp"

namespace sweptccd::ws {

using OrderedJson = nlohmann::ordered_json;

/// The readable twin of join_reply_t.reason ("accepted", "id_in_use"...),
/// "unknown" for a value outside the table.
const char* JoinReasonName(int reason);
/// contact_event_t / shared_entry_t result: "free", "contact", "invalid".
const char* ResultName(int result);

// Top-level messages: {"type": ..., fields...}.
OrderedJson ToJson(const contact_event_t& m);
OrderedJson ToJson(const shared_contact_t& m);
OrderedJson ToJson(const rejection_t& m);
OrderedJson ToJson(const status_t& m);
OrderedJson ToJson(const join_reply_t& m);
/// join_request_t's fields (without public_key, mac) and "proof".
OrderedJson ToJson(const join_request_t& m, const std::string& proof);
OrderedJson ToJson(const tracker_pose_t& m);
OrderedJson ToJson(const leave_t& m);
OrderedJson ToJson(const object_pose_t& m);

// Readers of the same shapes ("type" is not looked at). Each throws
// WsProtocolError("bad_message", ...) naming the field. The `num_*` counts
// are set from the array lengths; mac, public_key and sealed_key are zero
// / empty.
void FromJson(const nlohmann::json& v, const WireLimits& limits, contact_event_t* m);
void FromJson(const nlohmann::json& v, const WireLimits& limits, shared_contact_t* m);
void FromJson(const nlohmann::json& v, const WireLimits& limits, rejection_t* m);
void FromJson(const nlohmann::json& v, const WireLimits& limits, status_t* m);
void FromJson(const nlohmann::json& v, const WireLimits& limits, join_reply_t* m);
/// Also returns the proof ("" when absent).
void FromJson(const nlohmann::json& v, const WireLimits& limits, join_request_t* m,
              std::string* proof);
void FromJson(const nlohmann::json& v, const WireLimits& limits, tracker_pose_t* m);
void FromJson(const nlohmann::json& v, const WireLimits& limits, leave_t* m);
void FromJson(const nlohmann::json& v, const WireLimits& limits, object_pose_t* m);

}  // namespace sweptccd::ws
