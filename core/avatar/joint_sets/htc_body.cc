// XR_HTC_body_tracking: 26 joints (XrBodyJointHTC).
// Enumeration: https://github.com/KhronosGroup/OpenXR-SDK, include/openxr/openxr.h (commit
// 75c53b6e853dc12c7b3c771edc9c9c841b15faaa, 2025-10-14), licence Apache-2.0 OR MIT; the names below
// are that enum's identifiers in its order (0..25). The parents are anatomical, read from the names
// (the header gives none). The set has no hand joints: the forearm ends at the wrist whatever
// --hands says.

#include <string>
#include <vector>

#include "core/avatar/joint_set.h"
#include "core/avatar/joint_sets/anthropometry.h"

namespace sweptccd::internal {

JointSet HtcBodyJointSet() {
  namespace a = anthro;
  JointSetBuilder b("htc-body", "OpenXR XR_HTC_body_tracking",
                    "https://github.com/KhronosGroup/OpenXR-SDK, include/openxr/openxr.h (commit "
                    "75c53b6e853dc12c7b3c771edc9c9c841b15faaa, 2025-10-14), licence Apache-2.0 OR "
                    "MIT, enum XrBodyJointHTC",
                    /*runtime_radii=*/false);
  b.Joints({"XR_BODY_JOINT_PELVIS_HTC",        "XR_BODY_JOINT_LEFT_HIP_HTC",
            "XR_BODY_JOINT_LEFT_KNEE_HTC",     "XR_BODY_JOINT_LEFT_ANKLE_HTC",
            "XR_BODY_JOINT_LEFT_FEET_HTC",     "XR_BODY_JOINT_RIGHT_HIP_HTC",
            "XR_BODY_JOINT_RIGHT_KNEE_HTC",    "XR_BODY_JOINT_RIGHT_ANKLE_HTC",
            "XR_BODY_JOINT_RIGHT_FEET_HTC",    "XR_BODY_JOINT_WAIST_HTC",
            "XR_BODY_JOINT_SPINE_LOWER_HTC",   "XR_BODY_JOINT_SPINE_MIDDLE_HTC",
            "XR_BODY_JOINT_SPINE_HIGH_HTC",    "XR_BODY_JOINT_CHEST_HTC",
            "XR_BODY_JOINT_NECK_HTC",          "XR_BODY_JOINT_HEAD_HTC",
            "XR_BODY_JOINT_LEFT_CLAVICLE_HTC", "XR_BODY_JOINT_LEFT_SCAPULA_HTC",
            "XR_BODY_JOINT_LEFT_ARM_HTC",      "XR_BODY_JOINT_LEFT_ELBOW_HTC",
            "XR_BODY_JOINT_LEFT_WRIST_HTC",    "XR_BODY_JOINT_RIGHT_CLAVICLE_HTC",
            "XR_BODY_JOINT_RIGHT_SCAPULA_HTC", "XR_BODY_JOINT_RIGHT_ARM_HTC",
            "XR_BODY_JOINT_RIGHT_ELBOW_HTC",   "XR_BODY_JOINT_RIGHT_WRIST_HTC"});
  auto n = [](const std::string& w) { return "XR_BODY_JOINT_" + w + "_HTC"; };
  const HandPart body = HandPart::kBody;
  const char* spine[] = {"PELVIS",     "WAIST", "SPINE_LOWER", "SPINE_MIDDLE",
                         "SPINE_HIGH", "CHEST", "NECK",        "HEAD"};
  for (int i = 1; i < 8; ++i) b.Parent(n(spine[i]), n(spine[i - 1]));
  const double spine_len[] = {0.03, 0.04, 0.05, 0.05, 0.05, a::kPelvisToNeck - 0.22};
  for (int i = 0; i < 6; ++i) {
    b.Bone(n(spine[i]), n(spine[i + 1]), body, spine_len[i],
           i < 5 ? a::kTorsoRadius : a::kUpperChestRadius);
  }
  b.Bone(n("NECK"), n("HEAD"), body, a::kNeck, a::kNeckRadius);
  b.Extension(n("NECK"), n("HEAD"), body, a::kHead, a::kHeadRadius);
  for (const std::string side : {"LEFT", "RIGHT"}) {
    auto s = [&](const std::string& w) { return n(side + "_" + w); };
    b.Parent(s("CLAVICLE"), n("CHEST"));
    b.Parent(s("SCAPULA"), s("CLAVICLE"));
    b.Parent(s("ARM"), s("SCAPULA"));
    b.Parent(s("ELBOW"), s("ARM"));
    b.Parent(s("WRIST"), s("ELBOW"));
    b.Bone(n("CHEST"), s("CLAVICLE"), body, a::kHalfShoulder * 0.3, a::kShoulderRadius);
    b.Bone(s("CLAVICLE"), s("SCAPULA"), body, a::kHalfShoulder * 0.3, a::kShoulderRadius);
    b.Bone(s("SCAPULA"), s("ARM"), body, a::kHalfShoulder * 0.4, a::kShoulderRadius);
    b.Bone(s("ARM"), s("ELBOW"), body, a::kUpperArm, a::kUpperArmRadius);
    b.Bone(s("ELBOW"), s("WRIST"), body, a::kForearm, a::kForearmRadius);
  }
  for (const std::string side : {"LEFT", "RIGHT"}) {
    auto s = [&](const std::string& w) { return n(side + "_" + w); };
    b.Parent(s("HIP"), n("PELVIS"));
    b.Parent(s("KNEE"), s("HIP"));
    b.Parent(s("ANKLE"), s("KNEE"));
    b.Parent(s("FEET"), s("ANKLE"));
    b.Bone(n("PELVIS"), s("HIP"), body, a::kHalfHip, a::kPelvisSideRadius);
    b.Bone(s("HIP"), s("KNEE"), body, a::kThigh, a::kThighRadius);
    b.Bone(s("KNEE"), s("ANKLE"), body, a::kShank, a::kShankRadius);
    b.Bone(s("ANKLE"), s("FEET"), body, a::kFoot, a::kFootRadius);
    b.Extension(s("ANKLE"), s("FEET"), body, a::kToes, a::kToesRadius);
  }
  return b.Build();
}

}  // namespace sweptccd::internal
