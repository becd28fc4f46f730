#include "sweptccd_client/room_resolver.h"

#include <curl/curl.h>

#include <cctype>
#include <fstream>
#include <sstream>

#include "msgs/text.h"

namespace sweptccd {

namespace {

constexpr size_t kMaxMapBytes = 1 << 20;
constexpr size_t kMaxRooms = 4096;
constexpr size_t kMaxResponseBytes = 64 << 10;
constexpr size_t kMaxHostBytes = 253;

std::string Show(const std::string& s) { return "'" + EscapeForDisplay(s, 80) + "'"; }

// A DNS name or an IPv4 literal: letters, digits, '-', '.'; an IPv6 literal:
// hex digits, ':' and '.'. Nothing that could smuggle a path or a user.
bool IsHostName(const std::string& h) {
  if (h.empty() || h.size() > kMaxHostBytes) return false;
  for (char c : h) {
    if (!(std::isalnum(static_cast<unsigned char>(c)) || c == '-' || c == '.')) return false;
  }
  return true;
}

bool IsIpv6Literal(const std::string& h) {
  if (h.size() < 2 || h.size() > 45) return false;
  for (char c : h) {
    if (!(std::isxdigit(static_cast<unsigned char>(c)) || c == ':' || c == '.')) return false;
  }
  return h.find(':') != std::string::npos;
}

void CheckRoomName(const std::string& room) {
  if (!IsValidClientId(room)) {
    throw RoomError("room name " + Show(room) + " breaks the id rule (1-64 of A-Z a-z 0-9 _ . -)",
                    false);
  }
}

size_t AppendBounded(char* data, size_t size, size_t n, void* user) {
  auto* out = static_cast<std::string*>(user);
  const size_t bytes = size * n;
  if (out->size() + bytes > kMaxResponseBytes) return 0;  // curl fails the transfer.
  out->append(data, bytes);
  return bytes;
}

}  // namespace

std::string DoorAddress::Url() const {
  const bool v6 = host.find(':') != std::string::npos;
  return std::string(tls ? "wss://" : "ws://") + (v6 ? "[" + host + "]" : host) + ":" +
         std::to_string(port) + "/ws";
}

std::string DoorTarget(const std::string& room) {
  return room.empty() ? std::string("/ws") : "/ws?room=" + room;
}

std::string HelloRoomProblem(const std::string& room, const nlohmann::json& hello,
                             const std::string& door) {
  if (room.empty()) return "";
  const auto it = hello.find("room");
  if (it != hello.end() && it->is_string() && it->get<std::string>() == room) return "";
  const std::string held = it != hello.end() && it->is_string()
                               ? "holds room " + Show(it->get<std::string>())
                               : "does not say which room it holds";
  return "door " + Show(door) + " " + held + ", not room " + Show(room) +
         ": refused (a room mix-up; resolving again)";
}

DoorAddress ParseDoorUrl(const std::string& url) {
  DoorAddress d;
  std::string rest;
  if (url.rfind("wss://", 0) == 0) {
    d.tls = true;
    rest = url.substr(6);
  } else if (url.rfind("ws://", 0) == 0) {
    rest = url.substr(5);
  } else {
    throw RoomError("door address " + Show(url) + " is not ws://HOST:PORT or wss://HOST:PORT",
                    false);
  }
  if (rest.size() >= 3 && rest.compare(rest.size() - 3, 3, "/ws") == 0) {
    rest.resize(rest.size() - 3);
  }
  size_t colon;
  if (!rest.empty() && rest[0] == '[') {
    const size_t close = rest.find(']');
    if (close == std::string::npos || close + 1 >= rest.size() || rest[close + 1] != ':') {
      throw RoomError("door address " + Show(url) + ": expected [IPv6]:PORT", false);
    }
    d.host = rest.substr(1, close - 1);
    if (!IsIpv6Literal(d.host)) throw RoomError("door address " + Show(url) + ": bad IPv6", false);
    colon = close + 1;
  } else {
    colon = rest.rfind(':');
    if (colon == std::string::npos) {
      throw RoomError("door address " + Show(url) + " has no :PORT", false);
    }
    d.host = rest.substr(0, colon);
    if (!IsHostName(d.host)) {
      throw RoomError("door address " + Show(url) + ": host is not a name or an address", false);
    }
  }
  const std::string port = rest.substr(colon + 1);
  if (port.empty() || port.size() > 5 ||
      port.find_first_not_of("0123456789") != std::string::npos || std::stoi(port) < 1 ||
      std::stoi(port) > 65535) {
    throw RoomError("door address " + Show(url) + ": port is not 1-65535", false);
  }
  d.port = static_cast<uint16_t>(std::stoi(port));
  d.source = "static";
  return d;
}

StaticRoomMap StaticRoomMap::FromText(const std::string& text, const std::string& what) {
  if (text.size() > kMaxMapBytes) {
    throw RoomError(what + ": over " + std::to_string(kMaxMapBytes) + " bytes", false);
  }
  const nlohmann::json j = nlohmann::json::parse(text, nullptr, false);
  if (j.is_discarded() || !j.is_object() || !j.contains("rooms") || !j["rooms"].is_object()) {
    throw RoomError(what + ": not a JSON object with an object \"rooms\"", false);
  }
  if (j["rooms"].size() > kMaxRooms) {
    throw RoomError(what + ": more than " + std::to_string(kMaxRooms) + " rooms", false);
  }
  StaticRoomMap map;
  for (const auto& [name, url] : j["rooms"].items()) {
    CheckRoomName(name);
    if (!url.is_string())
      throw RoomError(what + ": room " + Show(name) + " is not a string", false);
    map.rooms_[name] = ParseDoorUrl(url.get<std::string>());
  }
  return map;
}

StaticRoomMap StaticRoomMap::FromFile(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw RoomError("room map " + Show(path) + ": cannot be read", false);
  std::string text(kMaxMapBytes + 1, '\0');
  in.read(text.data(), static_cast<std::streamsize>(text.size()));
  text.resize(static_cast<size_t>(in.gcount()));
  return FromText(text, "room map " + Show(path));
}

DoorAddress StaticRoomMap::Resolve(const std::string& room) {
  CheckRoomName(room);
  const auto it = rooms_.find(room);
  if (it == rooms_.end()) throw RoomError("room " + Show(room) + " is not in the room map", false);
  return it->second;
}

AgonesAllocatorResolver::AgonesAllocatorResolver(AgonesAllocatorOptions options)
    : options_(std::move(options)) {
  if (options_.url.rfind("https://", 0) != 0 && options_.url.rfind("http://", 0) != 0) {
    throw RoomError("allocator URL " + Show(options_.url) + " is not https://HOST[:PORT]", false);
  }
  if (options_.fleet_labels.empty()) {
    throw RoomError(
        "allocator: no fleet label to allocate a new room from (e.g. "
        "sweptccd.dev/scene=NAME)",
        false);
  }
  curl_global_init(CURL_GLOBAL_DEFAULT);
}

nlohmann::json AgonesAllocatorResolver::RequestBody(const AgonesAllocatorOptions& options,
                                                    const std::string& room) {
  nlohmann::json room_labels = {{options.room_label, room}};
  nlohmann::json fleet = nlohmann::json::object();
  for (const auto& [k, v] : options.fleet_labels) fleet[k] = v;
  // allocation.proto: gameServerSelectors are tried in order; ALLOCATED asks
  // for a GameServer already allocated to this room (get), the second for a
  // Ready one of the fleet (allocate), which metadata then labels.
  return {{"namespace", options.k8s_namespace},
          {"gameServerSelectors",
           {{{"matchLabels", room_labels}, {"gameServerState", "ALLOCATED"}},
            {{"matchLabels", fleet}, {"gameServerState", "READY"}}}},
          {"metadata", {{"labels", room_labels}}}};
}

DoorAddress AgonesAllocatorResolver::ParseResponse(const AgonesAllocatorOptions& options,
                                                   const std::string& body) {
  if (body.size() > kMaxResponseBytes) throw RoomError("allocator: answer too long", true);
  const nlohmann::json j = nlohmann::json::parse(body, nullptr, false);
  if (j.is_discarded() || !j.is_object()) throw RoomError("allocator: answer is not JSON", true);
  const auto str = [&](const char* key) {
    return j.contains(key) && j[key].is_string() ? j[key].get<std::string>() : std::string();
  };
  DoorAddress d;
  d.host = str("address");
  if (!IsHostName(d.host) && !IsIpv6Literal(d.host)) {
    throw RoomError("allocator: answer's address " + Show(d.host) + " is not a host", true);
  }
  const std::string name = str("gameServerName");
  if (!j.contains("ports") || !j["ports"].is_array() || j["ports"].size() > 64) {
    throw RoomError("allocator: answer has no ports", true);
  }
  for (const auto& p : j["ports"]) {
    if (!p.is_object() || p.value("name", nlohmann::json()).is_string() == false) continue;
    if (p["name"].get<std::string>() != options.port_name) continue;
    if (!p.contains("port") || !p["port"].is_number_integer() || p["port"].get<int64_t>() < 1 ||
        p["port"].get<int64_t>() > 65535) {
      throw RoomError("allocator: port " + Show(options.port_name) + " is not 1-65535", true);
    }
    d.port = static_cast<uint16_t>(p["port"].get<int64_t>());
  }
  if (d.port == 0) {
    throw RoomError("allocator: answer has no port named " + Show(options.port_name), true);
  }
  d.tls = options.door_tls;
  d.source = "agones:" + EscapeForDisplay(name, 64);
  return d;
}

DoorAddress AgonesAllocatorResolver::Resolve(const std::string& room) {
  CheckRoomName(room);
  const std::string request = RequestBody(options_, room).dump();
  std::unique_ptr<CURL, void (*)(CURL*)> curl(curl_easy_init(), curl_easy_cleanup);
  if (!curl) throw RoomError("allocator: curl_easy_init failed", true);
  std::string response;
  curl_slist* headers = curl_slist_append(nullptr, "Content-Type: application/json");
  std::unique_ptr<curl_slist, void (*)(curl_slist*)> header_list(headers, curl_slist_free_all);
  const std::string url = options_.url + "/gameserverallocation";
  CURL* c = curl.get();
  curl_easy_setopt(c, CURLOPT_URL, url.c_str());
  curl_easy_setopt(c, CURLOPT_PROTOCOLS_STR, "http,https");
  curl_easy_setopt(c, CURLOPT_HTTPHEADER, headers);
  curl_easy_setopt(c, CURLOPT_POSTFIELDS, request.c_str());
  curl_easy_setopt(c, CURLOPT_POSTFIELDSIZE, static_cast<long>(request.size()));
  curl_easy_setopt(c, CURLOPT_WRITEFUNCTION, AppendBounded);
  curl_easy_setopt(c, CURLOPT_WRITEDATA, &response);
  curl_easy_setopt(c, CURLOPT_TIMEOUT_MS, static_cast<long>(options_.timeout_s * 1000));
  curl_easy_setopt(c, CURLOPT_NOSIGNAL, 1L);
  curl_easy_setopt(c, CURLOPT_FOLLOWLOCATION, 0L);
  if (!options_.ca_file.empty()) curl_easy_setopt(c, CURLOPT_CAINFO, options_.ca_file.c_str());
  if (!options_.client_cert_file.empty()) {
    curl_easy_setopt(c, CURLOPT_SSLCERT, options_.client_cert_file.c_str());
    curl_easy_setopt(c, CURLOPT_SSLKEY, options_.client_key_file.c_str());
  }
  const CURLcode rc = curl_easy_perform(c);
  if (rc != CURLE_OK) {
    throw RoomError("allocator " + Show(options_.url) + ": " + curl_easy_strerror(rc), true);
  }
  long status = 0;
  curl_easy_getinfo(c, CURLINFO_RESPONSE_CODE, &status);
  if (status == 429) {
    // grpc-gateway's ResourceExhausted: no GameServer Ready in the fleet.
    throw RoomError("allocator: no room server Ready for " + Show(room) + " (429); retry", true);
  }
  if (status != 200) {
    throw RoomError("allocator: HTTP " + std::to_string(status) + " for " + Show(room) + ": " +
                        EscapeForDisplay(response, 160),
                    status >= 500);
  }
  return ParseResponse(options_, response);
}

}  // namespace sweptccd
