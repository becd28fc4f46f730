// XR_BD_body_tracking (PICO): 24 joints (XrBodyJointBD), SMPL's order.
// Enumeration: https://github.com/KhronosGroup/OpenXR-SDK, include/openxr/openxr.h (commit
// 75c53b6e853dc12c7b3c771edc9c9c841b15faaa, 2025-10-14), licence Apache-2.0 OR MIT; the names below
// are that enum's identifiers in its order (0..23). The parents are SMPL's kinematic tree for that
// order (SMPL's kintree_table: -1 0 0 0 1 2 3 4 5 6 7 8 9 9 9 12 13 14 16 17 18 19 20 21, Loper et
// al., "SMPL: A Skinned Multi-Person Linear Model", 2015), which the names also say. The hands are
// one joint each: --hands simple and full both give one capsule from the wrist towards it.

#include <string>
#include <vector>

#include "core/avatar/joint_set.h"
#include "core/avatar/joint_sets/anthropometry.h"

namespace sweptccd::internal {

JointSet BdBodyJointSet() {
  namespace a = anthro;
  JointSetBuilder b("bd-body", "OpenXR XR_BD_body_tracking (PICO, SMPL order)",
                    "https://github.com/KhronosGroup/OpenXR-SDK, include/openxr/openxr.h (commit "
                    "75c53b6e853dc12c7b3c771edc9c9c841b15faaa, 2025-10-14), licence Apache-2.0 OR "
                    "MIT, enum XrBodyJointBD",
                    /*runtime_radii=*/false);
  const std::vector<std::string> names = {
      "XR_BODY_JOINT_PELVIS_BD",        "XR_BODY_JOINT_LEFT_HIP_BD",
      "XR_BODY_JOINT_RIGHT_HIP_BD",     "XR_BODY_JOINT_SPINE1_BD",
      "XR_BODY_JOINT_LEFT_KNEE_BD",     "XR_BODY_JOINT_RIGHT_KNEE_BD",
      "XR_BODY_JOINT_SPINE2_BD",        "XR_BODY_JOINT_LEFT_ANKLE_BD",
      "XR_BODY_JOINT_RIGHT_ANKLE_BD",   "XR_BODY_JOINT_SPINE3_BD",
      "XR_BODY_JOINT_LEFT_FOOT_BD",     "XR_BODY_JOINT_RIGHT_FOOT_BD",
      "XR_BODY_JOINT_NECK_BD",          "XR_BODY_JOINT_LEFT_COLLAR_BD",
      "XR_BODY_JOINT_RIGHT_COLLAR_BD",  "XR_BODY_JOINT_HEAD_BD",
      "XR_BODY_JOINT_LEFT_SHOULDER_BD", "XR_BODY_JOINT_RIGHT_SHOULDER_BD",
      "XR_BODY_JOINT_LEFT_ELBOW_BD",    "XR_BODY_JOINT_RIGHT_ELBOW_BD",
      "XR_BODY_JOINT_LEFT_WRIST_BD",    "XR_BODY_JOINT_RIGHT_WRIST_BD",
      "XR_BODY_JOINT_LEFT_HAND_BD",     "XR_BODY_JOINT_RIGHT_HAND_BD"};
  b.Joints(names);
  const int kParents[24] = {-1, 0, 0, 0,  1,  2,  3,  4,  5,  6,  7,  8,
                            9,  9, 9, 12, 13, 14, 16, 17, 18, 19, 20, 21};
  for (int i = 1; i < 24; ++i) b.Parent(names[i], names[kParents[i]]);
  auto n = [](const std::string& w) { return "XR_BODY_JOINT_" + w + "_BD"; };
  const HandPart body = HandPart::kBody;
  b.Bone(n("PELVIS"), n("SPINE1"), body, 0.07, a::kTorsoRadius);
  b.Bone(n("SPINE1"), n("SPINE2"), body, 0.07, a::kTorsoRadius);
  b.Bone(n("SPINE2"), n("SPINE3"), body, 0.04, a::kTorsoRadius);
  b.Bone(n("SPINE3"), n("NECK"), body, a::kPelvisToNeck - 0.18, a::kUpperChestRadius);
  b.Bone(n("NECK"), n("HEAD"), body, a::kNeck, a::kNeckRadius);
  b.Extension(n("NECK"), n("HEAD"), body, a::kHead, a::kHeadRadius);
  for (const std::string side : {"LEFT", "RIGHT"}) {
    auto s = [&](const std::string& w) { return n(side + "_" + w); };
    b.Bone(n("SPINE3"), s("COLLAR"), body, a::kHalfShoulder * 0.5, a::kShoulderRadius);
    b.Bone(s("COLLAR"), s("SHOULDER"), body, a::kHalfShoulder * 0.5, a::kShoulderRadius);
    b.Bone(s("SHOULDER"), s("ELBOW"), body, a::kUpperArm, a::kUpperArmRadius);
    b.Bone(s("ELBOW"), s("WRIST"), body, a::kForearm, a::kForearmRadius);
    b.Toward(s("WRIST"), s("HAND"), HandPart::kHandSimple, a::kSimpleHandLength,
             a::kSimpleHandRadius);
  }
  for (const std::string side : {"LEFT", "RIGHT"}) {
    auto s = [&](const std::string& w) { return n(side + "_" + w); };
    b.Bone(n("PELVIS"), s("HIP"), body, a::kHalfHip, a::kPelvisSideRadius);
    b.Bone(s("HIP"), s("KNEE"), body, a::kThigh, a::kThighRadius);
    b.Bone(s("KNEE"), s("ANKLE"), body, a::kShank, a::kShankRadius);
    b.Bone(s("ANKLE"), s("FOOT"), body, a::kFoot, a::kFootRadius);
    b.Extension(s("ANKLE"), s("FOOT"), body, a::kToes, a::kToesRadius);
  }
  return b.Build();
}

}  // namespace sweptccd::internal
