// XR_FB_body_tracking: 70 joints (XrBodyJointFB), the upper body and hands.
// Enumeration: https://github.com/KhronosGroup/OpenXR-SDK, include/openxr/openxr.h (commit
// 75c53b6e853dc12c7b3c771edc9c9c841b15faaa, 2025-10-14), licence Apache-2.0 OR MIT; the names below
// are that enum's identifiers in its order (0..69). Its joints are
// XR_META_body_tracking_full_body's first 70, same meaning, so the structure (parents, links) is
// that table's (meta_full_body.cc).

#include <string>
#include <vector>

#include "core/avatar/joint_set.h"

namespace sweptccd::internal {

const std::vector<std::string>& MetaFullBodyJointNames();

JointSet FbBodyJointSet() {
  static const std::vector<std::string> kNames = {"XR_BODY_JOINT_ROOT_FB",
                                                  "XR_BODY_JOINT_HIPS_FB",
                                                  "XR_BODY_JOINT_SPINE_LOWER_FB",
                                                  "XR_BODY_JOINT_SPINE_MIDDLE_FB",
                                                  "XR_BODY_JOINT_SPINE_UPPER_FB",
                                                  "XR_BODY_JOINT_CHEST_FB",
                                                  "XR_BODY_JOINT_NECK_FB",
                                                  "XR_BODY_JOINT_HEAD_FB",
                                                  "XR_BODY_JOINT_LEFT_SHOULDER_FB",
                                                  "XR_BODY_JOINT_LEFT_SCAPULA_FB",
                                                  "XR_BODY_JOINT_LEFT_ARM_UPPER_FB",
                                                  "XR_BODY_JOINT_LEFT_ARM_LOWER_FB",
                                                  "XR_BODY_JOINT_LEFT_HAND_WRIST_TWIST_FB",
                                                  "XR_BODY_JOINT_RIGHT_SHOULDER_FB",
                                                  "XR_BODY_JOINT_RIGHT_SCAPULA_FB",
                                                  "XR_BODY_JOINT_RIGHT_ARM_UPPER_FB",
                                                  "XR_BODY_JOINT_RIGHT_ARM_LOWER_FB",
                                                  "XR_BODY_JOINT_RIGHT_HAND_WRIST_TWIST_FB",
                                                  "XR_BODY_JOINT_LEFT_HAND_PALM_FB",
                                                  "XR_BODY_JOINT_LEFT_HAND_WRIST_FB",
                                                  "XR_BODY_JOINT_LEFT_HAND_THUMB_METACARPAL_FB",
                                                  "XR_BODY_JOINT_LEFT_HAND_THUMB_PROXIMAL_FB",
                                                  "XR_BODY_JOINT_LEFT_HAND_THUMB_DISTAL_FB",
                                                  "XR_BODY_JOINT_LEFT_HAND_THUMB_TIP_FB",
                                                  "XR_BODY_JOINT_LEFT_HAND_INDEX_METACARPAL_FB",
                                                  "XR_BODY_JOINT_LEFT_HAND_INDEX_PROXIMAL_FB",
                                                  "XR_BODY_JOINT_LEFT_HAND_INDEX_INTERMEDIATE_FB",
                                                  "XR_BODY_JOINT_LEFT_HAND_INDEX_DISTAL_FB",
                                                  "XR_BODY_JOINT_LEFT_HAND_INDEX_TIP_FB",
                                                  "XR_BODY_JOINT_LEFT_HAND_MIDDLE_METACARPAL_FB",
                                                  "XR_BODY_JOINT_LEFT_HAND_MIDDLE_PROXIMAL_FB",
                                                  "XR_BODY_JOINT_LEFT_HAND_MIDDLE_INTERMEDIATE_FB",
                                                  "XR_BODY_JOINT_LEFT_HAND_MIDDLE_DISTAL_FB",
                                                  "XR_BODY_JOINT_LEFT_HAND_MIDDLE_TIP_FB",
                                                  "XR_BODY_JOINT_LEFT_HAND_RING_METACARPAL_FB",
                                                  "XR_BODY_JOINT_LEFT_HAND_RING_PROXIMAL_FB",
                                                  "XR_BODY_JOINT_LEFT_HAND_RING_INTERMEDIATE_FB",
                                                  "XR_BODY_JOINT_LEFT_HAND_RING_DISTAL_FB",
                                                  "XR_BODY_JOINT_LEFT_HAND_RING_TIP_FB",
                                                  "XR_BODY_JOINT_LEFT_HAND_LITTLE_METACARPAL_FB",
                                                  "XR_BODY_JOINT_LEFT_HAND_LITTLE_PROXIMAL_FB",
                                                  "XR_BODY_JOINT_LEFT_HAND_LITTLE_INTERMEDIATE_FB",
                                                  "XR_BODY_JOINT_LEFT_HAND_LITTLE_DISTAL_FB",
                                                  "XR_BODY_JOINT_LEFT_HAND_LITTLE_TIP_FB",
                                                  "XR_BODY_JOINT_RIGHT_HAND_PALM_FB",
                                                  "XR_BODY_JOINT_RIGHT_HAND_WRIST_FB",
                                                  "XR_BODY_JOINT_RIGHT_HAND_THUMB_METACARPAL_FB",
                                                  "XR_BODY_JOINT_RIGHT_HAND_THUMB_PROXIMAL_FB",
                                                  "XR_BODY_JOINT_RIGHT_HAND_THUMB_DISTAL_FB",
                                                  "XR_BODY_JOINT_RIGHT_HAND_THUMB_TIP_FB",
                                                  "XR_BODY_JOINT_RIGHT_HAND_INDEX_METACARPAL_FB",
                                                  "XR_BODY_JOINT_RIGHT_HAND_INDEX_PROXIMAL_FB",
                                                  "XR_BODY_JOINT_RIGHT_HAND_INDEX_INTERMEDIATE_FB",
                                                  "XR_BODY_JOINT_RIGHT_HAND_INDEX_DISTAL_FB",
                                                  "XR_BODY_JOINT_RIGHT_HAND_INDEX_TIP_FB",
                                                  "XR_BODY_JOINT_RIGHT_HAND_MIDDLE_METACARPAL_FB",
                                                  "XR_BODY_JOINT_RIGHT_HAND_MIDDLE_PROXIMAL_FB",
                                                  "XR_BODY_JOINT_RIGHT_HAND_MIDDLE_INTERMEDIATE_FB",
                                                  "XR_BODY_JOINT_RIGHT_HAND_MIDDLE_DISTAL_FB",
                                                  "XR_BODY_JOINT_RIGHT_HAND_MIDDLE_TIP_FB",
                                                  "XR_BODY_JOINT_RIGHT_HAND_RING_METACARPAL_FB",
                                                  "XR_BODY_JOINT_RIGHT_HAND_RING_PROXIMAL_FB",
                                                  "XR_BODY_JOINT_RIGHT_HAND_RING_INTERMEDIATE_FB",
                                                  "XR_BODY_JOINT_RIGHT_HAND_RING_DISTAL_FB",
                                                  "XR_BODY_JOINT_RIGHT_HAND_RING_TIP_FB",
                                                  "XR_BODY_JOINT_RIGHT_HAND_LITTLE_METACARPAL_FB",
                                                  "XR_BODY_JOINT_RIGHT_HAND_LITTLE_PROXIMAL_FB",
                                                  "XR_BODY_JOINT_RIGHT_HAND_LITTLE_INTERMEDIATE_FB",
                                                  "XR_BODY_JOINT_RIGHT_HAND_LITTLE_DISTAL_FB",
                                                  "XR_BODY_JOINT_RIGHT_HAND_LITTLE_TIP_FB"};
  std::vector<int> base_index;
  for (int i = 0; i < static_cast<int>(kNames.size()); ++i) base_index.push_back(i);
  return DeriveJointSet(MetaFullBodyJointSet(), "fb-body", "OpenXR XR_FB_body_tracking",
                        "https://github.com/KhronosGroup/OpenXR-SDK, include/openxr/openxr.h "
                        "(commit 75c53b6e853dc12c7b3c771edc9c9c841b15faaa, 2025-10-14), licence "
                        "Apache-2.0 OR MIT, enum XrBodyJointFB",
                        kNames, base_index);
}

}  // namespace sweptccd::internal
