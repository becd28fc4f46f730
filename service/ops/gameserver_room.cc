#include "service/ops/gameserver_room.h"

#include <nlohmann/json.hpp>

#include "msgs/text.h"

namespace sweptccd {

GameServerRoom RoomOfGameServer(const std::string& json, bool watch_event) {
  GameServerRoom out;
  const nlohmann::json doc = nlohmann::json::parse(json, nullptr, /*allow_exceptions=*/false);
  if (doc.is_discarded() || !doc.is_object()) {
    out.problem = "not a JSON object: " + EscapeForDisplay(json, 80);
    return out;
  }
  const nlohmann::json* gs = &doc;
  if (watch_event) {
    const auto result = doc.find("result");
    if (result == doc.end() || !result->is_object()) {
      out.problem = "a watch event without an object \"result\": " + EscapeForDisplay(json, 80);
      return out;
    }
    gs = &*result;
  }
  const auto meta = gs->find("object_meta");
  if (meta == gs->end() || !meta->is_object()) return out;  // No metadata, no label.
  const auto labels = meta->find("labels");
  if (labels == meta->end() || labels->is_null()) return out;
  if (!labels->is_object()) {
    out.problem = "object_meta.labels is not an object";
    return out;
  }
  const auto label = labels->find(kRoomLabel);
  if (label == labels->end()) return out;
  if (!label->is_string()) {
    out.problem = std::string("label ") + kRoomLabel + " is not a string";
    return out;
  }
  const std::string value = label->get<std::string>();
  if (!IsValidClientId(value)) {
    out.problem = std::string("label ") + kRoomLabel + " '" + EscapeForDisplay(value, 80) +
                  "' breaks the id rule (1-64 of A-Z a-z 0-9 _ . -)";
    return out;
  }
  out.room = value;
  return out;
}

}  // namespace sweptccd
