#include "mocap/full_body_frames.h"

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <string>

namespace sweptccd::full_body {

using Eigen::Quaterniond;
using Eigen::Vector3d;

double SmoothStep(double x) {
  x = std::clamp(x, 0.0, 1.0);
  return x * x * (3 - 2 * x);
}

double CycleCurl(double t_s) {
  const double t = std::fmod(t_s, 3.0);
  if (t < 1.0) return 0;
  if (t < 1.4) return SmoothStep((t - 1.0) / 0.4);
  if (t < 2.2) return 1;
  if (t < 2.6) return 1 - SmoothStep((t - 2.2) / 0.4);
  return 0;
}

Quaterniond HandFrame::Basis() const {
  Eigen::Matrix3d m;
  m.col(0) = fwd;
  m.col(1) = lat;
  m.col(2) = normal;
  return Quaterniond(m).normalized();
}

FrameBuilder::FrameBuilder(const JointSet& set, const Skeleton& mocap) : set_(set), mocap_(mocap) {}

int FrameBuilder::Index(const char* link) const {
  const int i = mocap_.FindLink(link);
  if (i < 0) std::abort();
  return i;
}

HandFrame FrameBuilder::Hand(const Pose& pose, bool left) const {
  const int i = Index(left ? "hand_l" : "hand_r");
  HandFrame h;
  h.wrist = pose.links[i].p;
  h.q = pose.links[i].q;
  const Vector3d end = h.wrist + h.q * mocap_.link(i).b_L;
  h.fwd = (end - h.wrist).normalized();
  Vector3d lat = h.q * Vector3d::UnitX();
  lat -= lat.dot(h.fwd) * h.fwd;
  if (lat.norm() < 1e-6) lat = h.fwd.unitOrthogonal();
  h.lat = lat.normalized();
  h.normal = h.fwd.cross(h.lat);
  return h;
}

JointFrame FrameBuilder::Build(const Pose& pose) const {
  const double t = 1e-6 * static_cast<double>(pose.utime);
  return Build(pose, CycleCurl(t + 1.5), CycleCurl(t));
}

namespace {

// Procedural fingers in the hand frame: each finger curls about the lateral
// axis by `curl` (0 open .. 1 closed); the thumb about the palm normal.
template <class Put>
void Fingers(const std::string& s, const HandFrame& hf, double curl, const Put& put) {
  const Vector3d& wrist = hf.wrist;
  const Vector3d& fwd = hf.fwd;
  const Vector3d& lat = hf.lat;
  const Quaterniond& q = hf.q;
  const std::string h = s + "_HAND_";
  put(h + "WRIST", wrist, q);
  put(h + "PALM", wrist + 0.05 * fwd, q);
  struct Finger {
    const char* name;
    double spread;     // Along lat, metres, at the knuckle.
    double meta;       // Wrist to knuckle, metres.
    double bones[3];   // Proximal, intermediate, distal to the tip.
    double angles[3];  // Full curl per joint, radians.
  };
  const Finger fingers[4] = {{"INDEX", 0.025, 0.085, {0.040, 0.024, 0.020}, {1.2, 1.5, 1.0}},
                             {"MIDDLE", 0.007, 0.085, {0.045, 0.027, 0.021}, {1.2, 1.5, 1.0}},
                             {"RING", -0.011, 0.080, {0.042, 0.026, 0.020}, {1.2, 1.5, 1.0}},
                             {"LITTLE", -0.028, 0.072, {0.034, 0.020, 0.018}, {1.2, 1.5, 1.0}}};
  for (const Finger& fg : fingers) {
    const std::string n = h + fg.name;
    put(n + "_METACARPAL", wrist + 0.015 * fwd + 0.5 * fg.spread * lat, q);
    Vector3d p = wrist + fg.meta * fwd + fg.spread * lat;
    put(n + "_PROXIMAL", p, q);
    Quaterniond bend = Quaterniond::Identity();
    const char* parts[3] = {"_INTERMEDIATE", "_DISTAL", "_TIP"};
    for (int k = 0; k < 3; ++k) {
      bend = Quaterniond(Eigen::AngleAxisd(curl * fg.angles[k], lat)) * bend;
      p += fg.bones[k] * (bend * fwd);
      put(n + parts[k], p, bend * q);
    }
  }
  // Thumb: from the wrist's side, along (fwd + lat), curling about the palm
  // normal.
  const Vector3d dir0 = (fwd + lat).normalized();
  Vector3d p = wrist + 0.02 * fwd + 0.02 * lat;
  put(h + "THUMB_METACARPAL", p, q);
  const double lens[3] = {0.045, 0.032, 0.028};
  const char* parts[3] = {"_THUMB_PROXIMAL", "_THUMB_DISTAL", "_THUMB_TIP"};
  Quaterniond bend = Quaterniond::Identity();
  for (int k = 0; k < 3; ++k) {
    p += lens[k] * (bend * dir0);
    put(s + "_HAND" + parts[k], p, bend * q);
    bend = Quaterniond(Eigen::AngleAxisd(-curl * 0.6, hf.normal)) * bend;
  }
}

}  // namespace

JointFrame FrameBuilder::Build(const Pose& pose, double curl_left, double curl_right) const {
  JointFrame f;
  f.utime = pose.utime;
  f.joints.resize(set_.num_joints());
  auto A = [&](const std::string& link) { return pose.links[Index(link.c_str())].p; };
  auto B = [&](const std::string& link) {
    const int i = Index(link.c_str());
    return Vector3d(pose.links[i].p + pose.links[i].q * mocap_.link(i).b_L);
  };
  auto Q = [&](const std::string& link) { return pose.links[Index(link.c_str())].q; };
  auto lerp = [](const Vector3d& a, const Vector3d& b, double s) -> Vector3d {
    return a + s * (b - a);
  };
  auto put = [&](const std::string& word, const Vector3d& p, const Quaterniond& q) {
    const int j = set_.FindJoint("XR_FULL_BODY_JOINT_" + word + "_META");
    if (j < 0) std::abort();
    f.joints[j].p = p;
    f.joints[j].q = q;
  };
  put("ROOT", A("pelvis"), Q("pelvis"));
  put("HIPS", A("pelvis"), Q("pelvis"));
  put("SPINE_LOWER", A("spine"), Q("spine"));
  put("SPINE_MIDDLE", lerp(A("spine"), B("spine"), 0.5), Q("spine"));
  put("SPINE_UPPER", A("chest"), Q("chest"));
  const Vector3d chest = lerp(A("chest"), B("chest"), 0.5);
  put("CHEST", chest, Q("chest"));
  put("NECK", A("head"), Q("head"));
  put("HEAD", lerp(A("head"), B("head"), 0.3), Q("head"));
  for (const bool left : {true, false}) {
    const std::string s = left ? "LEFT" : "RIGHT";
    const std::string x = left ? "_l" : "_r";
    const std::string ua = "upper_arm" + x, fa = "forearm" + x, ha = "hand" + x;
    const std::string th = "thigh" + x, sh = "shin" + x, fo = "foot" + x;
    put(s + "_SHOULDER", lerp(chest, A(ua), 0.3), Q(ua));
    put(s + "_SCAPULA", lerp(chest, A(ua), 0.6), Q(ua));
    put(s + "_ARM_UPPER", A(ua), Q(ua));
    put(s + "_ARM_LOWER", A(fa), Q(fa));
    put(s + "_HAND_WRIST_TWIST", lerp(A(fa), A(ha), 0.8), Q(fa));
    Fingers(s, Hand(pose, left), left ? curl_left : curl_right, put);
    put(s + "_UPPER_LEG", A(th), Q(th));
    put(s + "_LOWER_LEG", A(sh), Q(sh));
    put(s + "_FOOT_ANKLE_TWIST", lerp(A(sh), A(fo), 0.9), Q(sh));
    put(s + "_FOOT_ANKLE", A(fo), Q(fo));
    put(s + "_FOOT_SUBTALAR", lerp(A(fo), B(fo), 0.15), Q(fo));
    put(s + "_FOOT_TRANSVERSE", lerp(A(fo), B(fo), 0.55), Q(fo));
    put(s + "_FOOT_BALL", B(fo), Q(fo));
  }
  return f;
}

JointSkeleton CalibratedFullBody(const JointSet& set, const JointFrame& first) {
  JointSkeletonOptions so;
  so.calibration = &first;
  so.hands = HandsOption::kFull;
  so.length_tolerance_m = 0.05;
  so.length_tolerance_fraction = 0.25;
  return JointSkeleton::Build(set, so);
}

}  // namespace sweptccd::full_body
