#pragma once
// The links of one hand with OpenXR's hand joints (XR_EXT_hand_tracking's
// 26, also the hands of XR_FB_body_tracking and XR_META_body_tracking_full_body,
// and WebXR's 25 without the palm): shared by those tables, one place.

#include <functional>
#include <string>

#include "core/avatar/joint_set.h"

namespace sweptccd::internal {

/// Maps OpenXR's hand joint word ("PALM", "WRIST", "THUMB_METACARPAL",
/// "INDEX_TIP", ...) to the set's joint name, or "" when the set lacks it.
using HandJointName = std::function<std::string(const std::string& openxr_word)>;

/// Sets the hand joints' parents (wrist <- metacarpal <- proximal <- ...,
/// the palm under the wrist) and adds the links: --hands simple one capsule
/// from the wrist towards the middle finger's proximal joint; --hands full
/// a carpal bone from the wrist to each metacarpal joint, every finger bone
/// to its tip, and the palm (a sphere, where the set has one).
void AddOpenXrHand(JointSetBuilder* b, const HandJointName& name);

}  // namespace sweptccd::internal
