// XR_EXT_hand_tracking: 26 joints per hand (XrHandJointEXT), each located
// with a radius (XrHandJointLocationEXT::radius).
// Enumeration: https://github.com/KhronosGroup/OpenXR-SDK, include/openxr/openxr.h (commit
// 75c53b6e853dc12c7b3c771edc9c9c841b15faaa, 2025-10-14), licence Apache-2.0 OR MIT; the names below
// are that enum's identifiers in its order (0..25). The parents are the chains the names say
// (wrist, metacarpal, proximal, intermediate, distal, tip; the palm under the wrist). One hand per
// skeleton: a left and a right hand are two avatars (docs/SKELETONS.md).

#include <string>
#include <vector>

#include "core/avatar/joint_set.h"
#include "core/avatar/joint_sets/openxr_hand_links.h"

namespace sweptccd::internal {

JointSet ExtHandJointSet() {
  JointSetBuilder b("ext-hand", "OpenXR XR_EXT_hand_tracking (one hand)",
                    "https://github.com/KhronosGroup/OpenXR-SDK, include/openxr/openxr.h (commit "
                    "75c53b6e853dc12c7b3c771edc9c9c841b15faaa, 2025-10-14), licence Apache-2.0 OR "
                    "MIT, enum XrHandJointEXT",
                    /*runtime_radii=*/true);
  b.Joints({"XR_HAND_JOINT_PALM_EXT",
            "XR_HAND_JOINT_WRIST_EXT",
            "XR_HAND_JOINT_THUMB_METACARPAL_EXT",
            "XR_HAND_JOINT_THUMB_PROXIMAL_EXT",
            "XR_HAND_JOINT_THUMB_DISTAL_EXT",
            "XR_HAND_JOINT_THUMB_TIP_EXT",
            "XR_HAND_JOINT_INDEX_METACARPAL_EXT",
            "XR_HAND_JOINT_INDEX_PROXIMAL_EXT",
            "XR_HAND_JOINT_INDEX_INTERMEDIATE_EXT",
            "XR_HAND_JOINT_INDEX_DISTAL_EXT",
            "XR_HAND_JOINT_INDEX_TIP_EXT",
            "XR_HAND_JOINT_MIDDLE_METACARPAL_EXT",
            "XR_HAND_JOINT_MIDDLE_PROXIMAL_EXT",
            "XR_HAND_JOINT_MIDDLE_INTERMEDIATE_EXT",
            "XR_HAND_JOINT_MIDDLE_DISTAL_EXT",
            "XR_HAND_JOINT_MIDDLE_TIP_EXT",
            "XR_HAND_JOINT_RING_METACARPAL_EXT",
            "XR_HAND_JOINT_RING_PROXIMAL_EXT",
            "XR_HAND_JOINT_RING_INTERMEDIATE_EXT",
            "XR_HAND_JOINT_RING_DISTAL_EXT",
            "XR_HAND_JOINT_RING_TIP_EXT",
            "XR_HAND_JOINT_LITTLE_METACARPAL_EXT",
            "XR_HAND_JOINT_LITTLE_PROXIMAL_EXT",
            "XR_HAND_JOINT_LITTLE_INTERMEDIATE_EXT",
            "XR_HAND_JOINT_LITTLE_DISTAL_EXT",
            "XR_HAND_JOINT_LITTLE_TIP_EXT"});
  AddOpenXrHand(&b, [](const std::string& w) { return "XR_HAND_JOINT_" + w + "_EXT"; });
  return b.Build();
}

}  // namespace sweptccd::internal
