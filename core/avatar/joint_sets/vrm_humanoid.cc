// VRM 1.0 humanoid: 55 bones (VRMC_vrm humanoid.humanBones).
// Enumeration and parents: https://github.com/vrm-c/vrm-specification,
// specification/VRMC_vrm-1.0/humanoid.md (commit
// 3942748efbc803b258e288e0f6c993c6bb96cebf, 2026-01-30), the "Bone Name" and
// "Parent Bone" columns of its tables, in the document's order (torso, head,
// legs, arms, fingers). The repository carries no licence file; only the
// bone names and their parents (facts of the format) are used. A VRM bone is
// a node at a joint: a link runs from a bone to its child bone; the head, the
// toes and each finger's distal bone end in an extension along the bone
// before them. The eyes and the jaw are inside the head's capsule (no link).
// Optional bones (chest, upperChest, shoulders, toes, fingers) must be
// present in a joint frame, like every other joint: a model without them
// has no frame for this table.

#include <string>
#include <utility>
#include <vector>

#include "core/avatar/joint_set.h"
#include "core/avatar/joint_sets/anthropometry.h"

namespace sweptccd::internal {

namespace {

// The bones and their parents ("" for the root), in the specification's order.
const std::vector<std::pair<std::string, std::string>>& VrmBones() {
  static const std::vector<std::pair<std::string, std::string>> kBones = {
      {"hips", ""},
      {"spine", "hips"},
      {"chest", "spine"},
      {"upperChest", "chest"},
      {"neck", "upperChest"},
      {"head", "neck"},
      {"leftEye", "head"},
      {"rightEye", "head"},
      {"jaw", "head"},
      {"leftUpperLeg", "hips"},
      {"leftLowerLeg", "leftUpperLeg"},
      {"leftFoot", "leftLowerLeg"},
      {"leftToes", "leftFoot"},
      {"rightUpperLeg", "hips"},
      {"rightLowerLeg", "rightUpperLeg"},
      {"rightFoot", "rightLowerLeg"},
      {"rightToes", "rightFoot"},
      {"leftShoulder", "upperChest"},
      {"leftUpperArm", "leftShoulder"},
      {"leftLowerArm", "leftUpperArm"},
      {"leftHand", "leftLowerArm"},
      {"rightShoulder", "upperChest"},
      {"rightUpperArm", "rightShoulder"},
      {"rightLowerArm", "rightUpperArm"},
      {"rightHand", "rightLowerArm"},
      {"leftThumbMetacarpal", "leftHand"},
      {"leftThumbProximal", "leftThumbMetacarpal"},
      {"leftThumbDistal", "leftThumbProximal"},
      {"leftIndexProximal", "leftHand"},
      {"leftIndexIntermediate", "leftIndexProximal"},
      {"leftIndexDistal", "leftIndexIntermediate"},
      {"leftMiddleProximal", "leftHand"},
      {"leftMiddleIntermediate", "leftMiddleProximal"},
      {"leftMiddleDistal", "leftMiddleIntermediate"},
      {"leftRingProximal", "leftHand"},
      {"leftRingIntermediate", "leftRingProximal"},
      {"leftRingDistal", "leftRingIntermediate"},
      {"leftLittleProximal", "leftHand"},
      {"leftLittleIntermediate", "leftLittleProximal"},
      {"leftLittleDistal", "leftLittleIntermediate"},
      {"rightThumbMetacarpal", "rightHand"},
      {"rightThumbProximal", "rightThumbMetacarpal"},
      {"rightThumbDistal", "rightThumbProximal"},
      {"rightIndexProximal", "rightHand"},
      {"rightIndexIntermediate", "rightIndexProximal"},
      {"rightIndexDistal", "rightIndexIntermediate"},
      {"rightMiddleProximal", "rightHand"},
      {"rightMiddleIntermediate", "rightMiddleProximal"},
      {"rightMiddleDistal", "rightMiddleIntermediate"},
      {"rightRingProximal", "rightHand"},
      {"rightRingIntermediate", "rightRingProximal"},
      {"rightRingDistal", "rightRingIntermediate"},
      {"rightLittleProximal", "rightHand"},
      {"rightLittleIntermediate", "rightLittleProximal"},
      {"rightLittleDistal", "rightLittleIntermediate"},
  };
  return kBones;
}

}  // namespace

JointSet VrmHumanoidJointSet() {
  namespace a = anthro;
  const std::vector<std::pair<std::string, std::string>>& kBones = VrmBones();
  JointSetBuilder b("vrm-humanoid", "VRM 1.0 humanoid",
                    "https://github.com/vrm-c/vrm-specification "
                    "specification/VRMC_vrm-1.0/humanoid.md",
                    /*runtime_radii=*/false);
  std::vector<std::string> names;
  for (const auto& [name, parent] : kBones) names.push_back(name);
  b.Joints(names);
  for (const auto& [name, parent] : kBones) {
    if (!parent.empty()) b.Parent(name, parent);
  }
  const HandPart body = HandPart::kBody;
  b.Bone("hips", "spine", body, 0.06, a::kTorsoRadius);
  b.Bone("spine", "chest", body, 0.08, a::kTorsoRadius);
  b.Bone("chest", "upperChest", body, 0.08, a::kTorsoRadius);
  b.Bone("upperChest", "neck", body, a::kPelvisToNeck - 0.22, a::kUpperChestRadius);
  b.Bone("neck", "head", body, a::kNeck, a::kNeckRadius);
  b.Extension("neck", "head", body, a::kHead, a::kHeadRadius);
  const char* kFingerWords[5][2] = {{"Thumb", "THUMB"},
                                    {"Index", "INDEX"},
                                    {"Middle", "MIDDLE"},
                                    {"Ring", "RING"},
                                    {"Little", "LITTLE"}};
  for (const std::string side : {"left", "right"}) {
    b.Bone("upperChest", side + "Shoulder", body, a::kHalfShoulder * 0.6, a::kShoulderRadius);
    b.Bone(side + "Shoulder", side + "UpperArm", body, a::kHalfShoulder * 0.4, a::kShoulderRadius);
    b.Bone(side + "UpperArm", side + "LowerArm", body, a::kUpperArm, a::kUpperArmRadius);
    b.Bone(side + "LowerArm", side + "Hand", body, a::kForearm, a::kForearmRadius);
    const std::string hand = side + "Hand";
    b.Toward(hand, side + "MiddleProximal", HandPart::kHandSimple, a::kSimpleHandLength,
             a::kSimpleHandRadius);
    for (int f = 0; f < 5; ++f) {
      const a::FingerDefaults& d = a::kFingers[f];
      const std::string base = side + kFingerWords[f][0];
      const HandPart full = HandPart::kHandFull;
      if (f == 0) {
        // Thumb: metacarpal, proximal, distal (VRM 1.0 names).
        b.Bone(hand, base + "Metacarpal", full, a::kCarpal, a::kCarpalRadius);
        b.Bone(base + "Metacarpal", base + "Proximal", full, d.length[0], d.radius[0]);
        b.Bone(base + "Proximal", base + "Distal", full, d.length[1], d.radius[1]);
        b.Extension(base + "Proximal", base + "Distal", full, d.length[3], d.radius[3]);
      } else {
        // Fingers: the metacarpal bone from the hand, proximal,
        // intermediate, distal.
        b.Bone(hand, base + "Proximal", full, a::kCarpal + d.length[0], d.radius[0]);
        b.Bone(base + "Proximal", base + "Intermediate", full, d.length[1], d.radius[1]);
        b.Bone(base + "Intermediate", base + "Distal", full, d.length[2], d.radius[2]);
        b.Extension(base + "Intermediate", base + "Distal", full, d.length[3], d.radius[3]);
      }
    }
  }
  for (const std::string side : {"left", "right"}) {
    b.Bone("hips", side + "UpperLeg", body, a::kHalfHip, a::kPelvisSideRadius);
    b.Bone(side + "UpperLeg", side + "LowerLeg", body, a::kThigh, a::kThighRadius);
    b.Bone(side + "LowerLeg", side + "Foot", body, a::kShank, a::kShankRadius);
    b.Bone(side + "Foot", side + "Toes", body, a::kFoot, a::kFootRadius);
    b.Extension(side + "Foot", side + "Toes", body, a::kToes, a::kToesRadius);
  }
  return b.Build();
}

}  // namespace sweptccd::internal
