#include "mocap/mocap_import.h"

#include <gtest/gtest.h>
#include <unistd.h>

#include <Eigen/Geometry>
#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <random>
#include <sstream>
#include <string>
#include <utility>
#include <vector>

#include "core/avatar/motion.h"
#include "core/avatar/pose.h"
#include "core/avatar/skeleton.h"
#include "core/errors.h"
#include "core/geometry/mesh.h"

namespace sweptccd {
namespace {

namespace fs = std::filesystem;

const std::string kMocapDir = std::string(SWEPTCCD_DATA_DIR) + "/mocap";

std::string ClipPath(const std::string& file) { return kMocapDir + "/" + file; }

std::vector<std::string> ListClips() {
  std::vector<std::string> clips;
  std::error_code ec;
  for (const fs::directory_entry& entry : fs::directory_iterator(kMocapDir, ec)) {
    const std::string name = entry.path().filename().string();
    const bool bvh = name.size() > 4 && name.compare(name.size() - 4, 4, ".bvh") == 0;
    const bool bvh_gz = name.size() > 7 && name.compare(name.size() - 7, 7, ".bvh.gz") == 0;
    if (entry.is_regular_file() && (bvh || bvh_gz)) {
      clips.push_back(entry.path().string());
    }
  }
  std::sort(clips.begin(), clips.end());
  return clips;
}

// The file's text, gunzipped when it is gzip (the shipped clips are).
std::string ReadText(const std::string& path) { return ReadFileMaybeGzip(path); }

int IndexOfLink(const MocapClip& clip, const std::string& name) {
  const int i = clip.skeleton.FindLink(name);
  EXPECT_GE(i, 0) << name;
  return i;
}

Eigen::Vector3d WorldA(const MocapClip& clip, const Pose& pose, int i) {
  return pose.links[i].p + pose.links[i].q * clip.skeleton.link(i).a_L;
}

Eigen::Vector3d WorldB(const MocapClip& clip, const Pose& pose, int i) {
  return pose.links[i].p + pose.links[i].q * clip.skeleton.link(i).b_L;
}

// Max minus min of every segment end point along world axis `axis`.
double Extent(const MocapClip& clip, const Pose& pose, int axis) {
  double lo = 1e300, hi = -1e300;
  for (int i = 0; i < clip.skeleton.num_links(); ++i) {
    for (const Eigen::Vector3d& e : {WorldA(clip, pose, i), WorldB(clip, pose, i)}) {
      lo = std::min(lo, e[axis]);
      hi = std::max(hi, e[axis]);
    }
  }
  return hi - lo;
}

// (parent, child) links where the child's joint is the direct BVH child whose
// OFFSET is the parent's b: the child's A end is the parent's B end.
const std::vector<std::pair<std::string, std::string>> kConnected = {
    {"pelvis", "spine"},          {"spine", "chest"},      {"thigh_l", "shin_l"},
    {"shin_l", "foot_l"},         {"thigh_r", "shin_r"},   {"shin_r", "foot_r"},
    {"upper_arm_l", "forearm_l"}, {"forearm_l", "hand_l"}, {"upper_arm_r", "forearm_r"},
    {"forearm_r", "hand_r"},
};

// Suite names are lower case with "mocap" so that `ctest -R mocap` selects
// every test of this file (ctest's regex is case-sensitive).

TEST(mocap_import, MocapFolderHasClips) {
  ASSERT_TRUE(fs::is_directory(kMocapDir)) << kMocapDir << " is missing";
  EXPECT_FALSE(ListClips().empty()) << "no .bvh or .bvh.gz file in " << kMocapDir;
}

TEST(mocap_import, LinkNames) {
  const std::vector<std::string> expected = {"pelvis",      "spine",     "chest",   "head",
                                             "upper_arm_l", "forearm_l", "hand_l",  "upper_arm_r",
                                             "forearm_r",   "hand_r",    "thigh_l", "shin_l",
                                             "foot_l",      "thigh_r",   "shin_r",  "foot_r"};
  EXPECT_EQ(MocapLinkNames(), expected);
  EXPECT_EQ(kMocapNumLinks, 16);
}

// Every clip of the data folder imports into a plausible, connected avatar.
class mocap_every_clip : public ::testing::TestWithParam<std::string> {};

TEST_P(mocap_every_clip, ImportsPlausibleConnectedAvatar) {
  const std::string path = GetParam();
  const MocapClip clip = ImportBvhFile(path);
  const Skeleton& skel = clip.skeleton;
  ASSERT_EQ(skel.num_links(), 16);
  ASSERT_EQ(clip.source_joints.size(), 16u);
  for (int i = 0; i < 16; ++i) EXPECT_EQ(skel.link(i).name, MocapLinkNames()[i]);
  // The skeleton validates, also after a round trip through the SPEC JSON.
  const Skeleton reparsed = ParseSkeletonJson(SkeletonToJson(skel), path);
  EXPECT_EQ(reparsed.num_links(), 16);
  EXPECT_EQ(skel.link(skel.root()).name, "pelvis");
  ASSERT_FALSE(clip.poses.empty());
  EXPECT_GT(clip.frame_time_s, 0);
  EXPECT_GT(clip.unit_scale_m, 0);

  // Every pose: 16 finite links, unit quaternions, sign continuity, utime.
  double worst_norm = 0, worst_dot = 1;
  for (size_t k = 0; k < clip.poses.size(); ++k) {
    const Pose& pose = clip.poses[k];
    ASSERT_EQ(pose.links.size(), 16u);
    EXPECT_EQ(pose.utime, std::llround(static_cast<double>(k) * clip.frame_time_s * 1e6));
    for (int i = 0; i < 16; ++i) {
      ASSERT_TRUE(pose.links[i].p.allFinite() && pose.links[i].q.coeffs().allFinite());
      worst_norm = std::max(worst_norm, std::abs(pose.links[i].q.norm() - 1));
      if (k > 0) {
        worst_dot = std::min(worst_dot, clip.poses[k - 1].links[i].q.dot(pose.links[i].q));
      }
    }
    Pose copy = pose;
    EXPECT_EQ(ValidateAndNormalizePose(&copy, 16), "");
  }
  EXPECT_LT(worst_norm, 1e-12);
  EXPECT_GE(worst_dot, 0);

  // Height of the first pose along the up axis (y).
  const double height = Extent(clip, clip.poses.front(), 1);
  EXPECT_GE(height, 1.3);
  EXPECT_LE(height, 2.1);

  // Connectivity in every frame and halfway between consecutive frames.
  double worst_frame = 0, worst_mid = 0;
  for (size_t k = 0; k < clip.poses.size(); ++k) {
    for (const auto& [parent, child] : kConnected) {
      const int p = IndexOfLink(clip, parent), c = IndexOfLink(clip, child);
      ASSERT_EQ(skel.link(c).parent, p);
      worst_frame = std::max(
          worst_frame, (WorldA(clip, clip.poses[k], c) - WorldB(clip, clip.poses[k], p)).norm());
    }
    if (k + 1 < clip.poses.size()) {
      const PairMotion motion(skel, clip.poses[k], clip.poses[k + 1], MotionModel::kArticulated);
      for (const auto& [parent, child] : kConnected) {
        const LinkIndex p(IndexOfLink(clip, parent)), c(IndexOfLink(clip, child));
        Eigen::Vector3d pa, pb, ca, cb;
        motion.SegmentAt(p, 0.5, &pa, &pb);
        motion.SegmentAt(c, 0.5, &ca, &cb);
        worst_mid = std::max(worst_mid, (ca - pb).norm());
      }
    }
  }
  EXPECT_LT(worst_frame, 1e-6);
  EXPECT_LT(worst_mid, 1e-6);

  std::string joints;
  for (const std::string& j : clip.source_joints) joints += (joints.empty() ? "" : " ") + j;
  std::printf("%-48s frames %5zu  unit %.5f m  height %.3f m  dt %.6f s\n  joints: %s\n",
              fs::path(path).filename().c_str(), clip.poses.size(), clip.unit_scale_m, height,
              clip.frame_time_s, joints.c_str());
  RecordProperty("height_m", std::to_string(height));
}

std::string ClipTestName(const ::testing::TestParamInfo<std::string>& info) {
  fs::path file = fs::path(info.param).filename();
  if (file.extension() == ".gz") file = file.stem();
  std::string name = file.stem().string();
  for (char& c : name) {
    if (!std::isalnum(static_cast<unsigned char>(c))) c = '_';
  }
  return name;
}

INSTANTIATE_TEST_SUITE_P(RealData, mocap_every_clip, ::testing::ValuesIn(ListClips()),
                         ClipTestName);
GTEST_ALLOW_UNINSTANTIATED_PARAMETERIZED_TEST(mocap_every_clip);  // MocapFolderHasClips fails then.

// The joint each link follows, per naming convention, and the start frame and
// unit detection.
TEST(mocap_import, JointMappingPerConvention) {
  struct Case {
    const char* file;
    int frames_in_file;
    int first_frame;
    double unit;
    std::vector<std::string> joints;
  };
  const std::vector<Case> cases = {
      {"boxing_toes.bvh.gz",
       3069,
       0,
       0.01,
       {"Hips", "Ab", "Chest", "Head", "LeftShoulder", "LeftElbow", "LeftWrist", "RightShoulder",
        "RightElbow", "RightWrist", "LeftHip", "LeftKnee", "LeftAnkle", "RightHip", "RightKnee",
        "RightAnkle"}},
      {"cmu_01_01_playground_forward_jumps.bvh.gz",
       2752,
       1,
       0.05644,
       {"LowerBack", "Spine", "Neck", "Head", "LeftArm", "LeftForeArm", "LeftHand", "RightArm",
        "RightForeArm", "RightHand", "LeftUpLeg", "LeftLeg", "LeftFoot", "RightUpLeg", "RightLeg",
        "RightFoot"}},
      {"cmu_05_06_dance_cartwheel_pirouettes_jete.bvh.gz",
       885,
       0,
       0.05644,
       {"LowerBack", "Spine", "Neck", "Head", "LeftArm", "LeftForeArm", "LeftHand", "RightArm",
        "RightForeArm", "RightHand", "LeftUpLeg", "LeftLeg", "LeftFoot", "RightUpLeg", "RightLeg",
        "RightFoot"}},
      {"cmu_02_01_walk.bvh.gz",
       344,
       1,
       0.01,
       {"hip", "abdomen", "chest", "head", "lShldr", "lForeArm", "lHand", "rShldr", "rForeArm",
        "rHand", "lThigh", "lShin", "lFoot", "rThigh", "rShin", "rFoot"}},
  };
  for (const Case& c : cases) {
    SCOPED_TRACE(c.file);
    const MocapClip clip = ImportBvhFile(ClipPath(c.file));
    EXPECT_EQ(clip.source_joints, c.joints);
    EXPECT_EQ(clip.poses.size(), static_cast<size_t>(c.frames_in_file - c.first_frame));
    EXPECT_DOUBLE_EQ(clip.unit_scale_m, c.unit);
  }
}

// Hand-checked pose: cmu_02_01_walk.bvh (Daz/Poser names, centimetres), frame
// 1 (the first kept frame, frame 0 being the reference T-pose).
//
// Frame 1 channels used (file order):
//   hip      Xposition Yposition Zposition = 55.6924 84.8974 -160.488
//            Zrotation Yrotation Xrotation = -3.0091 -9.8219 -2.4897
//   lButtock Zrotation Xrotation Yrotation = 2.03e-16 0.0 3.88e-19   (identity)
//   lThigh   Zrotation Xrotation Yrotation = -0.20719 -10.0437 0.0626843
// OFFSETs: lButtock (8.77824, 4.35084, 1.2192), lThigh (0, -1.70687, -2.19456),
//          lShin (0, -36.8199, 0.73152).
// cos/sin: -2.4897 deg: 0.999056/-0.043440; -9.8219: 0.985343/-0.170586;
//          -3.0091: 0.998621/-0.052495; -10.0437: 0.984675/-0.174399;
//          -0.20719: 0.999993/-0.003616; 0.0626843: 0.999999/0.001094.
//
// Root (pelvis link origin) = hip position * 0.01 = (0.556924, 0.848974, -1.60488) m.
//
// Left knee (lShin joint) = p_hip + R_hip (o_lButtock + o_lThigh + R_lThigh o_lShin),
// R_hip = Rz(-3.0091) Ry(-9.8219) Rx(-2.4897), R_lThigh = Rz(-0.20719) Rx(-10.0437) Ry(0.0626843):
//   Ry(0.0626843) o_lShin: x = 0.001094*0.73152 = 0.000800 -> (0.000800, -36.819900, 0.731520)
//   Rx(-10.0437):  y = 0.984675*-36.8199 - (-0.174399)*0.73152 = -36.128059
//                  z = -0.174399*-36.8199 + 0.984675*0.73152   =   7.141672
//   Rz(-0.20719):  x = 0.999993*0.000800 - (-0.003616)*-36.128059 = -0.129844
//                  y = -0.003616*0.000800 + 0.999993*-36.128059  = -36.127826
//   + o_lButtock + o_lThigh = (8.778240, 2.643970, -0.975360) -> (8.648396, -33.483856, 6.166312)
//   Rx(-2.4897):   y = 0.999056*-33.483856 - (-0.043440)*6.166312 = -33.184386
//                  z = -0.043440*-33.483856 + 0.999056*6.166312   =   7.615023
//   Ry(-9.8219):   x = 0.985343*8.648396 + (-0.170586)*7.615023   =   7.222617
//                  z = -(-0.170586)*8.648396 + 0.985343*7.615023  =   8.978704
//   Rz(-3.0091):   x = 0.998621*7.222617 - (-0.052495)*-33.184386 =   5.470659
//                  y = -0.052495*7.222617 + 0.998621*-33.184386   = -33.517779
//   + p_hip -> (61.163059, 51.379621, -151.509296) cm = (0.61163059, 0.51379621, -1.51509296) m.
// The left hip (lThigh joint) is p_hip + R_hip (o_lButtock + o_lThigh)
//   = (64.652050, 87.029111, -160.063881) cm.
TEST(mocap_import, HandCheckedPoseCmu0201Frame1) {
  const MocapClip clip = ImportBvhFile(ClipPath("cmu_02_01_walk.bvh.gz"));
  MocapImportOptions explicit_start;
  explicit_start.start_frame = 1;
  explicit_start.frame_count = 2;
  const MocapClip same = ImportBvhFile(ClipPath("cmu_02_01_walk.bvh.gz"), explicit_start);
  ASSERT_EQ(same.poses.size(), 2u);
  const Pose& pose = clip.poses[0];
  EXPECT_EQ(pose.utime, 0);
  for (int i = 0; i < 16; ++i) {
    EXPECT_EQ(pose.links[i].p, same.poses[0].links[i].p);
  }
  const double tol = 2e-6;  // The hand arithmetic carries 6 decimals in cm.
  const int pelvis = IndexOfLink(clip, "pelvis");
  EXPECT_NEAR(pose.links[pelvis].p.x(), 0.556924, 1e-12);
  EXPECT_NEAR(pose.links[pelvis].p.y(), 0.848974, 1e-12);
  EXPECT_NEAR(pose.links[pelvis].p.z(), -1.60488, 1e-12);
  const int thigh = IndexOfLink(clip, "thigh_l");
  const int shin = IndexOfLink(clip, "shin_l");
  EXPECT_NEAR(pose.links[thigh].p.x(), 0.64652050, tol);
  EXPECT_NEAR(pose.links[thigh].p.y(), 0.87029111, tol);
  EXPECT_NEAR(pose.links[thigh].p.z(), -1.60063881, tol);
  EXPECT_NEAR(pose.links[shin].p.x(), 0.61163059, tol);
  EXPECT_NEAR(pose.links[shin].p.y(), 0.51379621, tol);
  EXPECT_NEAR(pose.links[shin].p.z(), -1.51509296, tol);
  // b of the thigh is the lShin OFFSET in metres.
  EXPECT_TRUE(clip.skeleton.link(thigh).b_L.isApprox(Eigen::Vector3d(0, -0.368199, 0.0073152)));
  // The pelvis orientation is R_hip = Rz Ry Rx.
  const double d = M_PI / 180;
  const Eigen::Quaterniond q_hip = Eigen::AngleAxisd(-3.0091 * d, Eigen::Vector3d::UnitZ()) *
                                   Eigen::AngleAxisd(-9.8219 * d, Eigen::Vector3d::UnitY()) *
                                   Eigen::AngleAxisd(-2.4897 * d, Eigen::Vector3d::UnitX());
  EXPECT_NEAR(std::abs(pose.links[pelvis].q.dot(q_hip)), 1.0, 1e-12);
}

// 05_06 has every End Site at 0 0 0: hands and head get fixed lengths along
// the bone that ends at their joint (LeftHand OFFSET is along +x, Head's is
// (0.10407, 1.76136, -0.12397)).
TEST(mocap_import, ZeroEndSitesGetFixedLengths) {
  const MocapClip clip =
      ImportBvhFile(ClipPath("cmu_05_06_dance_cartwheel_pirouettes_jete.bvh.gz"));
  EXPECT_TRUE(
      clip.skeleton.link(IndexOfLink(clip, "hand_l")).b_L.isApprox(Eigen::Vector3d(0.08, 0, 0)));
  EXPECT_TRUE(
      clip.skeleton.link(IndexOfLink(clip, "hand_r")).b_L.isApprox(Eigen::Vector3d(-0.08, 0, 0)));
  EXPECT_TRUE(clip.skeleton.link(IndexOfLink(clip, "head"))
                  .b_L.isApprox(0.15 * Eigen::Vector3d(0.10407, 1.76136, -0.12397).normalized()));
  for (int i = 0; i < 16; ++i) {
    EXPECT_GT(clip.skeleton.link(i).b_L.norm(), 0.05) << clip.skeleton.link(i).name;
  }
}

// The extra frame line of boxing_toes.bvh is ignored; its frame 0 is kept.
TEST(mocap_import, ReadsExactlyTheAnnouncedFrames) {
  const MocapClip clip = ImportBvhFile(ClipPath("boxing_toes.bvh.gz"));
  EXPECT_EQ(clip.poses.size(), 3069u);
  EXPECT_DOUBLE_EQ(clip.frame_time_s, 0.01);
  EXPECT_EQ(clip.poses.back().utime, 3068 * 10000);
}

TEST(mocap_import, UpAxisZ) {
  MocapImportOptions y_up;
  y_up.frame_count = 40;
  MocapImportOptions z_up = y_up;
  z_up.up_axis = 'z';
  const MocapClip a = ImportBvhFile(ClipPath("cmu_02_01_walk.bvh.gz"), y_up);
  const MocapClip b = ImportBvhFile(ClipPath("cmu_02_01_walk.bvh.gz"), z_up);
  ASSERT_EQ(a.poses.size(), 40u);
  ASSERT_EQ(b.poses.size(), 40u);
  Eigen::Matrix3d C;
  C << 1, 0, 0, 0, 0, -1, 0, 1, 0;
  for (size_t k = 0; k < a.poses.size(); ++k) {
    for (int i = 0; i < 16; ++i) {
      EXPECT_TRUE((C * a.poses[k].links[i].p - b.poses[k].links[i].p).norm() < 1e-12);
      const Eigen::Matrix3d R = C * a.poses[k].links[i].q.toRotationMatrix();
      EXPECT_TRUE(R.isApprox(b.poses[k].links[i].q.toRotationMatrix(), 1e-12));
    }
  }
  const double height_z = Extent(b, b.poses.front(), 2);
  EXPECT_NEAR(height_z, Extent(a, a.poses.front(), 1), 1e-9);
  EXPECT_GE(height_z, 1.3);
  EXPECT_LE(height_z, 2.1);
  // Along the new y the avatar is not tall.
  EXPECT_LT(Extent(b, b.poses.front(), 1), 1.0);
  MocapImportOptions upper = z_up;
  upper.up_axis = 'Z';
  EXPECT_EQ(ImportBvhFile(ClipPath("cmu_02_01_walk.bvh.gz"), upper).poses[3].links[5].p,
            b.poses[3].links[5].p);
}

TEST(mocap_import, FrameStepSubsamples) {
  const MocapClip full = ImportBvhFile(ClipPath("cmu_13_41_jump.bvh.gz"));
  MocapImportOptions options;
  options.frame_step = 3;
  const MocapClip sub = ImportBvhFile(ClipPath("cmu_13_41_jump.bvh.gz"), options);
  ASSERT_EQ(sub.poses.size(), (full.poses.size() + 2) / 3);
  EXPECT_DOUBLE_EQ(sub.frame_time_s, 3 * full.frame_time_s);
  for (size_t k = 0; k < sub.poses.size(); ++k) {
    EXPECT_EQ(sub.poses[k].utime, std::llround(k * 3 * full.frame_time_s * 1e6));
    for (int i = 0; i < 16; ++i) {
      EXPECT_EQ(sub.poses[k].links[i].p, full.poses[3 * k].links[i].p);
      // Same rotation; the sign may differ (continuity is kept per stream).
      EXPECT_NEAR(std::abs(sub.poses[k].links[i].q.dot(full.poses[3 * k].links[i].q)), 1.0, 1e-12);
    }
  }
  // Start and count select a window before subsampling.
  options.start_frame = 10;
  options.frame_count = 7;
  const MocapClip window = ImportBvhFile(ClipPath("cmu_13_41_jump.bvh.gz"), options);
  ASSERT_EQ(window.poses.size(), 3u);                                // File frames 10, 13, 16.
  EXPECT_EQ(window.poses[2].links[0].p, full.poses[15].links[0].p);  // full starts at frame 1.
  EXPECT_EQ(window.poses[0].utime, 0);
}

TEST(mocap_import, StartFrameZeroKeepsTheReferencePose) {
  MocapImportOptions options;
  options.start_frame = 0;
  const MocapClip clip = ImportBvhFile(ClipPath("cmu_02_01_walk.bvh.gz"), options);
  EXPECT_EQ(clip.poses.size(), 344u);
  // Frame 0: root rotation 0 -> the pelvis frame is the identity.
  EXPECT_NEAR(std::abs(clip.poses[0].links[0].q.w()), 1.0, 1e-12);
}

TEST(mocap_import, RadiusOverrideAndTranslate) {
  MocapImportOptions options;
  options.radius_override_m["head"] = 0.12;
  options.radius_override_m["foot_l"] = 0.03;
  options.frame_count = 5;
  MocapClip clip = ImportBvhFile(ClipPath("cmu_07_01_walk.bvh.gz"), options);
  EXPECT_EQ(clip.skeleton.link(IndexOfLink(clip, "head")).radius, 0.12);
  EXPECT_EQ(clip.skeleton.link(IndexOfLink(clip, "foot_l")).radius, 0.03);
  EXPECT_EQ(clip.skeleton.link(IndexOfLink(clip, "foot_r")).radius, 0.045);
  EXPECT_EQ(clip.skeleton.link(IndexOfLink(clip, "pelvis")).radius, 0.12);
  const MocapClip before = clip;
  const Eigen::Vector3d offset(1.5, -2.0, 0.25);
  TranslateClip(&clip, offset);
  for (size_t k = 0; k < clip.poses.size(); ++k) {
    for (int i = 0; i < 16; ++i) {
      EXPECT_TRUE((clip.poses[k].links[i].p - before.poses[k].links[i].p - offset).norm() < 1e-12);
      EXPECT_EQ(clip.poses[k].links[i].q.coeffs(), before.poses[k].links[i].q.coeffs());
    }
  }
  options.radius_override_m["tail"] = 0.1;
  try {
    ImportBvhFile(ClipPath("cmu_07_01_walk.bvh.gz"), options);
    ADD_FAILURE() << "no exception";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("tail"), std::string::npos) << e.what();
  }
  options.radius_override_m.erase("tail");
  options.radius_override_m["hand_l"] = -1;
  EXPECT_THROW(ImportBvhFile(ClipPath("cmu_07_01_walk.bvh.gz"), options), InputError);
}

// ---------------------------------------------------------------------------
// A tiny hand-written clip in the MotionBuilder/Vicon naming, centimetres.

std::string TinyHierarchy(const std::string& ab_channels) {
  return "HIERARCHY\n"
         "ROOT Hips\n{\n"
         "  OFFSET 0 0 0\n"
         "  CHANNELS 6 Xposition Yposition Zposition Zrotation Xrotation Yrotation\n"
         "  JOINT Ab\n  {\n"
         "    OFFSET 0 10 0\n"
         "    CHANNELS " +
         ab_channels +
         "\n"
         "    JOINT Chest\n    {\n"
         "      OFFSET 0 20 0\n"
         "      CHANNELS 3 Xrotation Yrotation Zrotation\n"
         "      JOINT Neck\n      {\n"
         "        OFFSET 0 20 0\n"
         "        CHANNELS 3 Zrotation Xrotation Yrotation\n"
         "        JOINT Head\n        {\n"
         "          OFFSET 0 10 0\n"
         "          CHANNELS 3 Zrotation Xrotation Yrotation\n"
         "          End Site\n          {\n            OFFSET 0 15 0\n          }\n"
         "        }\n"
         "      }\n"
         "      JOINT LeftShoulder\n      {\n"
         "        OFFSET 15 18 0\n"
         "        CHANNELS 3 Zrotation Xrotation Yrotation\n"
         "        JOINT LeftElbow\n        {\n"
         "          OFFSET 28 0 0\n"
         "          CHANNELS 3 Zrotation Xrotation Yrotation\n"
         "          JOINT LeftWrist\n          {\n"
         "            OFFSET 25 0 0\n"
         "            CHANNELS 3 Zrotation Xrotation Yrotation\n"
         "            End Site\n            {\n              OFFSET 15 0 0\n            }\n"
         "          }\n"
         "        }\n"
         "      }\n"
         "      JOINT RightShoulder\n      {\n"
         "        OFFSET -15 18 0\n"
         "        CHANNELS 3 Zrotation Xrotation Yrotation\n"
         "        JOINT RightElbow\n        {\n"
         "          OFFSET -28 0 0\n"
         "          CHANNELS 3 Zrotation Xrotation Yrotation\n"
         "          JOINT RightWrist\n          {\n"
         "            OFFSET -25 0 0\n"
         "            CHANNELS 3 Zrotation Xrotation Yrotation\n"
         "            End Site\n            {\n              OFFSET -15 0 0\n            }\n"
         "          }\n"
         "        }\n"
         "      }\n"
         "    }\n"
         "  }\n"
         "  JOINT LeftHip\n  {\n"
         "    OFFSET 10 0 0\n"
         "    CHANNELS 3 Zrotation Xrotation Yrotation\n"
         "    JOINT LeftKnee\n    {\n"
         "      OFFSET 0 -42 0\n"
         "      CHANNELS 3 Zrotation Xrotation Yrotation\n"
         "      JOINT LeftAnkle\n      {\n"
         "        OFFSET 0 -42 0\n"
         "        CHANNELS 3 Zrotation Xrotation Yrotation\n"
         "        End Site\n        {\n          OFFSET 0 -5 15\n        }\n"
         "      }\n"
         "    }\n"
         "  }\n"
         "  JOINT RightHip\n  {\n"
         "    OFFSET -10 0 0\n"
         "    CHANNELS 3 Zrotation Xrotation Yrotation\n"
         "    JOINT RightKnee\n    {\n"
         "      OFFSET 0 -42 0\n"
         "      CHANNELS 3 Zrotation Xrotation Yrotation\n"
         "      JOINT RightAnkle\n      {\n"
         "        OFFSET 0 -42 0\n"
         "        CHANNELS 3 Zrotation Xrotation Yrotation\n"
         "        End Site\n        {\n          OFFSET 0 -5 15\n        }\n"
         "      }\n"
         "    }\n"
         "  }\n"
         "}\n";
}

// The channel names in file order.
std::vector<std::string> ChannelNames(const std::string& hierarchy) {
  std::istringstream in(hierarchy);
  std::vector<std::string> names;
  std::string token;
  while (in >> token) {
    if (token != "CHANNELS") continue;
    int n = 0;
    in >> n;
    for (int k = 0; k < n && in >> token; ++k) names.push_back(token);
  }
  return names;
}

// Channel value of frame f, channel c: root position (10 + f, 90, -5) cm,
// other positions 1 + 0.5 f cm, rotations 3 + 0.1 c + 2 f degrees.
double TinyValue(const std::vector<std::string>& names, int f, int c) {
  if (c == 0) return 10 + f;
  if (c == 1) return 90;
  if (c == 2) return -5;
  if (names[c].find("position") != std::string::npos) return 1 + 0.5 * f;
  return 3 + 0.1 * c + 2 * f;
}

std::string TinyBvh(int frames = 3,
                    const std::string& ab_channels = "3 Zrotation Xrotation Yrotation") {
  const std::string hierarchy = TinyHierarchy(ab_channels);
  const std::vector<std::string> names = ChannelNames(hierarchy);
  std::ostringstream out;
  out << hierarchy << "MOTION\nFrames: " << frames << "\nFrame Time: 0.01\n";
  for (int f = 0; f < frames; ++f) {
    for (size_t c = 0; c < names.size(); ++c) {
      out << (c ? " " : "") << TinyValue(names, f, static_cast<int>(c));
    }
    out << "\n";
  }
  return out.str();
}

Eigen::Matrix3d Rot(char axis, double degrees) {
  const Eigen::Vector3d u = axis == 'X'   ? Eigen::Vector3d::UnitX()
                            : axis == 'Y' ? Eigen::Vector3d::UnitY()
                                          : Eigen::Vector3d::UnitZ();
  return Eigen::AngleAxisd(degrees * M_PI / 180, u).toRotationMatrix();
}

// Product of the rotation channels of one joint, in listed order.
Eigen::Matrix3d JointRotation(const std::vector<std::string>& names, int f, int first, int n) {
  Eigen::Matrix3d R = Eigen::Matrix3d::Identity();
  for (int c = first; c < first + n; ++c) {
    if (names[c].find("rotation") != std::string::npos)
      R = R * Rot(names[c][0], TinyValue(names, f, c));
  }
  return R;
}

// Channel order and position channels: the chest frame of the tiny clip,
// composed with Eigen from the channel values.
TEST(mocap_import, ChannelOrderAndPositionChannels) {
  for (const std::string& ab :
       std::vector<std::string>{"3 Zrotation Xrotation Yrotation",
                                "6 Xposition Yposition Zposition Yrotation Zrotation Xrotation"}) {
    SCOPED_TRACE(ab);
    const std::string text = TinyBvh(3, ab);
    const std::vector<std::string> names = ChannelNames(TinyHierarchy(ab));
    const MocapClip clip = ImportBvhText(text, "tiny.bvh");
    ASSERT_EQ(clip.poses.size(), 3u);
    EXPECT_DOUBLE_EQ(clip.unit_scale_m, 0.01);
    const int ab_n = ab[0] - '0';
    for (int f = 0; f < 3; ++f) {
      const Eigen::Matrix3d R_root = JointRotation(names, f, 0, 6);
      const Eigen::Matrix3d R_ab = JointRotation(names, f, 6, ab_n);
      const Eigen::Matrix3d R_chest = JointRotation(names, f, 6 + ab_n, 3);
      Eigen::Vector3d t_ab(0, 10, 0);
      if (ab_n == 6) t_ab += Eigen::Vector3d::Constant(1 + 0.5 * f);
      const Eigen::Vector3d p_root(10 + f, 90, -5);
      const Eigen::Vector3d p_chest =
          p_root + R_root * t_ab + R_root * R_ab * Eigen::Vector3d(0, 20, 0);
      const LinkPose& chest = clip.poses[f].links[2];
      EXPECT_TRUE((chest.p - 0.01 * p_chest).norm() < 1e-12);
      EXPECT_TRUE(chest.q.toRotationMatrix().isApprox(R_root * R_ab * R_chest, 1e-12));
      EXPECT_EQ(clip.poses[f].utime, f * 10000);
    }
    EXPECT_EQ(clip.source_joints[2], "Chest");
    EXPECT_TRUE(clip.skeleton.link(2).b_L.isApprox(Eigen::Vector3d(0, 0.2, 0)));
  }
}

TEST(mocap_import, ExplicitUnitScale) {
  MocapImportOptions options;
  options.unit_scale_m = 0.02;
  const MocapClip clip = ImportBvhText(TinyBvh(), "tiny.bvh", options);
  EXPECT_EQ(clip.unit_scale_m, 0.02);
  EXPECT_TRUE(
      clip.skeleton.link(IndexOfLink(clip, "shin_l")).b_L.isApprox(Eigen::Vector3d(0, -0.84, 0)));
}

// ---------------------------------------------------------------------------
// Bad input: every problem is an InputError naming the source (and the line).

void ExpectInputError(const std::string& text, const std::string& needle,
                      const MocapImportOptions& options = {}) {
  try {
    ImportBvhText(text, "tiny.bvh", options);
    ADD_FAILURE() << "no exception; wanted one mentioning '" << needle << "'";
  } catch (const InputError& e) {
    const std::string what = e.what();
    EXPECT_EQ(what.rfind("tiny.bvh: ", 0), 0u) << what;
    EXPECT_NE(what.find(needle), std::string::npos) << what;
  }
}

std::string Replace(std::string text, const std::string& from, const std::string& to) {
  const size_t at = text.find(from);
  EXPECT_NE(at, std::string::npos) << from;
  if (at != std::string::npos) text.replace(at, from.size(), to);
  return text;
}

TEST(mocap_import, BadInputThrowsNamingTheSource) {
  const std::string good = TinyBvh();
  ASSERT_NO_THROW(ImportBvhText(good, "tiny.bvh"));

  ExpectInputError("", "line 1: the file is empty");
  ExpectInputError("  \n\n \t\n", "the file is empty");
  // Truncated MOTION section: the last frame line is missing.
  const std::string truncated = good.substr(0, good.rfind('\n', good.size() - 2) + 1);
  ExpectInputError(truncated, "truncated MOTION section");
  // Frame line cut in the middle.
  ExpectInputError(good.substr(0, good.size() - 20), "values, expected 54");
  // Non-numeric values.
  ExpectInputError(Replace(good, "\n10 90 -5", "\n10 abc -5"), "'abc' is not a finite number");
  ExpectInputError(Replace(good, "\n10 90 -5", "\n10 nan -5"), "'nan' is not a finite number");
  ExpectInputError(Replace(good, "OFFSET 0 10 0", "OFFSET 0 1O 0"), "line 8: OFFSET");
  ExpectInputError(Replace(good, "Frame Time: 0.01", "Frame Time: fast"), "Frame Time");
  ExpectInputError(Replace(good, "Frames: 3", "Frames: -3"), "Frames:");
  ExpectInputError(Replace(good, "Frames: 3", "Frames: 0"), "Frames:");
  // Missing ROOT.
  ExpectInputError(Replace(good, "ROOT Hips", "JOINT Hips"), "line 2: expected ROOT");
  ExpectInputError(Replace(good, "HIERARCHY\n", ""), "expected HIERARCHY");
  // Wrong channel count: fewer names than declared, more names than declared,
  // a frame line with one value too many.
  ExpectInputError(Replace(good, "CHANNELS 6 Xposition Yposition Zposition Zrotation Xrotation",
                           "CHANNELS 6 Xposition Yposition Zposition Zrotation"),
                   "declares 6 channels");
  ExpectInputError(Replace(good, "CHANNELS 3 Xrotation Yrotation Zrotation",
                           "CHANNELS 2 Xrotation Yrotation Zrotation"),
                   "outside CHANNELS");
  ExpectInputError(Replace(good, "\n10 90 -5", "\n10 90 -5 7"), "more than 54 values");
  ExpectInputError(Replace(good, "CHANNELS 3 Xrotation", "CHANNELS x Xrotation"), "channel count");
  ExpectInputError(Replace(good, "Xrotation Yrotation Zrotation", "Xrotation Yrotation Wrotation"),
                   "'Wrotation'");
  // Structure.
  ExpectInputError(good.substr(0, good.find("JOINT LeftHip")), "ends inside the HIERARCHY");
  ExpectInputError(good.substr(0, good.find("MOTION")), "MOTION section is missing");
  ExpectInputError(Replace(good, "    OFFSET 0 10 0\n", ""), "has no OFFSET");
  ExpectInputError(Replace(good, "End Site", "End Zone"), "expected 'Site'");
  ExpectInputError(Replace(good, "MOTION", "ROOT Other\n{\n}\nMOTION"), "second ROOT");
  // A joint the avatar needs is missing (knee renamed).
  ExpectInputError(Replace(good, "JOINT LeftKnee", "JOINT LeftBendyBit"), "link 'shin_l'");
  // Bad options.
  MocapImportOptions options;
  options.frame_step = 0;
  ExpectInputError(good, "frame_step", options);
  options = {};
  options.up_axis = 'x';
  ExpectInputError(good, "up_axis", options);
  options = {};
  options.start_frame = 3;
  ExpectInputError(good, "start_frame 3", options);
  options = {};
  options.frame_count = 0;
  ExpectInputError(good, "frame_count", options);
  options = {};
  options.unit_scale_m = -1;
  ExpectInputError(good, "unit_scale_m", options);
}

TEST(mocap_import, MissingFileNamesThePath) {
  const std::string path = kMocapDir + "/no_such_clip.bvh";
  try {
    ImportBvhFile(path);
    ADD_FAILURE() << "no exception";
  } catch (const InputError& e) {
    EXPECT_EQ(std::string(e.what()).rfind(path + ": ", 0), 0u) << e.what();
  }
  EXPECT_THROW(ImportBvhFile(kMocapDir), InputError);
}

// A gzip-compressed clip (as shipped in data/mocap) imports exactly as its
// plain text does; a damaged gzip stream is refused naming the file.
TEST(mocap_import, GzipFileImportsAsItsPlainText) {
  const std::string gz = ClipPath("cmu_02_03_run_jog.bvh.gz");
  const std::string text = ReadText(gz);
  ASSERT_EQ(text.rfind("HIERARCHY", 0), 0u) << gz << " does not gunzip to BVH text";
  const std::string dir = ::testing::TempDir() + "/mocap_gzip_" + std::to_string(::getpid());
  fs::create_directories(dir);
  const std::string plain = dir + "/run_jog.bvh";
  std::ofstream(plain, std::ios::binary) << text;
  const MocapClip a = ImportBvhFile(gz);
  const MocapClip b = ImportBvhFile(plain);
  ASSERT_EQ(a.poses.size(), b.poses.size());
  ASSERT_GT(a.poses.size(), 100u);
  EXPECT_EQ(a.source_joints, b.source_joints);
  // Named after the file without .bvh.gz, as b is without .bvh.
  EXPECT_EQ(a.skeleton.name(), "cmu_02_03_run_jog");
  EXPECT_EQ(b.skeleton.name(), "run_jog");
  EXPECT_EQ(SkeletonToJson(a.skeleton),
            SkeletonToJson(Skeleton::FromLinks("cmu_02_03_run_jog", b.skeleton.links(), plain)));
  for (size_t f = 0; f < a.poses.size(); ++f) {
    for (size_t i = 0; i < a.poses[f].links.size(); ++i) {
      ASSERT_EQ(a.poses[f].links[i].p, b.poses[f].links[i].p) << f << " " << i;
      ASSERT_EQ(a.poses[f].links[i].q.coeffs(), b.poses[f].links[i].q.coeffs()) << f << " " << i;
    }
  }
  // The first half of the compressed bytes: a truncated gzip stream.
  std::ifstream in(gz, std::ios::binary);
  const std::string bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  const std::string cut = dir + "/cut.bvh.gz";
  std::ofstream(cut, std::ios::binary) << bytes.substr(0, bytes.size() / 2);
  try {
    ImportBvhFile(cut);
    ADD_FAILURE() << "no exception";
  } catch (const InputError& e) {
    EXPECT_EQ(std::string(e.what()).rfind(cut + ": ", 0), 0u) << e.what();
    EXPECT_NE(std::string(e.what()).find("gzip"), std::string::npos) << e.what();
  }
  fs::remove_all(dir);
}

// Truncated or damaged files never crash: every prefix of the tiny clip, and
// seeded random byte edits, either import or throw InputError.
TEST(mocap_import, TruncationsAndGarbageNeverCrash) {
  const std::string good = TinyBvh();
  int imported = 0;
  for (size_t n = 0; n <= good.size(); ++n) {
    try {
      ImportBvhText(good.substr(0, n), "tiny.bvh");
      ++imported;
    } catch (const InputError& e) {
      EXPECT_EQ(std::string(e.what()).rfind("tiny.bvh: ", 0), 0u) << e.what();
    }
  }
  // Only prefixes that end within the last frame's final newline or last
  // digits can parse; the hierarchy and earlier frames always fail.
  EXPECT_GE(imported, 1);
  EXPECT_LT(imported, 10);

  std::mt19937 rng(12345);
  const std::string alphabet = "0123456789 .-+e\n\t{}ABCXYZrotpsin\r\x01\xff:";
  int accepted = 0;
  for (int trial = 0; trial < 2000; ++trial) {
    std::string text = good;
    const int edits = 1 + static_cast<int>(rng() % 4);
    for (int e = 0; e < edits; ++e) {
      const size_t at = rng() % text.size();
      switch (rng() % 3) {
        case 0:
          text[at] = alphabet[rng() % alphabet.size()];
          break;
        case 1:
          text.erase(at, 1 + rng() % 8);
          break;
        default:
          text.insert(at, 1, alphabet[rng() % alphabet.size()]);
          break;
      }
      if (text.empty()) text = "x";
    }
    try {
      const MocapClip clip = ImportBvhText(text, "tiny.bvh");
      ++accepted;
      for (const Pose& pose : clip.poses) {
        Pose copy = pose;
        EXPECT_EQ(ValidateAndNormalizePose(&copy, 16), "");
      }
    } catch (const InputError& e) {
      EXPECT_EQ(std::string(e.what()).rfind("tiny.bvh: ", 0), 0u) << e.what();
    }
  }
  EXPECT_GT(accepted, 0);  // Some edits only change a value.

  // Random cuts of a real clip.
  const std::string real = ReadText(ClipPath("cmu_02_03_run_jog.bvh.gz"));
  ASSERT_FALSE(real.empty());
  for (int trial = 0; trial < 40; ++trial) {
    const size_t n = rng() % (real.size() - 2000);  // Well before the last frame.
    EXPECT_THROW(ImportBvhText(real.substr(0, n), "cut.bvh"), InputError) << n;
  }
}

}  // namespace
}  // namespace sweptccd
