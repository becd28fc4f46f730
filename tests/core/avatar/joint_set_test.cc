// The joint sets against their specifications' enumerations (names in
// order, counts, parents), the skeletons they give (SPEC 1, one tree, radii
// > 0) and the conversion of joint frames to SPEC 2 poses, checked against
// a brute-force twin on seeded random frames; bad frames refused.

#include "core/avatar/joint_set.h"

#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <map>
#include <set>
#include <string>
#include <vector>

#include "core/avatar/joint_frame.h"
#include "core/avatar/skeleton.h"
#include "core/errors.h"
#include "tests/common/random.h"

namespace sweptccd {
namespace {

using testing::Rng;

const HandsOption kAllHands[] = {HandsOption::kNone, HandsOption::kSimple, HandsOption::kFull};

bool HandOnly(const JointSet& set) {
  for (const LinkDef& l : set.links) {
    if (l.part == HandPart::kBody) return false;
  }
  return true;
}

// --- The enumerations, against the specifications ---------------------------

struct Expected {
  const char* id;
  int count;
  const char* first;
  const char* last;
};
// First and last names and counts as the specifications write them
// (OpenXR-SDK include/openxr/openxr.h, immersive-web index.bs files, VRM
// humanoid.md; docs/SKELETONS.md cites each).
const Expected kExpected[] = {
    {"meta-full-body", 84, "XR_FULL_BODY_JOINT_ROOT_META",
     "XR_FULL_BODY_JOINT_RIGHT_FOOT_BALL_META"},
    {"fb-body", 70, "XR_BODY_JOINT_ROOT_FB", "XR_BODY_JOINT_RIGHT_HAND_LITTLE_TIP_FB"},
    {"webxr-body", 83, "hips", "right-foot-ball"},
    {"htc-body", 26, "XR_BODY_JOINT_PELVIS_HTC", "XR_BODY_JOINT_RIGHT_WRIST_HTC"},
    {"bd-body", 24, "XR_BODY_JOINT_PELVIS_BD", "XR_BODY_JOINT_RIGHT_HAND_BD"},
    {"ext-hand", 26, "XR_HAND_JOINT_PALM_EXT", "XR_HAND_JOINT_LITTLE_TIP_EXT"},
    {"webxr-hand", 25, "wrist", "pinky-finger-tip"},
    {"vrm-humanoid", 55, "hips", "rightLittleDistal"},
};

TEST(JointSetTest, CountsAndEndsMatchTheSpecifications) {
  ASSERT_EQ(JointSetIds().size(), std::size(kExpected));
  for (const Expected& e : kExpected) {
    SCOPED_TRACE(e.id);
    const JointSet& set = FindJointSet(e.id);
    ASSERT_EQ(set.num_joints(), e.count);
    EXPECT_EQ(set.joints.front().name, e.first);
    EXPECT_EQ(set.joints.back().name, e.last);
    std::set<std::string> names;
    for (const JointDef& j : set.joints) names.insert(j.name);
    EXPECT_EQ(names.size(), set.joints.size()) << "duplicate joint names";
    EXPECT_FALSE(set.source.empty());
  }
}

TEST(JointSetTest, IndicesMatchTheSpecifications) {
  // Spot checks at the enums' section boundaries, index as in the spec.
  const std::map<std::string, std::vector<std::pair<int, std::string>>> kAt = {
      {"meta-full-body",
       {{1, "XR_FULL_BODY_JOINT_HIPS_META"},
        {7, "XR_FULL_BODY_JOINT_HEAD_META"},
        {12, "XR_FULL_BODY_JOINT_LEFT_HAND_WRIST_TWIST_META"},
        {18, "XR_FULL_BODY_JOINT_LEFT_HAND_PALM_META"},
        {19, "XR_FULL_BODY_JOINT_LEFT_HAND_WRIST_META"},
        {43, "XR_FULL_BODY_JOINT_LEFT_HAND_LITTLE_TIP_META"},
        {44, "XR_FULL_BODY_JOINT_RIGHT_HAND_PALM_META"},
        {70, "XR_FULL_BODY_JOINT_LEFT_UPPER_LEG_META"},
        {76, "XR_FULL_BODY_JOINT_LEFT_FOOT_BALL_META"},
        {77, "XR_FULL_BODY_JOINT_RIGHT_UPPER_LEG_META"}}},
      {"fb-body",
       {{9, "XR_BODY_JOINT_LEFT_SCAPULA_FB"}, {45, "XR_BODY_JOINT_RIGHT_HAND_WRIST_FB"}}},
      {"webxr-body",
       {{0, "hips"},
        {16, "right-hand-wrist-twist"},
        {17, "left-hand-palm"},
        {28, "left-hand-middle-phalanx-metacarpal"},  // Sic, in the draft.
        {54, "right-hand-middle-metacarpal"},
        {69, "left-upper-leg"}}},
      {"htc-body",
       {{4, "XR_BODY_JOINT_LEFT_FEET_HTC"},
        {9, "XR_BODY_JOINT_WAIST_HTC"},
        {16, "XR_BODY_JOINT_LEFT_CLAVICLE_HTC"}}},
      {"bd-body",
       {{3, "XR_BODY_JOINT_SPINE1_BD"},
        {12, "XR_BODY_JOINT_NECK_BD"},
        {15, "XR_BODY_JOINT_HEAD_BD"},
        {22, "XR_BODY_JOINT_LEFT_HAND_BD"}}},
      {"ext-hand",
       {{1, "XR_HAND_JOINT_WRIST_EXT"},
        {5, "XR_HAND_JOINT_THUMB_TIP_EXT"},
        {8, "XR_HAND_JOINT_INDEX_INTERMEDIATE_EXT"},
        {21, "XR_HAND_JOINT_LITTLE_METACARPAL_EXT"}}},
      {"webxr-hand",
       {{1, "thumb-metacarpal"},
        {4, "thumb-tip"},
        {5, "index-finger-metacarpal"},
        {20, "pinky-finger-metacarpal"}}},
      {"vrm-humanoid",
       {{5, "head"},
        {8, "jaw"},
        {9, "leftUpperLeg"},
        {17, "leftShoulder"},
        {25, "leftThumbMetacarpal"},
        {40, "rightThumbMetacarpal"}}},
  };
  for (const auto& [id, at] : kAt) {
    const JointSet& set = FindJointSet(id);
    for (const auto& [i, name] : at) EXPECT_EQ(set.joints[i].name, name) << id << " " << i;
  }
}

TEST(JointSetTest, RelatedSetsShareTheirJoints) {
  // XR_FB_body_tracking's joints are XR_META_body_tracking_full_body's first
  // 70 and WebXR's are Meta's without ROOT: same words, same order.
  const JointSet& meta = FindJointSet("meta-full-body");
  const JointSet& fb = FindJointSet("fb-body");
  const JointSet& webxr = FindJointSet("webxr-body");
  auto word = [](std::string s, const std::string& pre, const std::string& suf) {
    return s.substr(pre.size(), s.size() - pre.size() - suf.size());
  };
  for (int i = 0; i < fb.num_joints(); ++i) {
    EXPECT_EQ(word(fb.joints[i].name, "XR_BODY_JOINT_", "_FB"),
              word(meta.joints[i].name, "XR_FULL_BODY_JOINT_", "_META"));
    EXPECT_EQ(fb.joints[i].parent, meta.joints[i].parent);
  }
  for (int i = 0; i < webxr.num_joints(); ++i) {
    // The side and the last word agree ("left-hand-index-phalanx-distal" and
    // LEFT_HAND_INDEX_DISTAL).
    std::string m = word(meta.joints[i + 1].name, "XR_FULL_BODY_JOINT_", "_META");
    std::string w = webxr.joints[i].name;
    for (char& c : m) c = c == '_' ? '-' : static_cast<char>(std::tolower(c));
    auto last = [](const std::string& x) {
      const size_t cut = x.rfind('-');
      return cut == std::string::npos ? x : x.substr(cut + 1);
    };
    EXPECT_EQ(m.substr(0, 4), w.substr(0, 4)) << w;
    EXPECT_EQ(last(m), last(w)) << w;
  }
}

TEST(JointSetTest, ParentsFormOneTree) {
  for (const std::string& id : JointSetIds()) {
    SCOPED_TRACE(id);
    const JointSet& set = FindJointSet(id);
    int roots = 0;
    for (int j = 0; j < set.num_joints(); ++j) {
      const int p = set.joints[j].parent;
      ASSERT_LT(p, set.num_joints());
      if (p < 0) ++roots;
      // No loop: the walk up ends within num_joints steps.
      int steps = 0;
      for (int k = j; k >= 0; k = set.joints[k].parent) ASSERT_LE(++steps, set.num_joints());
    }
    EXPECT_EQ(roots, 1);
  }
}

TEST(JointSetTest, ParentsAsTheSpecificationsSay) {
  auto parent = [](const std::string& id, const std::string& child) {
    const JointSet& set = FindJointSet(id);
    const int j = set.FindJoint(child);
    EXPECT_GE(j, 0) << child;
    return set.joints[j].parent < 0 ? std::string() : set.joints[set.joints[j].parent].name;
  };
  // VRM 1.0 humanoid.md, "Parent Bone" column.
  EXPECT_EQ(parent("vrm-humanoid", "neck"), "upperChest");
  EXPECT_EQ(parent("vrm-humanoid", "leftShoulder"), "upperChest");
  EXPECT_EQ(parent("vrm-humanoid", "leftIndexProximal"), "leftHand");
  EXPECT_EQ(parent("vrm-humanoid", "rightThumbDistal"), "rightThumbProximal");
  EXPECT_EQ(parent("vrm-humanoid", "jaw"), "head");
  EXPECT_EQ(parent("vrm-humanoid", "hips"), "");
  // SMPL's kintree_table for XR_BD_body_tracking.
  const int kSmpl[24] = {-1, 0, 0, 0,  1,  2,  3,  4,  5,  6,  7,  8,
                         9,  9, 9, 12, 13, 14, 16, 17, 18, 19, 20, 21};
  const JointSet& bd = FindJointSet("bd-body");
  for (int j = 0; j < 24; ++j) EXPECT_EQ(bd.joints[j].parent, kSmpl[j]) << j;
  // The hands' chains.
  EXPECT_EQ(parent("ext-hand", "XR_HAND_JOINT_INDEX_TIP_EXT"), "XR_HAND_JOINT_INDEX_DISTAL_EXT");
  EXPECT_EQ(parent("ext-hand", "XR_HAND_JOINT_PALM_EXT"), "XR_HAND_JOINT_WRIST_EXT");
  EXPECT_EQ(parent("webxr-hand", "pinky-finger-metacarpal"), "wrist");
  EXPECT_EQ(parent("meta-full-body", "XR_FULL_BODY_JOINT_RIGHT_FOOT_BALL_META"),
            "XR_FULL_BODY_JOINT_RIGHT_FOOT_TRANSVERSE_META");
  EXPECT_EQ(parent("webxr-body", "left-upper-leg"), "hips");
}

// --- Skeletons -----------------------------------------------------------------

TEST(JointSkeletonTest, LinkCountsAsDocumented) {
  // docs/SKELETONS.md, "Link counts": none / simple / full.
  const std::map<std::string, std::vector<int>> kCounts = {
      {"meta-full-body", {31, 33, 81}}, {"fb-body", {17, 19, 67}},
      {"webxr-body", {31, 33, 81}},     {"htc-body", {28, 28, 28}},
      {"bd-body", {24, 26, 26}},        {"ext-hand", {0, 1, 25}},
      {"webxr-hand", {0, 1, 24}},       {"vrm-humanoid", {24, 26, 64}},
  };
  for (const auto& [id, counts] : kCounts) {
    for (int h = 0; h < 3; ++h) {
      EXPECT_EQ(static_cast<int>(PlanLinks(FindJointSet(id), kAllHands[h]).size()), counts[h])
          << id << " hands " << h;
    }
  }
}

TEST(JointSkeletonTest, EverySkeletonPassesTheSpecLoader) {
  for (const std::string& id : JointSetIds()) {
    const JointSet& set = FindJointSet(id);
    for (HandsOption hands : kAllHands) {
      SCOPED_TRACE(id + " hands " + std::to_string(static_cast<int>(hands)));
      if (hands == HandsOption::kNone && HandOnly(set)) {
        EXPECT_THROW(JointSkeleton::Build(set, {1.75, hands}), InputError);
        continue;
      }
      for (double height : {1.2, 1.75, 2.0}) {
        JointSkeletonOptions o;
        o.height_m = height;
        o.hands = hands;
        const JointSkeleton js = JointSkeleton::Build(set, o);
        const Skeleton& s = js.skeleton();
        // SPEC 1 through the project's loader: one root, a tree, radius > 0.
        const Skeleton back = ParseSkeletonJson(SkeletonToJson(s), id);
        ASSERT_EQ(back.num_links(), s.num_links());
        int roots = 0;
        for (int i = 0; i < s.num_links(); ++i) {
          const Link& l = s.link(i);
          roots += l.parent < 0;
          EXPECT_GT(l.radius, 0);
          EXPECT_LT(l.radius, 0.1 * height) << l.name;
          EXPECT_EQ(l.a_L, Eigen::Vector3d::Zero());
          EXPECT_GE(l.b_L.y(), 0);
          // A link's parent is a link whose ends touch its own joint_a's
          // chain: its first joint lies on the path from the root joint.
          if (l.parent >= 0) {
            const LinkDef& mine = *js.plan()[i].def;
            const LinkDef& theirs = *js.plan()[l.parent].def;
            bool on_path = false;
            for (int j = mine.joint_a; j >= 0; j = set.joints[j].parent) {
              on_path = on_path || j == theirs.joint_a || j == theirs.joint_b;
            }
            EXPECT_TRUE(on_path) << l.name << " under " << theirs.name;
          }
        }
        EXPECT_EQ(roots, 1);
      }
    }
  }
}

TEST(JointSkeletonTest, RefusesBadOptions) {
  const JointSet& set = FindJointSet("meta-full-body");
  EXPECT_THROW(JointSkeleton::Build(set, {0.1}), InputError);
  EXPECT_THROW(JointSkeleton::Build(set, {std::numeric_limits<double>::quiet_NaN()}), InputError);
  EXPECT_THROW(FindJointSet("meta"), InputError);
  EXPECT_THROW(ParseHandsOption("some"), InputError);
  JointFrame short_frame;
  short_frame.joints.resize(10);
  JointSkeletonOptions o;
  o.calibration = &short_frame;
  EXPECT_THROW(JointSkeleton::Build(set, o), InputError);
}

// --- Conversion: brute-force twin on random frames ------------------------------

// A random frame: every joint at a random offset (5 mm .. 30 cm) from its
// parent joint, every orientation random; a few joints coincide with their
// parents (zero-length bones).
JointFrame RandomFrame(const JointSet& set, Rng* rng) {
  JointFrame f;
  f.utime = 1000000 + rng->I(1000000);
  f.joints.resize(set.num_joints());
  std::vector<bool> done(set.num_joints(), false);
  std::function<void(int)> place = [&](int j) {
    if (done[j]) return;
    const int p = set.joints[j].parent;
    Eigen::Vector3d base = rng->Box(2.0);
    if (p >= 0) {
      place(p);
      base = f.joints[p].p + (rng->P(0.05) ? 0.0 : rng->U(0.005, 0.3)) * rng->Dir();
    }
    f.joints[j].p = base;
    // Not normalised: the conversion normalises.
    f.joints[j].q = Eigen::Quaterniond(rng->Quat().coeffs() * rng->U(0.5, 2.0));
    f.joints[j].radius = rng->U(0.004, 0.03);
    done[j] = true;
  };
  for (int j = 0; j < set.num_joints(); ++j) place(j);
  return f;
}

// The world segment of link i of `pose` (SPEC 3's A_i, B_i at the pose).
std::pair<Eigen::Vector3d, Eigen::Vector3d> WorldEnds(const Skeleton& s, const Pose& pose, int i) {
  const LinkPose& lp = pose.links[i];
  const Eigen::Matrix3d R = lp.q.normalized().toRotationMatrix();
  return {lp.p + R * s.link(i).a_L, lp.p + R * s.link(i).b_L};
}

TEST(JointFrameTest, LinkEndsReproduceTheJoints) {
  Rng rng(31);
  for (const std::string& id : JointSetIds()) {
    const JointSet& set = FindJointSet(id);
    for (HandsOption hands : kAllHands) {
      if (hands == HandsOption::kNone && HandOnly(set)) continue;
      SCOPED_TRACE(id + " hands " + std::to_string(static_cast<int>(hands)));
      for (int trial = 0; trial < 20; ++trial) {
        const JointFrame frame = RandomFrame(set, &rng);
        JointSkeletonOptions o;
        o.hands = hands;
        o.height_m = rng.U(1.4, 2.0);
        o.calibration = &frame;
        const JointSkeleton js = JointSkeleton::Build(set, o);
        const Skeleton& s = js.skeleton();
        Pose pose;
        ASSERT_EQ(js.Convert(frame, &pose), "");
        ASSERT_EQ(pose.utime, frame.utime);
        ASSERT_EQ(static_cast<int>(pose.links.size()), s.num_links());
        for (int i = 0; i < s.num_links(); ++i) {
          const LinkDef& d = *js.plan()[i].def;
          const auto [A, B] = WorldEnds(s, pose, i);
          const Eigen::Vector3d pa = frame.joints[d.joint_a].p;
          EXPECT_LT((A - pa).norm(), 1e-9) << d.name;
          // The twin: where the far end must be, from the joints alone.
          const double len = s.link(i).b_L.norm();
          Eigen::Vector3d expect_b;
          if (d.joint_b >= 0 && !d.fixed_length) {
            expect_b = frame.joints[d.joint_b].p;  // A bone: at its joint.
          } else if (d.joint_b < 0 && d.joint_from < 0) {
            EXPECT_EQ(len, 0);  // A sphere.
            expect_b = pa;
          } else {
            // Fixed length, towards joint_b or on from joint_from.
            const Eigen::Vector3d dir =
                d.joint_b >= 0 ? frame.joints[d.joint_b].p - pa : pa - frame.joints[d.joint_from].p;
            // No direction (coincident joints): along joint_a's own +Y.
            expect_b = dir.norm() > 1e-9
                           ? Eigen::Vector3d(pa + len * dir.normalized())
                           : Eigen::Vector3d(pa + len * (frame.joints[d.joint_a].q.normalized() *
                                                         Eigen::Vector3d::UnitY()));
          }
          EXPECT_LT((B - expect_b).norm(), 1e-9) << d.name;
          // Runtime radii where the set has them: the larger of its joints'.
          if (set.runtime_radii) {
            double r = frame.joints[d.joint_a].radius;
            if (d.joint_b >= 0) r = std::max(r, frame.joints[d.joint_b].radius);
            EXPECT_DOUBLE_EQ(s.link(i).radius, r) << d.name;
          }
        }
      }
    }
  }
}

TEST(JointFrameTest, RigidMotionOfTheCalibrationIsAccepted) {
  // The same body moved and turned as a whole: every bone keeps its length,
  // the conversion accepts it and the link ends follow the joints.
  Rng rng(7);
  const JointSet& set = FindJointSet("meta-full-body");
  const JointFrame cal = RandomFrame(set, &rng);
  JointSkeletonOptions o;
  o.calibration = &cal;
  const JointSkeleton js = JointSkeleton::Build(set, o);
  for (int trial = 0; trial < 20; ++trial) {
    const Eigen::Quaterniond R = rng.Quat();
    const Eigen::Vector3d t = rng.Box(3);
    JointFrame f = cal;
    for (JointSample& s : f.joints) {
      s.p = R * s.p + t;
      s.q = R * s.q;
    }
    Pose pose;
    ASSERT_EQ(js.Convert(f, &pose), "");
    for (int i = 0; i < js.skeleton().num_links(); ++i) {
      const LinkDef& d = *js.plan()[i].def;
      if (d.joint_b < 0 || d.fixed_length) continue;
      EXPECT_LT((WorldEnds(js.skeleton(), pose, i).second - f.joints[d.joint_b].p).norm(), 1e-9);
    }
  }
}

// --- Bad frames -----------------------------------------------------------------

class BadFrameTest : public ::testing::Test {
 protected:
  void SetUp() override {
    Rng rng(3);
    cal_ = RandomFrame(set_, &rng);
    JointSkeletonOptions o;
    o.calibration = &cal_;
    o.hands = HandsOption::kNone;
    js_ = JointSkeleton::Build(set_, o);
    ASSERT_EQ(js_.Convert(cal_, &good_), "");
  }
  // Converting `f` fails with a message containing `words`; *pose untouched.
  void ExpectRefused(const JointFrame& f, const std::string& words) {
    Pose pose = good_;
    const std::string problem = js_.Convert(f, &pose);
    EXPECT_NE(problem.find(words), std::string::npos) << problem;
    EXPECT_EQ(problem.find('\n'), std::string::npos);
    EXPECT_TRUE(SamePose(pose, good_));
  }
  const JointSet& set_ = FindJointSet("meta-full-body");
  JointFrame cal_;
  JointSkeleton js_;
  Pose good_;
};

TEST_F(BadFrameTest, UntrackedNanZeroAndMissingAreRefused) {
  const int wrist = set_.FindJoint("XR_FULL_BODY_JOINT_LEFT_HAND_WRIST_META");
  JointFrame f = cal_;
  f.joints[wrist].valid = false;
  ExpectRefused(f, "joint 19 (XR_FULL_BODY_JOINT_LEFT_HAND_WRIST_META): not tracked");
  f = cal_;
  f.joints[wrist].p.x() = std::numeric_limits<double>::quiet_NaN();
  ExpectRefused(f, "non-finite position");
  f = cal_;
  f.joints[wrist].q.coeffs().setZero();
  ExpectRefused(f, "quaternion norm");
  f = cal_;
  f.joints[wrist].q.w() = std::numeric_limits<double>::infinity();
  ExpectRefused(f, "non-finite quaternion");
  f = cal_;
  f.joints.pop_back();
  ExpectRefused(f, "expected 84 joints");
  f = cal_;
  f.joints[wrist].p += Eigen::Vector3d(0.5, 0, 0);  // A forearm half a metre longer.
  ExpectRefused(f, "build the skeleton from a calibration frame");
}

TEST_F(BadFrameTest, JointsNoLinkUsesAreNotLookedAt) {
  // --hands none: a finger the runtime lost does not spoil the frame.
  JointFrame f = cal_;
  const int tip = set_.FindJoint("XR_FULL_BODY_JOINT_LEFT_HAND_INDEX_TIP_META");
  EXPECT_FALSE(js_.uses_joint(tip));
  f.joints[tip].valid = false;
  f.joints[tip].p.setConstant(std::numeric_limits<double>::quiet_NaN());
  Pose pose;
  EXPECT_EQ(js_.Convert(f, &pose), "");
  EXPECT_TRUE(SamePose(pose, good_));
}

TEST(JointFrameParseTest, LinesRoundTripAndBadLinesAreRefused) {
  Rng rng(5);
  const JointSet& set = FindJointSet("ext-hand");
  JointFrame f = RandomFrame(set, &rng);
  f.joints[3].valid = false;
  std::string error;
  const std::optional<JointFrame> back =
      ParseJointFrameLine(JointFrameToJsonLine(f), set.num_joints(), &error);
  ASSERT_TRUE(back) << error;
  EXPECT_EQ(back->utime, f.utime);
  for (int j = 0; j < set.num_joints(); ++j) {
    EXPECT_EQ(back->joints[j].valid, f.joints[j].valid);
    EXPECT_EQ(back->joints[j].p, f.joints[j].p);
    EXPECT_EQ(back->joints[j].q.coeffs(), f.joints[j].q.coeffs());
    EXPECT_EQ(back->joints[j].radius, f.joints[j].radius);
  }
  const std::string ok_joint = "[0,0,0,1,0,0,0]";
  std::string joints = "[";
  for (int j = 0; j < 26; ++j) joints += (j ? "," : "") + (j == 4 ? "null" : ok_joint);
  joints += "]";
  const std::optional<JointFrame> with_null =
      ParseJointFrameLine("{\"utime\": 5, \"joints\": " + joints + "}", 26, &error);
  ASSERT_TRUE(with_null) << error;
  EXPECT_FALSE(with_null->joints[4].valid);
  EXPECT_TRUE(with_null->joints[5].valid);
  const std::pair<std::string, std::string> kBad[] = {
      {"garbage", "not a JSON object"},
      {"{\"joints\": " + joints + "}", "utime"},
      {"{\"utime\": 1, \"joints\": [" + ok_joint + "]}", "joints: 1 entries, the joint set has 26"},
      {"{\"utime\": 1, \"joints\": " + joints + ", \"valid\": [true]}", "valid: not an array"},
      {"{\"utime\": 1, \"joints\": " + joints + ", \"radii\": 3}", "radii: not an array"},
      {"{\"utime\": 1.5, \"joints\": " + joints + "}", "utime"},
  };
  for (const auto& [line, words] : kBad) {
    EXPECT_FALSE(ParseJointFrameLine(line, 26, &error)) << line;
    EXPECT_NE(error.find(words), std::string::npos) << error;
  }
  std::string bad_entry = joints;
  bad_entry.replace(1, ok_joint.size(), "[0,0,0,1,0,0,\"x\"]");
  EXPECT_FALSE(ParseJointFrameLine("{\"utime\": 1, \"joints\": " + bad_entry + "}", 26, &error));
  EXPECT_NE(error.find("joints[0]"), std::string::npos) << error;
}

}  // namespace
}  // namespace sweptccd
