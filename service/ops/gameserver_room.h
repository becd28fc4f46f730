#pragma once
// The room a GameServer holds, from the Agones SDK sidecar's JSON (its REST
// gateway's field names: object_meta.labels): the label kRoomLabel, the same
// label the clients' allocator requests select on (client/room_resolver.h).

#include <string>

namespace sweptccd {

inline constexpr const char* kRoomLabel = "sweptccd.dev/room";

struct GameServerRoom {
  std::string room;     // The label's value; empty: none (or a problem).
  std::string problem;  // One line, already escaped; empty: fine.
};

/// `json` is a GameServer (GET /gameserver) or, with `watch_event`, one
/// line of GET /watch/gameserver ({"result": GameServer}). A GameServer
/// without the label: room and problem empty. A label that breaks the id
/// rule, or JSON of another shape: problem set.
GameServerRoom RoomOfGameServer(const std::string& json, bool watch_event);

}  // namespace sweptccd
