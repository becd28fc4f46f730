#pragma once
// The structure (parents, links) of Meta's body joints, shared by
// XR_META_body_tracking_full_body, XR_FB_body_tracking (its first 70 joints)
// and WebXR body tracking (the same 83 joints without ROOT): one place.

#include <functional>
#include <string>

#include "core/avatar/joint_set.h"

namespace sweptccd::internal {

/// Maps Meta's joint word ("HIPS", "LEFT_HAND_INDEX_TIP", ...) to the set's
/// joint name.
using MetaJointName = std::function<std::string(const std::string& word)>;

/// Sets the parents and adds the links of XR_META_body_tracking_full_body's
/// 84 joints, named by `name`.
void AddMetaBody(JointSetBuilder* b, const MetaJointName& name);

}  // namespace sweptccd::internal
