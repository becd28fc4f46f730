// TrackerPoseOf / TrackerPoseOfLine, the one conversion of a pose to a
// tracker message: every number as it is, in link order, bit for bit.
#include "sweptccd_client/tracker_pose.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstring>

#include "core/errors.h"

namespace sweptccd {
namespace {

bool SameBits(double a, double b) { return std::memcmp(&a, &b, sizeof(double)) == 0; }

TEST(TrackerPoseTest, EveryNumberAsItIsInLinkOrder) {
  const tracker_pose_t m = TrackerPoseOfLine(
      R"({"utime": 9223372036854775807, "links": [[0.1, -0.0, 1e-300, 2, 0, 0, 0],
                                                     [1, 2, 3, 0.5, -0.5, 0.25, -0.0]]})");
  EXPECT_EQ(m.utime, INT64_MAX);
  EXPECT_EQ(m.num_links, 2);
  ASSERT_EQ(m.position.size(), 2u);
  ASSERT_EQ(m.orientation.size(), 2u);
  EXPECT_TRUE(SameBits(m.position[0][0], 0.1));
  EXPECT_TRUE(SameBits(m.position[0][1], -0.0));  // Not 0.0.
  EXPECT_TRUE(SameBits(m.position[0][2], 1e-300));
  EXPECT_EQ(m.orientation[0], (std::vector<double>{2, 0, 0, 0}));  // Not normalised.
  EXPECT_EQ(m.position[1], (std::vector<double>{1, 2, 3}));
  EXPECT_TRUE(SameBits(m.orientation[1][3], -0.0));
  EXPECT_EQ(m.orientation[1][1], -0.5);  // [w x y z].
  EXPECT_EQ(m.client_id, "");
  EXPECT_EQ(m.session, 0);
  EXPECT_EQ(m.seq, 0);
  for (uint8_t b : m.mac) EXPECT_EQ(b, 0);
  EXPECT_THROW(TrackerPoseOfLine(R"({"utime": 1, "links": []})"), InputError);
  EXPECT_THROW(TrackerPoseOfLine("garbage"), InputError);
}

TEST(TrackerPoseTest, AnOffsetMovesEveryPosition) {
  Pose p;
  p.utime = 7;
  p.links.push_back(LinkPose{Eigen::Vector3d(1, -0.0, 3), Eigen::Quaterniond(0, 1, 0, 0)});
  const tracker_pose_t as_is = TrackerPoseOf(p);
  EXPECT_TRUE(SameBits(as_is.position[0][1], -0.0));
  const tracker_pose_t moved = TrackerPoseOf(p, Eigen::Vector3d(10, 0, -3));
  EXPECT_EQ(moved.position[0], (std::vector<double>{11, 0, 0}));
  EXPECT_EQ(moved.orientation[0], (std::vector<double>{0, 1, 0, 0}));
  EXPECT_EQ(moved.utime, 7);
}

}  // namespace
}  // namespace sweptccd
