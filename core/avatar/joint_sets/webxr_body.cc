// WebXR body tracking: 83 joints (enum XRBodyJoint).
// Enumeration: https://github.com/immersive-web/body-tracking, index.bs
// (commit 9d44b6f3ba3b3d745a9ed2f566c7b0c6d9ca792d, 2025-09-05; the WebXR
// Body Tracking Module draft, https://immersive-web.github.io/body-tracking/),
// W3C Software and Document License. The names below are that enum's strings
// in its order, verbatim (including "left-hand-middle-phalanx-metacarpal",
// whose right-hand twin is "right-hand-middle-metacarpal"). Its joints are
// XR_META_body_tracking_full_body's without ROOT, in the same order, so the
// structure (parents, links) is that table's (meta_full_body.cc).

#include <string>
#include <vector>

#include "core/avatar/joint_set.h"

namespace sweptccd::internal {

JointSet WebXrBodyJointSet() {
  static const std::vector<std::string> kNames = {"hips",
                                                  "spine-lower",
                                                  "spine-middle",
                                                  "spine-upper",
                                                  "chest",
                                                  "neck",
                                                  "head",
                                                  "left-shoulder",
                                                  "left-scapula",
                                                  "left-arm-upper",
                                                  "left-arm-lower",
                                                  "left-hand-wrist-twist",
                                                  "right-shoulder",
                                                  "right-scapula",
                                                  "right-arm-upper",
                                                  "right-arm-lower",
                                                  "right-hand-wrist-twist",
                                                  "left-hand-palm",
                                                  "left-hand-wrist",
                                                  "left-hand-thumb-metacarpal",
                                                  "left-hand-thumb-phalanx-proximal",
                                                  "left-hand-thumb-phalanx-distal",
                                                  "left-hand-thumb-tip",
                                                  "left-hand-index-metacarpal",
                                                  "left-hand-index-phalanx-proximal",
                                                  "left-hand-index-phalanx-intermediate",
                                                  "left-hand-index-phalanx-distal",
                                                  "left-hand-index-tip",
                                                  "left-hand-middle-phalanx-metacarpal",
                                                  "left-hand-middle-phalanx-proximal",
                                                  "left-hand-middle-phalanx-intermediate",
                                                  "left-hand-middle-phalanx-distal",
                                                  "left-hand-middle-tip",
                                                  "left-hand-ring-metacarpal",
                                                  "left-hand-ring-phalanx-proximal",
                                                  "left-hand-ring-phalanx-intermediate",
                                                  "left-hand-ring-phalanx-distal",
                                                  "left-hand-ring-tip",
                                                  "left-hand-little-metacarpal",
                                                  "left-hand-little-phalanx-proximal",
                                                  "left-hand-little-phalanx-intermediate",
                                                  "left-hand-little-phalanx-distal",
                                                  "left-hand-little-tip",
                                                  "right-hand-palm",
                                                  "right-hand-wrist",
                                                  "right-hand-thumb-metacarpal",
                                                  "right-hand-thumb-phalanx-proximal",
                                                  "right-hand-thumb-phalanx-distal",
                                                  "right-hand-thumb-tip",
                                                  "right-hand-index-metacarpal",
                                                  "right-hand-index-phalanx-proximal",
                                                  "right-hand-index-phalanx-intermediate",
                                                  "right-hand-index-phalanx-distal",
                                                  "right-hand-index-tip",
                                                  "right-hand-middle-metacarpal",
                                                  "right-hand-middle-phalanx-proximal",
                                                  "right-hand-middle-phalanx-intermediate",
                                                  "right-hand-middle-phalanx-distal",
                                                  "right-hand-middle-tip",
                                                  "right-hand-ring-metacarpal",
                                                  "right-hand-ring-phalanx-proximal",
                                                  "right-hand-ring-phalanx-intermediate",
                                                  "right-hand-ring-phalanx-distal",
                                                  "right-hand-ring-tip",
                                                  "right-hand-little-metacarpal",
                                                  "right-hand-little-phalanx-proximal",
                                                  "right-hand-little-phalanx-intermediate",
                                                  "right-hand-little-phalanx-distal",
                                                  "right-hand-little-tip",
                                                  "left-upper-leg",
                                                  "left-lower-leg",
                                                  "left-foot-ankle-twist",
                                                  "left-foot-ankle",
                                                  "left-foot-subtalar",
                                                  "left-foot-transverse",
                                                  "left-foot-ball",
                                                  "right-upper-leg",
                                                  "right-lower-leg",
                                                  "right-foot-ankle-twist",
                                                  "right-foot-ankle",
                                                  "right-foot-subtalar",
                                                  "right-foot-transverse",
                                                  "right-foot-ball"};
  std::vector<int> base_index;
  for (int i = 0; i < static_cast<int>(kNames.size()); ++i) base_index.push_back(i + 1);
  return DeriveJointSet(MetaFullBodyJointSet(), "webxr-body", "WebXR body tracking (XRBodyJoint)",
                        "https://github.com/immersive-web/body-tracking index.bs, enum "
                        "XRBodyJoint (W3C Software and Document License)",
                        kNames, base_index);
}

}  // namespace sweptccd::internal
