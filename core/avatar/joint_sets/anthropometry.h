#pragma once
// Default link lengths and radii as fractions of the user's height, for
// joint sets whose runtime gives no radii and skeletons built without a
// calibration frame (docs/SKELETONS.md, "Defaults").
//
// Lengths of the long bones: Drillis and Contini (1966), segment lengths as
// fractions of height H, as tabulated in D. A. Winter, "Biomechanics and
// Motor Control of Human Movement", 4th ed. (2009), Fig. 4.1: upper arm
// 0.186 H, forearm 0.146 H, hand 0.108 H, thigh 0.245 H, shank 0.246 H,
// foot length 0.152 H, shoulder width 0.259 H, hip width 0.191 H, neck base
// (shoulder height) 0.818 H, chin 0.870 H. Everything else here (spine
// splits, finger bones, and every radius) is this project's own estimate for
// an adult of 1.75 m (typical segment circumferences / 2 pi, rounded down
// where neighbouring capsules overlap), not a measured table: a runtime's
// radii, or a calibration frame, replace them.

namespace sweptccd::internal::anthro {

// Lengths (fractions of height).
inline constexpr double kUpperArm = 0.186;
inline constexpr double kForearm = 0.146;
inline constexpr double kHand = 0.108;
inline constexpr double kThigh = 0.245;
inline constexpr double kShank = 0.246;
inline constexpr double kHalfShoulder = 0.259 / 2;
inline constexpr double kHalfHip = 0.191 / 2;
inline constexpr double kNeck = 0.870 - 0.818;
inline constexpr double kPelvisToNeck = 0.27;  // Estimate: hip centre to neck base.
inline constexpr double kHead = 0.075;         // Head capsule above the neck joint.
inline constexpr double kFoot = 0.152 * 0.75;  // Ankle to the ball of the foot.
inline constexpr double kToes = 0.152 * 0.2;
// Radii (fractions of height), estimates.
inline constexpr double kTorsoRadius = 0.065;
inline constexpr double kUpperChestRadius = 0.045;
inline constexpr double kNeckRadius = 0.03;
inline constexpr double kHeadRadius = 0.055;
inline constexpr double kShoulderRadius = 0.03;
inline constexpr double kUpperArmRadius = 0.026;
inline constexpr double kForearmRadius = 0.021;
inline constexpr double kPelvisSideRadius = 0.05;
inline constexpr double kThighRadius = 0.04;
inline constexpr double kShankRadius = 0.028;
inline constexpr double kFootRadius = 0.022;
inline constexpr double kToesRadius = 0.015;
inline constexpr double kSimpleHandRadius = 0.026;
inline constexpr double kSimpleHandLength = 0.085;  // Wrist towards the knuckles.
inline constexpr double kPalmRadius = 0.012;
inline constexpr double kCarpalRadius = 0.01;

/// One finger's bones from its metacarpal joint (fractions of height):
/// metacarpal, proximal, intermediate, distal (to the tip); the thumb has no
/// intermediate (0). Estimates from a hand of 0.108 H.
struct FingerDefaults {
  const char* name;  // OpenXR's word: THUMB, INDEX, MIDDLE, RING, LITTLE.
  double length[4];
  double radius[4];
};
inline constexpr double kCarpal = 0.012;  // Wrist to a metacarpal joint.
inline constexpr FingerDefaults kFingers[5] = {
    {"THUMB", {0.026, 0.019, 0, 0.0135}, {0.0065, 0.006, 0, 0.0055}},
    {"INDEX", {0.037, 0.023, 0.0135, 0.011}, {0.006, 0.0055, 0.005, 0.0046}},
    {"MIDDLE", {0.036, 0.026, 0.016, 0.0115}, {0.006, 0.0055, 0.005, 0.0046}},
    {"RING", {0.033, 0.024, 0.015, 0.011}, {0.006, 0.0055, 0.005, 0.0046}},
    {"LITTLE", {0.030, 0.019, 0.011, 0.010}, {0.0055, 0.005, 0.0045, 0.0042}},
};

}  // namespace sweptccd::internal::anthro
