// WebXR hand input: 25 joints per hand (enum XRHandJoint), each with a
// radius (XRJointPose.radius).
// Enumeration: https://github.com/immersive-web/webxr-hand-input, index.bs
// (commit 940a91869d6a52582347fdf3ec4719925ce3e3a6, 2024-02-07; WebXR Hand
// Input Module - Level 1, https://www.w3.org/TR/webxr-hand-input-1/), W3C
// Software and Document License. The names below are that enum's strings in
// its order, verbatim. OpenXR's hand joints without the palm, so the links
// are the OpenXR hand's (openxr_hand_links.cc). One hand per skeleton.

#include <string>
#include <vector>

#include "core/avatar/joint_set.h"
#include "core/avatar/joint_sets/openxr_hand_links.h"

namespace sweptccd::internal {

JointSet WebXrHandJointSet() {
  JointSetBuilder b("webxr-hand", "WebXR hand input (XRHandJoint, one hand)",
                    "https://github.com/immersive-web/webxr-hand-input index.bs, enum "
                    "XRHandJoint (W3C Software and Document License)",
                    /*runtime_radii=*/true);
  b.Joints({"wrist",
            "thumb-metacarpal",
            "thumb-phalanx-proximal",
            "thumb-phalanx-distal",
            "thumb-tip",
            "index-finger-metacarpal",
            "index-finger-phalanx-proximal",
            "index-finger-phalanx-intermediate",
            "index-finger-phalanx-distal",
            "index-finger-tip",
            "middle-finger-metacarpal",
            "middle-finger-phalanx-proximal",
            "middle-finger-phalanx-intermediate",
            "middle-finger-phalanx-distal",
            "middle-finger-tip",
            "ring-finger-metacarpal",
            "ring-finger-phalanx-proximal",
            "ring-finger-phalanx-intermediate",
            "ring-finger-phalanx-distal",
            "ring-finger-tip",
            "pinky-finger-metacarpal",
            "pinky-finger-phalanx-proximal",
            "pinky-finger-phalanx-intermediate",
            "pinky-finger-phalanx-distal",
            "pinky-finger-tip"});
  AddOpenXrHand(&b, [](const std::string& word) -> std::string {
    if (word == "PALM") return "";
    if (word == "WRIST") return "wrist";
    const size_t cut = word.find('_');
    const std::string finger = word.substr(0, cut);
    const std::string part = word.substr(cut + 1);
    std::string f = finger == "THUMB"    ? "thumb"
                    : finger == "INDEX"  ? "index-finger"
                    : finger == "MIDDLE" ? "middle-finger"
                    : finger == "RING"   ? "ring-finger"
                                         : "pinky-finger";
    std::string p = part == "METACARPAL"     ? "metacarpal"
                    : part == "PROXIMAL"     ? "phalanx-proximal"
                    : part == "INTERMEDIATE" ? "phalanx-intermediate"
                    : part == "DISTAL"       ? "phalanx-distal"
                                             : "tip";
    return f + "-" + p;
  });
  return b.Build();
}

}  // namespace sweptccd::internal
