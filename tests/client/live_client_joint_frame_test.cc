// LiveClient::PublishJointFrame: a joint frame is converted by the core rule
// (JointSkeleton::Convert) and published as the link pose; a bad frame
// publishes nothing. Published through LCM's file:// provider (a log, no
// network) and read back.

#include <gtest/gtest.h>
#include <unistd.h>

#include <cmath>
#include <cstdio>
#include <filesystem>
#include <lcm/lcm-cpp.hpp>
#include <limits>
#include <string>
#include <vector>

#include "core/avatar/joint_frame.h"
#include "core/avatar/joint_set.h"
#include "sweptccd/tracker_pose_t.hpp"
#include "sweptccd_client/live_client.h"
#include "tests/common/random.h"

namespace sweptccd {
namespace {

// A hand frame: joints along chains from the wrist, random orientations.
JointFrame HandFrame(const JointSet& set, testing::Rng* rng, int64_t utime) {
  JointFrame f;
  f.utime = utime;
  f.joints.resize(set.num_joints());
  std::vector<bool> done(set.num_joints(), false);
  std::function<void(int)> place = [&](int j) {
    if (done[j]) return;
    const int p = set.joints[j].parent;
    Eigen::Vector3d base(0.2, 1.0, 0.3);
    if (p >= 0) {
      place(p);
      base = f.joints[p].p + rng->U(0.01, 0.05) * rng->Dir();
    }
    f.joints[j].p = base;
    f.joints[j].q = rng->Quat();
    done[j] = true;
  };
  for (int j = 0; j < set.num_joints(); ++j) place(j);
  return f;
}

TEST(LiveClientJointFrameTest, PublishesTheConvertedPoseAndRefusesBadFrames) {
  const std::string log_path = (std::filesystem::temp_directory_path() /
                                ("sweptccd_joint_frame_" + std::to_string(getpid()) + ".lcmlog"))
                                   .string();
  const JointSet& set = FindJointSet("webxr-hand");
  testing::Rng rng(11);
  const JointFrame cal = HandFrame(set, &rng, 1000);
  JointSkeletonOptions so;
  so.calibration = &cal;
  const JointSkeleton js = JointSkeleton::Build(set, so);
  Pose expected;
  ASSERT_EQ(js.Convert(cal, &expected), "");
  {
    LiveClient::Options o;
    o.lcm_url = "file://" + log_path + "?mode=w";
    o.client_id = "hand";
    o.join = false;  // A configured client: no join over a log.
    o.session = 7;
    o.skeleton = js.skeleton();
    LiveClient client(o);
    ASSERT_TRUE(client.Join().ok());
    EXPECT_EQ(client.PublishJointFrame(js, cal, 1), "");
    JointFrame bad = cal;
    bad.joints[3].valid = false;
    EXPECT_NE(client.PublishJointFrame(js, bad, 2).find("not tracked"), std::string::npos);
    bad = cal;
    bad.joints[9].p.z() = std::numeric_limits<double>::quiet_NaN();
    EXPECT_NE(client.PublishJointFrame(js, bad, 3).find("non-finite"), std::string::npos);
    bad = cal;
    bad.joints.pop_back();
    EXPECT_NE(client.PublishJointFrame(js, bad, 4).find("expected 25 joints"), std::string::npos);
    // A skeleton other than the joined one is refused.
    JointSkeletonOptions simple = so;
    simple.hands = HandsOption::kSimple;
    EXPECT_NE(client.PublishJointFrame(JointSkeleton::Build(set, simple), cal, 5)
                  .find("links, this client joined with"),
              std::string::npos);
  }
  lcm::LogFile log(log_path, "r");
  ASSERT_TRUE(log.good());
  std::vector<tracker_pose_t> poses;
  while (const lcm::LogEvent* ev = log.readNextEvent()) {
    tracker_pose_t m;
    if (ev->channel != kPoseChannel) continue;
    ASSERT_GE(m.decode(ev->data, 0, ev->datalen), 0);
    poses.push_back(m);
  }
  std::remove(log_path.c_str());
  ASSERT_EQ(poses.size(), 1u);  // Only the good frame.
  const tracker_pose_t& m = poses[0];
  EXPECT_EQ(m.utime, 1000);
  EXPECT_EQ(m.seq, 1);
  EXPECT_EQ(m.client_id, "hand");
  ASSERT_EQ(m.num_links, js.skeleton().num_links());
  for (int i = 0; i < m.num_links; ++i) {
    for (int k = 0; k < 3; ++k) EXPECT_EQ(m.position[i][k], expected.links[i].p[k]);
    EXPECT_EQ(m.orientation[i][0], expected.links[i].q.w());
    EXPECT_EQ(m.orientation[i][1], expected.links[i].q.x());
  }
}

}  // namespace
}  // namespace sweptccd
