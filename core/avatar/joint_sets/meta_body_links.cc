#include "core/avatar/joint_sets/meta_body_links.h"

#include "core/avatar/joint_sets/anthropometry.h"
#include "core/avatar/joint_sets/openxr_hand_links.h"

namespace sweptccd::internal {

void AddMetaBody(JointSetBuilder* b, const MetaJointName& n) {
  namespace a = anthro;
  const HandPart body = HandPart::kBody;
  // The spine, from the floor (ROOT, no link) up.
  const char* spine[] = {"ROOT",        "HIPS",  "SPINE_LOWER", "SPINE_MIDDLE",
                         "SPINE_UPPER", "CHEST", "NECK",        "HEAD"};
  for (int i = 1; i < 8; ++i) b->Parent(n(spine[i]), n(spine[i - 1]));
  const double spine_len[] = {0.05, 0.06, 0.06, 0.05, a::kPelvisToNeck - 0.22};
  for (int i = 1; i < 6; ++i) {
    b->Bone(n(spine[i]), n(spine[i + 1]), body, spine_len[i - 1],
            i < 5 ? a::kTorsoRadius : a::kUpperChestRadius);
  }
  b->Bone(n("NECK"), n("HEAD"), body, a::kNeck, a::kNeckRadius);
  b->Extension(n("NECK"), n("HEAD"), body, a::kHead, a::kHeadRadius);
  for (const std::string side : {"LEFT", "RIGHT"}) {
    auto s = [&](const std::string& w) { return n(side + "_" + w); };
    // The arm: chest, shoulder (clavicle), scapula, upper arm (the shoulder
    // joint), lower arm (the elbow), the wrist twist and the wrist.
    b->Parent(s("SHOULDER"), n("CHEST"));
    b->Parent(s("SCAPULA"), s("SHOULDER"));
    b->Parent(s("ARM_UPPER"), s("SCAPULA"));
    b->Parent(s("ARM_LOWER"), s("ARM_UPPER"));
    b->Parent(s("HAND_WRIST_TWIST"), s("ARM_LOWER"));
    b->Parent(s("HAND_WRIST"), s("HAND_WRIST_TWIST"));
    b->Bone(n("CHEST"), s("SHOULDER"), body, a::kHalfShoulder * 0.3, a::kShoulderRadius);
    b->Bone(s("SHOULDER"), s("SCAPULA"), body, a::kHalfShoulder * 0.3, a::kShoulderRadius);
    b->Bone(s("SCAPULA"), s("ARM_UPPER"), body, a::kHalfShoulder * 0.4, a::kShoulderRadius);
    b->Bone(s("ARM_UPPER"), s("ARM_LOWER"), body, a::kUpperArm, a::kUpperArmRadius);
    b->Bone(s("ARM_LOWER"), s("HAND_WRIST"), body, a::kForearm, a::kForearmRadius);
    AddOpenXrHand(b, [&](const std::string& w) { return s("HAND_" + w); });
    // The leg: hip joint, knee, ankle twist, ankle, subtalar, transverse
    // (midfoot), ball of the foot.
    b->Parent(s("UPPER_LEG"), n("HIPS"));
    b->Parent(s("LOWER_LEG"), s("UPPER_LEG"));
    b->Parent(s("FOOT_ANKLE_TWIST"), s("LOWER_LEG"));
    b->Parent(s("FOOT_ANKLE"), s("FOOT_ANKLE_TWIST"));
    b->Parent(s("FOOT_SUBTALAR"), s("FOOT_ANKLE"));
    b->Parent(s("FOOT_TRANSVERSE"), s("FOOT_SUBTALAR"));
    b->Parent(s("FOOT_BALL"), s("FOOT_TRANSVERSE"));
  }
  for (const std::string side : {"LEFT", "RIGHT"}) {
    auto s = [&](const std::string& w) { return n(side + "_" + w); };
    b->Bone(n("HIPS"), s("UPPER_LEG"), body, a::kHalfHip, a::kPelvisSideRadius);
    b->Bone(s("UPPER_LEG"), s("LOWER_LEG"), body, a::kThigh, a::kThighRadius);
    b->Bone(s("LOWER_LEG"), s("FOOT_ANKLE"), body, a::kShank, a::kShankRadius);
    b->Bone(s("FOOT_ANKLE"), s("FOOT_SUBTALAR"), body, a::kFoot * 0.15, a::kFootRadius);
    b->Bone(s("FOOT_SUBTALAR"), s("FOOT_TRANSVERSE"), body, a::kFoot * 0.4, a::kFootRadius);
    b->Bone(s("FOOT_TRANSVERSE"), s("FOOT_BALL"), body, a::kFoot * 0.45, a::kFootRadius);
    b->Extension(s("FOOT_TRANSVERSE"), s("FOOT_BALL"), body, a::kToes, a::kToesRadius);
  }
}

}  // namespace sweptccd::internal
