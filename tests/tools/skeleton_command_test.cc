// `sweptccd skeleton`: the skeleton of a joint set (read back through the
// SPEC loader), joint frames converted to a pose stream that `query` reads,
// a bad frame written as an invalid pose (its pair reported invalid, the
// others untouched) and one-line refusals of bad options.

#include <gtest/gtest.h>

#include <fstream>
#include <functional>
#include <nlohmann/json.hpp>
#include <sstream>
#include <string>
#include <vector>

#include "core/avatar/joint_frame.h"
#include "core/avatar/joint_set.h"
#include "core/avatar/pose.h"
#include "core/avatar/skeleton.h"
#include "tests/common/random.h"
#include "tests/common/temp_dir_test.h"
#include "tests/tools/run_binary.h"

namespace sweptccd {
namespace {

using nlohmann::json;
using testing::RunResult;

const char* const kBinary = SWEPTCCD_BINARY;

class SkeletonCommandTest : public test::TempDirTest {
 protected:
  SkeletonCommandTest() : TempDirTest("skeleton_cmd") {}
  RunResult Run(const std::vector<std::string>& args) {
    const int n = run_count_++;
    return testing::RunBinary(kBinary, args, Path("run" + std::to_string(n) + ".out"),
                              Path("run" + std::to_string(n) + ".err"), 60);
  }
  // A body standing 1 m above the origin: each joint 2-20 cm from its
  // parent, random orientations.
  static JointFrame Body(const JointSet& set, int64_t utime) {
    testing::Rng rng(99);
    JointFrame f;
    f.utime = utime;
    f.joints.resize(set.num_joints());
    std::vector<bool> done(set.num_joints(), false);
    std::function<void(int)> place = [&](int j) {
      if (done[j]) return;
      const int p = set.joints[j].parent;
      Eigen::Vector3d base(0, 0, 1);
      if (p >= 0) {
        place(p);
        base = f.joints[p].p + rng.U(0.02, 0.2) * rng.Dir();
      }
      f.joints[j].p = base;
      f.joints[j].q = rng.Quat();
      done[j] = true;
    };
    for (int j = 0; j < set.num_joints(); ++j) place(j);
    return f;
  }
  int run_count_ = 0;
};

std::vector<std::string> Lines(const std::string& text) {
  std::vector<std::string> out;
  std::istringstream in(text);
  for (std::string line; std::getline(in, line);) {
    if (!line.empty()) out.push_back(line);
  }
  return out;
}

TEST_F(SkeletonCommandTest, WritesEverySetsSkeleton) {
  for (const std::string& id : JointSetIds()) {
    const std::string out = Path(id + ".json");
    const RunResult r =
        Run({"skeleton", "--from", id, "--hands", "full", "--height", "1.6", "--out", out});
    ASSERT_TRUE(r.exited && r.code == 0) << r.Describe();
    const Skeleton s = LoadSkeletonFile(out);
    EXPECT_EQ(s.num_links(),
              static_cast<int>(PlanLinks(FindJointSet(id), HandsOption::kFull).size()));
  }
}

TEST_F(SkeletonCommandTest, FramesBecomePosesAndABadFrameItsInvalidPair) {
  const JointSet& set = FindJointSet("meta-full-body");
  const JointFrame f0 = Body(set, 1000000);
  std::string frames;
  for (int k = 0; k < 4; ++k) {
    JointFrame f = f0;
    f.utime += k * 8333;
    for (JointSample& s : f.joints) s.p.x() += 0.01 * k;
    if (k == 2)
      f.joints[set.FindJoint("XR_FULL_BODY_JOINT_LEFT_HAND_INDEX_TIP_META")].valid = false;
    frames += JointFrameToJsonLine(f) + "\n";
  }
  const std::string cal = Write("cal.jsonl", JointFrameToJsonLine(f0) + "\n");
  const std::string in = Write("frames.jsonl", frames);
  const std::string skel = Path("skel.json"), poses = Path("poses.jsonl");
  const RunResult r = Run({"skeleton", "--from", "meta-full-body", "--calibrate", cal, "--out",
                           skel, "--joints", in, "--poses-out", poses});
  ASSERT_TRUE(r.exited && r.code == 0) << r.Describe();
  // One warning line, naming the frame's line and the joint.
  const std::vector<std::string> warnings = Lines(r.err);
  ASSERT_EQ(warnings.size(), 1u) << r.err;
  EXPECT_NE(warnings[0].find("line 3: joint 28 (XR_FULL_BODY_JOINT_LEFT_HAND_INDEX_TIP_META): "
                             "not tracked"),
            std::string::npos)
      << warnings[0];
  const Skeleton s = LoadSkeletonFile(skel);
  const std::vector<std::string> lines = Lines(testing::ReadFile(poses));
  ASSERT_EQ(lines.size(), 4u);
  for (int k = 0; k < 4; ++k) {
    std::string error;
    const std::optional<Pose> p = ParsePoseLine(lines[k], s.num_links(), &error);
    EXPECT_EQ(p.has_value(), k != 2) << lines[k];
  }
  // `query` pairs them: pair 1 (the bad frame) invalid, the others free.
  const std::string floor =
      Write("floor.obj", "v -1 -1 -5\nv 1 -1 -5\nv 1 1 -5\nv -1 1 -5\nf 1 2 3 4\n");
  const RunResult q = Run({"query", "--skeleton", skel, "--poses", poses, "--env", floor});
  ASSERT_TRUE(q.exited && q.code == 0) << q.Describe();
  const std::vector<std::string> records = Lines(q.out);
  ASSERT_EQ(records.size(), 3u) << q.out;
  EXPECT_EQ(json::parse(records[0])["result"], "free");
  EXPECT_EQ(json::parse(records[1])["result"], "invalid");
  EXPECT_EQ(json::parse(records[2])["result"], "free");
  EXPECT_EQ(json::parse(records[2])["utime0"], 1008333);
}

TEST_F(SkeletonCommandTest, BadOptionsAreRefusedInOneLine) {
  const std::string out = Path("s.json");
  const std::string bad_cal = Write("bad.jsonl", "{\"utime\": 1, \"joints\": []}\n");
  const std::vector<std::vector<std::string>> cases = {
      {"skeleton", "--from", "kinect", "--out", out},
      {"skeleton", "--from", "ext-hand", "--hands", "none", "--out", out},
      {"skeleton", "--from", "bd-body", "--height", "7", "--out", out},
      {"skeleton", "--from", "bd-body"},
      {"skeleton", "--from", "bd-body", "--joints", bad_cal},
      {"skeleton", "--from", "bd-body", "--calibrate", bad_cal, "--out", out},
  };
  for (const auto& args : cases) {
    const RunResult r = Run(args);
    EXPECT_TRUE(r.exited && r.code == 2) << r.Describe();
    EXPECT_EQ(Lines(r.err).size(), 1u) << r.err;
  }
}

}  // namespace
}  // namespace sweptccd
