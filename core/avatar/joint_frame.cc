#include "core/avatar/joint_frame.h"

#include <cmath>
#include <cstdio>
#include <nlohmann/json.hpp>
#include <utility>

#include "core/errors.h"
#include "core/json_text.h"

namespace sweptccd {

namespace {

using nlohmann::json;

std::string Metres(double v) {
  char buf[32];
  std::snprintf(buf, sizeof(buf), "%.4f m", v);
  return buf;
}

std::string JointLabel(const JointSet& set, int j) {
  return "joint " + std::to_string(j) + " (" + set.joints[j].name + ")";
}

// The problem of one joint sample a link needs, or "".
std::string JointProblem(const JointSample& s) {
  if (!s.valid) return "not tracked (null or valid: false)";
  for (int k = 0; k < 3; ++k) {
    if (!std::isfinite(s.p[k])) return "non-finite position";
    if (std::abs(s.p[k]) > kMaxCoordinate) return "position beyond 1e9 m";
  }
  const double q[4] = {s.q.w(), s.q.x(), s.q.y(), s.q.z()};
  for (double v : q) {
    if (!std::isfinite(v)) return "non-finite quaternion";
  }
  const double norm = s.q.norm();
  if (!(norm >= kMinQuaternionNorm)) return "quaternion norm below 1e-6";
  return "";
}

const Eigen::Vector3d kAxis(0, 1, 0);  // A link's bone axis in its own frame.

// The bone vector of link `l` in `frame` (joint_a to joint_b, or the
// extension's direction from joint_from to joint_a), or zero for a sphere.
Eigen::Vector3d BoneVector(const LinkDef& l, const JointFrame& frame) {
  const Eigen::Vector3d& a = frame.joints[l.joint_a].p;
  if (l.joint_b >= 0) return frame.joints[l.joint_b].p - a;
  if (l.joint_from >= 0) return a - frame.joints[l.joint_from].p;
  return Eigen::Vector3d::Zero();
}

}  // namespace

uint64_t MaxJointFrameLineBytes(int num_joints) {
  return 4096 + static_cast<uint64_t>(num_joints) * (8 * 64 + 8);
}

std::optional<JointFrame> ParseJointFrameLine(const std::string& line, int num_joints,
                                              std::string* error) {
  error->clear();
  if (line.size() > MaxJointFrameLineBytes(num_joints)) {
    *error = "longer than " + std::to_string(MaxJointFrameLineBytes(num_joints)) + " bytes";
    return std::nullopt;
  }
  if (std::string nul = NulByteProblem(line); !nul.empty()) {
    *error = "not JSON: " + nul;
    return std::nullopt;
  }
  const json doc = json::parse(line, nullptr, /*allow_exceptions=*/false);
  if (doc.is_discarded() || !doc.is_object()) {
    *error = "not a JSON object";
    return std::nullopt;
  }
  JointFrame frame;
  const auto utime = doc.find("utime");
  if (utime == doc.end() || !utime->is_number_integer()) {
    *error = "utime: missing or not an integer";
    return std::nullopt;
  }
  frame.utime = utime->get<int64_t>();
  const auto joints = doc.find("joints");
  if (joints == doc.end() || !joints->is_array()) {
    *error = "joints: missing or not an array";
    return std::nullopt;
  }
  if (static_cast<int>(joints->size()) != num_joints) {
    *error = "joints: " + std::to_string(joints->size()) + " entries, the joint set has " +
             std::to_string(num_joints);
    return std::nullopt;
  }
  // Optional per-joint arrays of the same length.
  auto optional_array = [&](const char* key) -> const json* {
    const auto it = doc.find(key);
    if (it == doc.end()) return nullptr;
    if (!it->is_array() || static_cast<int>(it->size()) != num_joints) {
      *error = std::string(key) + ": not an array of " + std::to_string(num_joints) + " entries";
      return &*it;
    }
    return &*it;
  };
  const json* valid = optional_array("valid");
  const json* radii = optional_array("radii");
  if (!error->empty()) return std::nullopt;
  frame.joints.resize(num_joints);
  for (int j = 0; j < num_joints; ++j) {
    JointSample& s = frame.joints[j];
    const json& e = (*joints)[j];
    if (e.is_null()) {
      s.valid = false;
    } else if (e.is_array() && e.size() == 7) {
      double v[7];
      for (int k = 0; k < 7; ++k) {
        if (!e[k].is_number()) {
          *error = "joints[" + std::to_string(j) + "]: not 7 numbers";
          return std::nullopt;
        }
        v[k] = e[k].get<double>();
      }
      s.p = Eigen::Vector3d(v[0], v[1], v[2]);
      s.q = Eigen::Quaterniond(v[3], v[4], v[5], v[6]);
    } else {
      *error = "joints[" + std::to_string(j) + "]: not 7 numbers or null";
      return std::nullopt;
    }
    if (valid != nullptr) {
      if (!(*valid)[j].is_boolean()) {
        *error = "valid[" + std::to_string(j) + "]: not true or false";
        return std::nullopt;
      }
      s.valid = s.valid && (*valid)[j].get<bool>();
    }
    if (radii != nullptr && !(*radii)[j].is_null()) {
      if (!(*radii)[j].is_number()) {
        *error = "radii[" + std::to_string(j) + "]: not a number or null";
        return std::nullopt;
      }
      s.radius = (*radii)[j].get<double>();
    }
  }
  return frame;
}

std::string JointFrameToJsonLine(const JointFrame& frame) {
  json joints = json::array(), valid = json::array(), radii = json::array();
  bool any_radius = false;
  for (const JointSample& s : frame.joints) {
    joints.push_back({s.p.x(), s.p.y(), s.p.z(), s.q.w(), s.q.x(), s.q.y(), s.q.z()});
    valid.push_back(s.valid);
    if (std::isfinite(s.radius)) {
      radii.push_back(s.radius);
      any_radius = true;
    } else {
      radii.push_back(nullptr);
    }
  }
  json doc = {{"utime", frame.utime}, {"joints", joints}, {"valid", valid}};
  if (any_radius) doc["radii"] = radii;
  return doc.dump();
}

JointSkeleton JointSkeleton::Build(const JointSet& set, const JointSkeletonOptions& options) {
  if (!(options.height_m >= 0.5 && options.height_m <= 2.5)) {
    throw InputError("--height: " + std::to_string(options.height_m) + " m is outside 0.5..2.5 m");
  }
  if (!(options.length_tolerance_m >= 0) || !(options.length_tolerance_fraction >= 0)) {
    throw InputError("--length-tolerance: must be >= 0");
  }
  JointSkeleton out;
  out.set_ = &set;
  out.options_ = options;
  out.options_.calibration = nullptr;
  out.plan_ = PlanLinks(set, options.hands);
  if (out.plan_.empty()) {
    throw InputError(set.id + ": --hands none leaves no links (the set has only hand joints)");
  }
  out.used_.assign(set.joints.size(), false);
  for (const PlannedLink& pl : out.plan_) {
    for (int j : {pl.def->joint_a, pl.def->joint_b, pl.def->joint_from}) {
      if (j >= 0) out.used_[j] = true;
    }
  }
  const JointFrame* cal = options.calibration;
  if (cal != nullptr) {
    if (static_cast<int>(cal->joints.size()) != set.num_joints()) {
      throw InputError("calibration frame: " + std::to_string(cal->joints.size()) +
                       " joints, the joint set " + set.id + " has " +
                       std::to_string(set.num_joints()));
    }
    for (int j = 0; j < set.num_joints(); ++j) {
      if (!out.used_[j]) continue;
      if (std::string p = JointProblem(cal->joints[j]); !p.empty()) {
        throw InputError("calibration frame: " + JointLabel(set, j) + ": " + p);
      }
    }
  }
  const double h = options.height_m;
  std::vector<Link> links;
  for (const PlannedLink& pl : out.plan_) {
    const LinkDef& d = *pl.def;
    double length = d.length_per_height * h;
    if (cal != nullptr && d.joint_b >= 0 && !d.fixed_length) length = BoneVector(d, *cal).norm();
    if (d.joint_b < 0 && d.joint_from < 0) length = 0;
    double radius = d.radius_per_height * h;
    if (cal != nullptr && set.runtime_radii) {
      double r = 0;
      for (int j : {d.joint_a, d.joint_b}) {
        if (j >= 0 && std::isfinite(cal->joints[j].radius) && cal->joints[j].radius > 0) {
          r = std::max(r, cal->joints[j].radius);
        }
      }
      if (r > 0) radius = r;
    }
    Link link;
    link.name = d.name;
    link.parent = pl.parent;
    link.a_L = Eigen::Vector3d::Zero();
    link.b_L = length * kAxis;
    link.radius = radius;
    links.push_back(link);
    out.length_.push_back(length);
  }
  out.skeleton_ = Skeleton::FromLinks(set.id, std::move(links), set.id);
  return out;
}

std::string JointSkeleton::Convert(const JointFrame& frame, Pose* pose) const {
  const JointSet& set = *set_;
  if (static_cast<int>(frame.joints.size()) != set.num_joints()) {
    return "expected " + std::to_string(set.num_joints()) + " joints (" + set.id + "), got " +
           std::to_string(frame.joints.size());
  }
  for (int j = 0; j < set.num_joints(); ++j) {
    if (!used_[j]) continue;
    if (std::string p = JointProblem(frame.joints[j]); !p.empty()) {
      return JointLabel(set, j) + ": " + p;
    }
  }
  Pose out;
  out.utime = frame.utime;
  out.links.resize(plan_.size());
  for (size_t i = 0; i < plan_.size(); ++i) {
    const LinkDef& d = *plan_[i].def;
    const JointSample& a = frame.joints[d.joint_a];
    const Eigen::Quaterniond q_a = a.q.normalized();
    const Eigen::Vector3d bone = BoneVector(d, frame);
    const double bone_length = bone.norm();
    if (d.joint_b >= 0 && !d.fixed_length) {
      const double tolerance =
          std::max(options_.length_tolerance_m, options_.length_tolerance_fraction * length_[i]);
      if (!(std::abs(bone_length - length_[i]) <= tolerance)) {
        return "link " + std::to_string(i) + " (" + d.name + "): joints " + Metres(bone_length) +
               " apart, the skeleton's bone is " + Metres(length_[i]) + " (tolerance " +
               Metres(tolerance) + "): build the skeleton from a calibration frame of this user";
      }
    }
    LinkPose& lp = out.links[i];
    lp.p = a.p;
    // A sphere, or a bone too short to have a direction: joint_a's frame.
    lp.q = q_a;
    if (bone_length > 1e-9 && (d.joint_b >= 0 || d.joint_from >= 0)) {
      const Eigen::Vector3d axis_W = q_a * kAxis;
      lp.q = Eigen::Quaterniond::FromTwoVectors(axis_W, bone / bone_length) * q_a;
    }
  }
  if (std::string p = ValidateAndNormalizePose(&out, static_cast<int>(plan_.size())); !p.empty()) {
    return p;
  }
  *pose = std::move(out);
  return "";
}

}  // namespace sweptccd
