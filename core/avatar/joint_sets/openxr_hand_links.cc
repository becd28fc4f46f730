#include "core/avatar/joint_sets/openxr_hand_links.h"

#include "core/avatar/joint_sets/anthropometry.h"

namespace sweptccd::internal {

void AddOpenXrHand(JointSetBuilder* b, const HandJointName& name) {
  using anthro::kFingers;
  const std::string wrist = name("WRIST");
  const std::string palm = name("PALM");
  if (!palm.empty()) b->Parent(palm, wrist);
  b->Toward(wrist, name("MIDDLE_PROXIMAL"), HandPart::kHandSimple, anthro::kSimpleHandLength,
            anthro::kSimpleHandRadius);
  for (const anthro::FingerDefaults& f : kFingers) {
    const std::string finger = f.name;
    std::vector<std::string> chain = {name(finger + "_METACARPAL"), name(finger + "_PROXIMAL")};
    std::vector<int> seg = {0};
    if (finger == "THUMB") {
      chain.push_back(name("THUMB_DISTAL"));
      seg.push_back(1);
    } else {
      chain.push_back(name(finger + "_INTERMEDIATE"));
      chain.push_back(name(finger + "_DISTAL"));
      seg.push_back(1);
      seg.push_back(2);
    }
    chain.push_back(name(finger + "_TIP"));
    seg.push_back(3);
    b->Parent(chain[0], wrist);
    b->Bone(wrist, chain[0], HandPart::kHandFull, anthro::kCarpal, anthro::kCarpalRadius);
    for (size_t i = 1; i < chain.size(); ++i) {
      b->Parent(chain[i], chain[i - 1]);
      const int s = seg[i - 1];
      b->Bone(chain[i - 1], chain[i], HandPart::kHandFull, f.length[s], f.radius[s]);
    }
  }
  // After the fingers: a hand-only skeleton's root is the thumb's carpal bone.
  if (!palm.empty()) b->Sphere(palm, HandPart::kHandFull, anthro::kPalmRadius);
}

}  // namespace sweptccd::internal
