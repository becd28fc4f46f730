#pragma once
// Room discovery (docs/DEPLOY.md, "Finding a room"): a room name resolved to
// the address of its WebSocket door, either through a static map file (one
// host, a few rooms) or through the Agones allocator's REST API
// (get-or-allocate a GameServer by a room label). Everything read from a
// file or the network is checked before use (sizes, the id rule, ports) and
// every failure is one line (RoomError).

#include <cstdint>
#include <map>
#include <memory>
#include <nlohmann/json.hpp>
#include <stdexcept>
#include <string>

namespace sweptccd {

/// Where a room's door is: ws[s]://host:port/ws.
struct DoorAddress {
  std::string host;  // An IPv4 or IPv6 literal (no brackets) or a DNS name.
  uint16_t port = 0;
  bool tls = false;
  /// Where it came from, for logs: "static", or "agones:GAMESERVER".
  std::string source;
  std::string Url() const;
};

/// A resolution that failed: one line, safe to print (escaped).
class RoomError : public std::runtime_error {
 public:
  /// retryable: the room may exist in a moment (no server Ready yet, the
  /// allocator unreachable); false: a configuration error (no such room in a
  /// static map, a malformed answer).
  RoomError(const std::string& message, bool retryable)
      : std::runtime_error(message), retryable_(retryable) {}
  bool retryable() const { return retryable_; }

 private:
  bool retryable_;
};

class RoomResolver {
 public:
  virtual ~RoomResolver() = default;
  /// The door of room `room` (the id rule: 1-64 of A-Z a-z 0-9 _ . -).
  /// Throws RoomError. May block (network) up to the resolver's timeout.
  virtual DoorAddress Resolve(const std::string& room) = 0;
};

/// The door's WebSocket target for a client of `room`: "/ws?room=ROOM" (the
/// door refuses another room's client with 409 before any frame,
/// docs/WEBSOCKET.md section 1), or "/ws" when `room` is empty (no
/// resolver: any door). `room` follows the id rule (URL-safe as it is).
std::string DoorTarget(const std::string& room);

/// The one check of a hello against the room the client resolved
/// (docs/WEBSOCKET.md section 5, hello.room): "" when `room` is empty (no
/// resolver) or the hello names `room`; else one line, safe to print, saying
/// which room the door holds (a room mix-up: another room's events must
/// never be delivered). A hello without a string `room` is refused too: a
/// door reached through a resolver tells its room.
std::string HelloRoomProblem(const std::string& room, const nlohmann::json& hello,
                             const std::string& door);

/// "ws://HOST:PORT[/ws]" or "wss://..."; HOST an IPv4 literal, [IPv6] or a
/// DNS name of at most 253 characters. Throws RoomError (not retryable).
DoorAddress ParseDoorUrl(const std::string& url);

/// The static map (docs/DEPLOY.md): a JSON object
/// {"rooms": {"NAME": "wss://HOST:PORT", ...}}, at most 1 MiB and 4096 rooms.
class StaticRoomMap : public RoomResolver {
 public:
  /// Parses the text of a map file; `what` names it in errors.
  static StaticRoomMap FromText(const std::string& text, const std::string& what);
  /// Reads and parses FILE. Throws RoomError.
  static StaticRoomMap FromFile(const std::string& path);
  DoorAddress Resolve(const std::string& room) override;
  size_t size() const { return rooms_.size(); }

 private:
  std::map<std::string, DoorAddress> rooms_;
};

/// The Agones allocator service (its REST gateway: POST /gameserverallocation,
/// agones allocation.proto). Get-or-allocate: the first selector asks for an
/// Allocated GameServer already labelled with the room, the second for a
/// Ready one of the scene's fleet; the allocation labels it with the room.
struct AgonesAllocatorOptions {
  std::string url;  // https://HOST[:PORT] of the allocator service (http:// for tests only)
  std::string k8s_namespace = "default";
  std::string room_label = "sweptccd.dev/room";
  /// Labels of the fleet to allocate a new room from (e.g. the scene's):
  /// {"sweptccd.dev/scene": "arcade"}. At least one.
  std::map<std::string, std::string> fleet_labels;
  std::string port_name = "websocket";  // The GameServer port of the door.
  bool door_tls = true;                 // The door is wss:// (the fleets' doors are).
  /// mTLS to the allocator (Agones' allocator asks for a client certificate).
  std::string ca_file, client_cert_file, client_key_file;
  double timeout_s = 2.0;
};

class AgonesAllocatorResolver : public RoomResolver {
 public:
  explicit AgonesAllocatorResolver(AgonesAllocatorOptions options);
  DoorAddress Resolve(const std::string& room) override;

  /// The request body for room `room` (pure; tested).
  static nlohmann::json RequestBody(const AgonesAllocatorOptions& options, const std::string& room);
  /// The door out of an AllocationResponse body (at most 64 KiB, checked).
  /// Throws RoomError.
  static DoorAddress ParseResponse(const AgonesAllocatorOptions& options, const std::string& body);

 private:
  AgonesAllocatorOptions options_;
};

}  // namespace sweptccd
