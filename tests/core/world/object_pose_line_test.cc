// Tracked-object pose lines and pose lines read a utime by one rule
// (ReadUtime: an integral value in the int64 range), and `sweptccd world`
// and `simulate-tracker --object` read object pose files by one reader
// (ReadObjectPoseFile). Before, the object reader refused floats from 9e18,
// the pose reader from 9.2e18, and the object reader took 2^64 - 1 as -1.
#include <gtest/gtest.h>

#include <optional>
#include <string>
#include <vector>

#include "core/avatar/pose.h"
#include "core/errors.h"
#include "core/utime_json.h"
#include "core/world/world_file.h"
#include "tests/common/temp_dir_test.h"

namespace sweptccd {
namespace {

std::optional<int64_t> PoseLineUtime(const std::string& utime) {
  std::string error;
  const std::optional<Pose> pose = ParsePoseLineAsWritten(
      R"({"utime": )" + utime + R"(, "links": [[0, 0, 0, 1, 0, 0, 0]]})", 1, &error);
  if (!pose) return std::nullopt;
  return pose->utime;
}

std::optional<int64_t> ObjectLineUtime(const std::string& utime) {
  world::RigidSample x;
  std::string error;
  if (!world::ParseObjectPoseLine(R"({"utime": )" + utime + R"(, "pose": [0, 0, 0, 1, 0, 0, 0]})",
                                  &x, &error)) {
    return std::nullopt;
  }
  return x.utime;
}

TEST(ObjectPoseLineTest, BothReadersTakeTheInt64RangeAndNothingElse) {
  struct Case {
    const char* utime;
    std::optional<int64_t> want;
  };
  const Case cases[] = {
      {"1000000", 1000000},
      {"1000000.0", 1000000},
      {"1e6", 1000000},
      {"-5", -5},
      {"9223372036854775807", INT64_MAX},
      {"-9223372036854775808", INT64_MIN},
      // Floats at the boundary: 9.1e18 (the object reader refused it),
      // 9.21e18 (both refused it), -2^63 (both refused it) are in range.
      {"9.1e18", int64_t{9100000000000000000}},
      {"9.21e18", int64_t{9210000000000000000}},
      {"9223372036854774784.0", int64_t{9223372036854774784}},  // 2^63 - 1024.
      {"-9223372036854775808.0", INT64_MIN},
      {"9223372036854775808.0", std::nullopt},   // 2^63: past INT64_MAX.
      {"-9223372036854777856.0", std::nullopt},  // -2^63 - 2048.
      {"1e19", std::nullopt},
      {"9223372036854775808", std::nullopt},   // INT64_MAX + 1 as an integer.
      {"18446744073709551615", std::nullopt},  // 2^64 - 1 (the object reader took -1).
      {"1000000.5", std::nullopt},
      {"\"1000000\"", std::nullopt},
      {"null", std::nullopt},
  };
  for (const Case& c : cases) {
    EXPECT_EQ(PoseLineUtime(c.utime), c.want) << "pose line utime " << c.utime;
    EXPECT_EQ(ObjectLineUtime(c.utime), c.want) << "object line utime " << c.utime;
    int64_t got = 0;
    const nlohmann::json j = nlohmann::json::parse(c.utime);
    EXPECT_EQ(ReadUtime(j, &got), c.want.has_value()) << c.utime;
    if (c.want) EXPECT_EQ(got, *c.want) << c.utime;
  }
}

class ObjectPoseFileTest : public test::TempDirTest {
 protected:
  ObjectPoseFileTest() : TempDirTest("object_pose_file") {}
};

// Blank lines are not counted; malformed, unusable and too long lines are
// counted and skipped; every usable line comes in file order (not checked
// for increasing utime: the world file keeps the increasing ones, the
// tracker simulator publishes every one).
TEST_F(ObjectPoseFileTest, OneReaderForEveryObjectPoseFile) {
  const std::string pad(world::kMaxObjectPoseLineBytes, ' ');
  const std::string path =
      Write("cup.jsonl",
            "{\"utime\": 10, \"pose\": [1, 2, 3, 1, 0, 0, 0]}\n"
            "\n   \t\n"
            "{\"utime\": 5, \"pose\": [0, 0, 0, 0, 0, 0, 2]}\n"   // Earlier: still given.
            "{\"utime\": 20, \"pose\": [0, 0, 0, 0, 0, 0, 0]}\n"  // Zero quaternion.
            "not json\n"
            "{\"utime\": 30," +
                pad +
                "\"pose\": [0, 0, 0, 1, 0, 0, 0]}\n"  // Too long.
                "{\"utime\": 18446744073709551615, \"pose\": [0, 0, 0, 1, 0, 0, 0]}\n"
                "{\"utime\": 9.21e18, \"pose\": [0, 0, 0, 1, 0, 0, 0]}");  // No newline.
  std::vector<world::RigidSample> got;
  const int64_t unusable = world::ReadObjectPoseFile(
      path, "object pose file", [&](const world::RigidSample& x) { got.push_back(x); });
  EXPECT_EQ(unusable, 4);
  ASSERT_EQ(got.size(), 3u);
  EXPECT_EQ(got[0].utime, 10);
  EXPECT_EQ(got[0].p.x(), 1);
  EXPECT_EQ(got[1].utime, 5);
  EXPECT_EQ(got[1].q.z(), 1);  // Normalised.
  EXPECT_EQ(got[2].utime, int64_t{9210000000000000000});

  // The world file keeps the increasing ones: 10 and 9.21e18.
  Write("world.json", R"({"objects": [{"id": "cup", "mesh": "cup.obj", "poses": "cup.jsonl"}]})");
  Write("cup.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n");
  const world::LoadedWorld w = world::LoadWorldFile(Path("world.json"));
  ASSERT_EQ(w.world.objects.size(), 1u);
  ASSERT_EQ(w.world.objects[0].used.size(), 2u);
  EXPECT_EQ(w.world.objects[0].used[0].utime, 10);
  EXPECT_EQ(w.world.objects[0].used[1].utime, int64_t{9210000000000000000});

  EXPECT_THROW(world::ReadObjectPoseFile(Path("none.jsonl"), "object pose file",
                                         [](const world::RigidSample&) {}),
               InputError);
}

}  // namespace
}  // namespace sweptccd
