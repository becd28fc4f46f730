#include "service/ws/client_message.h"

#include <nlohmann/json.hpp>

#include "msgs/text.h"
#include "service/ws/json_fields.h"
#include "service/ws/lcm_json.h"

namespace sweptccd::ws {

int JsonDepth(std::string_view text, int limit) {
  int depth = 0, deepest = 0;
  bool in_string = false, escaped = false;
  for (const char c : text) {
    if (in_string) {
      if (escaped) {
        escaped = false;
      } else if (c == '\\') {
        escaped = true;
      } else if (c == '"') {
        in_string = false;
      }
      continue;
    }
    if (c == '"') {
      in_string = true;
    } else if (c == '[' || c == '{') {
      if (++depth > deepest) deepest = depth;
      if (deepest > limit) return limit + 1;
    } else if (c == ']' || c == '}') {
      --depth;
    }
  }
  return deepest;
}

ClientDecodeResult DecodeClientMessage(std::string_view text, const WireLimits& limits) {
  ClientDecodeResult r;
  if (text.size() > limits.max_message_bytes) {
    r.code = "too_big";
    r.problem = "message of " + std::to_string(text.size()) + " bytes, over the limit " +
                std::to_string(limits.max_message_bytes);
    return r;
  }
  if (JsonDepth(text, kMaxJsonDepth) > kMaxJsonDepth) {
    r.code = "bad_json";
    r.problem = "nested deeper than " + std::to_string(kMaxJsonDepth);
    return r;
  }
  try {
    const nlohmann::json v = nlohmann::json::parse(text.begin(), text.end(), nullptr,
                                                   /*allow_exceptions=*/false);
    if (v.is_discarded() || !v.is_object()) {
      r.code = "bad_json";
      r.problem = v.is_discarded() ? "not valid JSON" : "not a JSON object";
      return r;
    }
    const auto t = v.find("type");
    if (t == v.end() || !t->is_string()) {
      r.code = "bad_message";
      r.problem = "type: missing or not a string";
      return r;
    }
    const std::string& type = t->get_ref<const std::string&>();
    ClientMessage m;
    if (type == "join_request") {
      m.kind = ClientMessage::Kind::kJoin;
      FromJson(v, limits, &m.join, &m.proof);
    } else if (type == "tracker_pose") {
      m.kind = ClientMessage::Kind::kPose;
      FromJson(v, limits, &m.pose);
    } else if (type == "leave") {
      m.kind = ClientMessage::Kind::kLeave;
      FromJson(v, limits, &m.leave);
    } else if (type == "object_pose") {
      m.kind = ClientMessage::Kind::kObjectPose;
      FromJson(v, limits, &m.object_pose);
    } else if (type == "ping") {
      const Fields f(v, type);
      m.kind = ClientMessage::Kind::kPing;
      if (f.Find("utime")) m.ping_utime = f.Int("utime", -kMaxSafeInteger, kMaxSafeInteger);
    } else if (type == "subscribe" || type == "object_attach") {
      const Fields f(v, type);
      m.kind = type == "subscribe" ? ClientMessage::Kind::kSubscribe
                                   : ClientMessage::Kind::kObjectAttach;
      if (m.kind == ClientMessage::Kind::kObjectAttach) {
        m.object_id = f.String("object_id", static_cast<size_t>(limits.max_id_bytes));
      }
      if (const nlohmann::json* p = f.Find("proof")) m.proof = StringAt(*p, f.Path("proof"), 64);
    } else {
      r.code = "unknown_type";
      r.problem = "type '" + EscapeForDisplay(type, 64) + "' is not a client message";
      return r;
    }
    r.message = std::move(m);
  } catch (const WsProtocolError& e) {
    r.code = e.code();
    r.problem = e.what();
  } catch (const std::exception& e) {
    r.code = "bad_message";
    r.problem = std::string("cannot decode: ") + e.what();
  }
  return r;
}

}  // namespace sweptccd::ws
