// Room discovery (client/room_resolver.cc): the static map's format and its
// refusals, door URLs, the Agones allocator's request body and the checks on
// its answer (hostile input: sizes, ports, hosts).
#include "sweptccd_client/room_resolver.h"

#include <gtest/gtest.h>

namespace sweptccd {
namespace {

TEST(RoomResolverTest, DoorUrls) {
  DoorAddress d = ParseDoorUrl("wss://10.0.1.2:8765/ws");
  EXPECT_EQ(d.host, "10.0.1.2");
  EXPECT_EQ(d.port, 8765);
  EXPECT_TRUE(d.tls);
  EXPECT_EQ(d.Url(), "wss://10.0.1.2:8765/ws");
  d = ParseDoorUrl("ws://[::1]:80");
  EXPECT_EQ(d.host, "::1");
  EXPECT_FALSE(d.tls);
  EXPECT_EQ(d.Url(), "ws://[::1]:80/ws");
  EXPECT_EQ(ParseDoorUrl("ws://room-3.arcade.example:1").host, "room-3.arcade.example");
  for (const char* bad : {"http://a:1", "ws://a", "ws://a:0", "ws://a:65536", "ws://a:1x",
                          "ws://user@a:1", "ws://a/b:1", "ws://[zz]:1", "ws://:1", "wss://a:-1"}) {
    EXPECT_THROW(ParseDoorUrl(bad), RoomError) << bad;
  }
}

TEST(RoomResolverTest, StaticMap) {
  StaticRoomMap map = StaticRoomMap::FromText(
      R"({"rooms": {"arcade-1": "wss://10.0.0.5:8765", "lab": "ws://127.0.0.1:8765/ws"}})", "t");
  EXPECT_EQ(map.size(), 2u);
  EXPECT_EQ(map.Resolve("arcade-1").Url(), "wss://10.0.0.5:8765/ws");
  EXPECT_EQ(map.Resolve("lab").port, 8765);
  try {
    map.Resolve("nowhere");
    FAIL();
  } catch (const RoomError& e) {
    EXPECT_FALSE(e.retryable());
    EXPECT_NE(std::string(e.what()).find("not in the room map"), std::string::npos);
  }
  EXPECT_THROW(map.Resolve("bad room"), RoomError);
  for (const char* bad : {"[]", "{}", R"({"rooms": []})", R"({"rooms": {"a b": "ws://h:1"}})",
                          R"({"rooms": {"a": 5}})", R"({"rooms": {"a": "ws://h"}})", "{"}) {
    EXPECT_THROW(StaticRoomMap::FromText(bad, "t"), RoomError) << bad;
  }
  EXPECT_THROW(StaticRoomMap::FromText(std::string(2 << 20, ' '), "t"), RoomError);
  EXPECT_THROW(StaticRoomMap::FromFile("/nonexistent/rooms.json"), RoomError);
}

AgonesAllocatorOptions Options() {
  AgonesAllocatorOptions o;
  o.url = "https://allocator:443";
  o.fleet_labels = {{"sweptccd.dev/scene", "dragon"}};
  return o;
}

TEST(RoomResolverTest, AllocatorRequestIsGetOrAllocateByRoomLabel) {
  const nlohmann::json body = AgonesAllocatorResolver::RequestBody(Options(), "arcade-7");
  const nlohmann::json want = nlohmann::json::parse(R"({
    "namespace": "default",
    "gameServerSelectors": [
      {"matchLabels": {"sweptccd.dev/room": "arcade-7"}, "gameServerState": "ALLOCATED"},
      {"matchLabels": {"sweptccd.dev/scene": "dragon"}, "gameServerState": "READY"}],
    "metadata": {"labels": {"sweptccd.dev/room": "arcade-7"}}})");
  EXPECT_EQ(body, want);
}

TEST(RoomResolverTest, AllocatorAnswerChecked) {
  const DoorAddress d = AgonesAllocatorResolver::ParseResponse(Options(), R"({
    "gameServerName": "dragon-x7k2p", "address": "10.0.3.2", "nodeName": "n1",
    "ports": [{"name": "metrics", "port": 9464}, {"name": "websocket", "port": 7011}]})");
  EXPECT_EQ(d.Url(), "wss://10.0.3.2:7011/ws");
  EXPECT_EQ(d.source, "agones:dragon-x7k2p");
  for (const char* bad :
       {"", "[]", R"({"address": "10.0.3.2"})",
        R"({"address": "10.0.3.2", "ports": [{"name": "other", "port": 1}]})",
        R"({"address": "10.0.3.2", "ports": [{"name": "websocket", "port": 70000}]})",
        R"({"address": "10.0.3.2", "ports": [{"name": "websocket", "port": "1"}]})",
        R"({"address": "a/b", "ports": [{"name": "websocket", "port": 1}]})",
        R"({"address": "", "ports": [{"name": "websocket", "port": 1}]})"}) {
    EXPECT_THROW(AgonesAllocatorResolver::ParseResponse(Options(), bad), RoomError) << bad;
  }
  AgonesAllocatorOptions no_fleet = Options();
  no_fleet.fleet_labels.clear();
  EXPECT_THROW(AgonesAllocatorResolver{no_fleet}, RoomError);
  AgonesAllocatorOptions ftp = Options();
  ftp.url = "ftp://x";
  EXPECT_THROW(AgonesAllocatorResolver{ftp}, RoomError);
}

TEST(RoomResolverTest, AllocatorUnreachableIsRetryable) {
  AgonesAllocatorOptions o = Options();
  o.url = "http://127.0.0.1:1";  // Nothing listens on port 1.
  o.timeout_s = 1;
  AgonesAllocatorResolver r(o);
  try {
    r.Resolve("arcade-7");
    FAIL();
  } catch (const RoomError& e) {
    EXPECT_TRUE(e.retryable());
  }
  EXPECT_THROW(r.Resolve("../etc"), RoomError);
}

TEST(RoomResolverTest, DoorTargetNamesTheRoom) {
  EXPECT_EQ(DoorTarget(""), "/ws");
  EXPECT_EQ(DoorTarget("arcade-7"), "/ws?room=arcade-7");
}

TEST(RoomResolverTest, HelloOfAnotherRoomIsRefused) {
  const auto hello = [](nlohmann::json room) {
    nlohmann::json h = {{"type", "hello"}, {"instance", 1}};
    if (!room.is_null()) h["room"] = room;
    return h;
  };
  const std::string door = "wss://10.0.1.2:8765/ws";
  // No room asked (no resolver): any door.
  EXPECT_EQ(HelloRoomProblem("", hello("lobby"), door), "");
  EXPECT_EQ(HelloRoomProblem("", hello(nullptr), door), "");
  EXPECT_EQ(HelloRoomProblem("arcade-7", hello("arcade-7"), door), "");
  const std::string other = HelloRoomProblem("arcade-7", hello("arcade-8"), door);
  EXPECT_NE(other.find("holds room 'arcade-8', not room 'arcade-7'"), std::string::npos) << other;
  EXPECT_NE(other.find(door), std::string::npos) << other;
  const std::string none = HelloRoomProblem("arcade-7", hello(nullptr), door);
  EXPECT_NE(none.find("does not say which room"), std::string::npos) << none;
  EXPECT_NE(HelloRoomProblem("arcade-7", hello(7), door), "");
  // A hostile room name is escaped: one line, no raw control bytes.
  const std::string hostile = HelloRoomProblem("arcade-7", hello("x\n\x1b[31m"), door);
  EXPECT_EQ(hostile.find('\n'), std::string::npos);
  EXPECT_EQ(hostile.find('\x1b'), std::string::npos);
}

}  // namespace
}  // namespace sweptccd
