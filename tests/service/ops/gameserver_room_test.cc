// The room a GameServer holds, from the SDK sidecar's JSON
// (service/ops/gameserver_room.h): the shapes of GET /gameserver and of a
// GET /watch/gameserver line, and what a broken or hostile sidecar may send.
#include "service/ops/gameserver_room.h"

#include <gtest/gtest.h>

namespace sweptccd {
namespace {

TEST(GameServerRoomTest, ReadsTheLabelFromBothShapes) {
  const std::string gs =
      R"({"object_meta":{"name":"gs-1","labels":{"sweptccd.dev/room":"arcade-7","x":"y"}},)"
      R"("status":{"state":"Allocated"}})";
  const GameServerRoom get = RoomOfGameServer(gs, false);
  EXPECT_EQ(get.room, "arcade-7");
  EXPECT_EQ(get.problem, "");
  const GameServerRoom watch = RoomOfGameServer(R"({"result":)" + gs + "}", true);
  EXPECT_EQ(watch.room, "arcade-7");
  EXPECT_EQ(watch.problem, "");
  // The GET shape read as a watch line: no "result".
  EXPECT_NE(RoomOfGameServer(gs, true).problem, "");
}

TEST(GameServerRoomTest, NoLabelIsNoRoomAndNoProblem) {
  for (const char* json : {R"({})", R"({"object_meta":{}})", R"({"object_meta":{"labels":null}})",
                           R"({"object_meta":{"labels":{"other":"x"}}})"}) {
    const GameServerRoom r = RoomOfGameServer(json, false);
    EXPECT_EQ(r.room, "") << json;
    EXPECT_EQ(r.problem, "") << json;
  }
}

TEST(GameServerRoomTest, RefusesBadValuesAndShapesEscaped) {
  const GameServerRoom bad = RoomOfGameServer(
      R"({"object_meta":{"labels":{"sweptccd.dev/room":"a\nb\u001b[31m"}}})", false);
  EXPECT_EQ(bad.room, "");
  EXPECT_NE(bad.problem.find("breaks the id rule"), std::string::npos);
  EXPECT_EQ(bad.problem.find('\n'), std::string::npos);
  EXPECT_EQ(bad.problem.find('\x1b'), std::string::npos);
  const std::string too_long(65, 'a');
  EXPECT_NE(RoomOfGameServer(
                R"({"object_meta":{"labels":{"sweptccd.dev/room":")" + too_long + R"("}}})", false)
                .problem,
            "");
  EXPECT_NE(
      RoomOfGameServer(R"({"object_meta":{"labels":{"sweptccd.dev/room":7}}})", false).problem, "");
  EXPECT_NE(RoomOfGameServer(R"({"object_meta":{"labels":[1]}})", false).problem, "");
  EXPECT_NE(RoomOfGameServer("not json\x1b", true).problem, "");
  EXPECT_EQ(RoomOfGameServer("not json\x1b", true).problem.find('\x1b'), std::string::npos);
  EXPECT_NE(RoomOfGameServer(R"([1,2])", false).problem, "");
  EXPECT_NE(RoomOfGameServer(R"({"result":"x"})", true).problem, "");
}

}  // namespace
}  // namespace sweptccd
