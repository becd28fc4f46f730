#include "core/avatar/joint_set.h"

#include <cstdio>
#include <cstdlib>
#include <utility>

#include "core/errors.h"

namespace sweptccd {

int JointSet::FindJoint(const std::string& name) const {
  for (int i = 0; i < num_joints(); ++i) {
    if (joints[i].name == name) return i;
  }
  return -1;
}

std::vector<PlannedLink> PlanLinks(const JointSet& set, HandsOption hands) {
  bool has_full = false;
  for (const LinkDef& l : set.links) has_full = has_full || l.part == HandPart::kHandFull;
  const bool use_full = hands == HandsOption::kFull && has_full;
  const bool use_simple =
      hands == HandsOption::kSimple || (hands == HandsOption::kFull && !has_full);
  std::vector<PlannedLink> out;
  for (const LinkDef& l : set.links) {
    const bool keep = l.part == HandPart::kBody || (l.part == HandPart::kHandFull && use_full) ||
                      (l.part == HandPart::kHandSimple && use_simple);
    if (keep) out.push_back({&l, -1});
  }
  int root = -1;
  for (int i = 0; i < static_cast<int>(out.size()); ++i) {
    int parent = -1;
    for (int j = out[i].def->joint_a; j >= 0 && parent < 0; j = set.joints[j].parent) {
      for (int k = 0; k < static_cast<int>(out.size()) && parent < 0; ++k) {
        if (k != i && out[k].def->joint_b == j) parent = k;
      }
      for (int k = 0; k < i && parent < 0; ++k) {
        if (out[k].def->joint_a == j) parent = k;
      }
    }
    if (parent < 0 && root < 0) {
      root = i;
    } else if (parent < 0) {
      parent = root;
    }
    out[i].parent = parent;
  }
  return out;
}

std::vector<std::string> JointSetIds() {
  std::vector<std::string> ids;
  for (const char* id : {"meta-full-body", "fb-body", "webxr-body", "htc-body", "bd-body",
                         "ext-hand", "webxr-hand", "vrm-humanoid"}) {
    ids.emplace_back(id);
  }
  return ids;
}

const JointSet& FindJointSet(const std::string& id) {
  // Built once, on first use (thread-safe static initialisation).
  static const std::vector<JointSet> kSets = [] {
    std::vector<JointSet> sets;
    sets.push_back(internal::MetaFullBodyJointSet());
    sets.push_back(internal::FbBodyJointSet());
    sets.push_back(internal::WebXrBodyJointSet());
    sets.push_back(internal::HtcBodyJointSet());
    sets.push_back(internal::BdBodyJointSet());
    sets.push_back(internal::ExtHandJointSet());
    sets.push_back(internal::WebXrHandJointSet());
    sets.push_back(internal::VrmHumanoidJointSet());
    return sets;
  }();
  for (const JointSet& s : kSets) {
    if (s.id == id) return s;
  }
  std::string known;
  for (const std::string& k : JointSetIds()) known += (known.empty() ? "" : ", ") + k;
  throw InputError("unknown joint set '" + id + "' (known: " + known + ")");
}

HandsOption ParseHandsOption(const std::string& name) {
  if (name == "none") return HandsOption::kNone;
  if (name == "simple") return HandsOption::kSimple;
  if (name == "full") return HandsOption::kFull;
  throw InputError("--hands: '" + name + "' is not none, simple or full");
}

namespace internal {

JointSetBuilder::JointSetBuilder(std::string id, std::string title, std::string source,
                                 bool runtime_radii) {
  set_.id = std::move(id);
  set_.title = std::move(title);
  set_.source = std::move(source);
  set_.runtime_radii = runtime_radii;
}

int JointSetBuilder::Index(const std::string& name) const {
  const int i = set_.FindJoint(name);
  if (i < 0) {
    std::fprintf(stderr, "joint set %s: no joint named %s\n", set_.id.c_str(), name.c_str());
    std::abort();
  }
  return i;
}

JointSetBuilder& JointSetBuilder::Joints(const std::vector<std::string>& names) {
  for (const std::string& n : names) set_.joints.push_back({n, -1});
  return *this;
}

JointSetBuilder& JointSetBuilder::Parent(const std::string& child, const std::string& parent) {
  set_.joints[Index(child)].parent = Index(parent);
  return *this;
}

JointSetBuilder& JointSetBuilder::Toward(const std::string& a, const std::string& b, HandPart part,
                                         double length_per_height, double radius_per_height) {
  LinkDef l{a + ">" + b + "~", Index(a),         Index(b), -1, part, true,
            length_per_height, radius_per_height};
  set_.links.push_back(l);
  return *this;
}

JointSetBuilder& JointSetBuilder::Bone(const std::string& a, const std::string& b, HandPart part,
                                       double length_per_height, double radius_per_height) {
  set_.links.push_back(
      {a + ">" + b, Index(a), Index(b), -1, part, false, length_per_height, radius_per_height});
  return *this;
}

JointSetBuilder& JointSetBuilder::Extension(const std::string& from, const std::string& a,
                                            HandPart part, double length_per_height,
                                            double radius_per_height) {
  set_.links.push_back(
      {a + ">end", Index(a), -1, Index(from), part, false, length_per_height, radius_per_height});
  return *this;
}

JointSetBuilder& JointSetBuilder::Sphere(const std::string& a, HandPart part,
                                         double radius_per_height) {
  set_.links.push_back({a, Index(a), -1, -1, part, false, 0, radius_per_height});
  return *this;
}

JointSet JointSetBuilder::Build() { return std::move(set_); }

JointSet DeriveJointSet(const JointSet& base, std::string id, std::string title, std::string source,
                        const std::vector<std::string>& names, const std::vector<int>& base_index) {
  JointSet out;
  out.id = std::move(id);
  out.title = std::move(title);
  out.source = std::move(source);
  out.runtime_radii = base.runtime_radii;
  std::vector<int> new_index(base.joints.size(), -1);
  for (size_t i = 0; i < names.size(); ++i) new_index[base_index[i]] = static_cast<int>(i);
  for (size_t i = 0; i < names.size(); ++i) {
    int p = base.joints[base_index[i]].parent;
    while (p >= 0 && new_index[p] < 0) p = base.joints[p].parent;
    out.joints.push_back({names[i], p >= 0 ? new_index[p] : -1});
  }
  auto map = [&](int j) { return j >= 0 ? new_index[j] : -1; };
  auto name = [&](int j) { return out.joints[j].name; };
  for (const LinkDef& l : base.links) {
    const bool kept = new_index[l.joint_a] >= 0 && (l.joint_b < 0 || new_index[l.joint_b] >= 0) &&
                      (l.joint_from < 0 || new_index[l.joint_from] >= 0);
    if (!kept) continue;
    LinkDef d = l;
    d.joint_a = map(l.joint_a);
    d.joint_b = map(l.joint_b);
    d.joint_from = map(l.joint_from);
    if (d.joint_b >= 0) {
      d.name = name(d.joint_a) + ">" + name(d.joint_b) + (d.fixed_length ? "~" : "");
    } else if (d.joint_from >= 0) {
      d.name = name(d.joint_a) + ">end";
    } else {
      d.name = name(d.joint_a);
    }
    out.links.push_back(d);
  }
  return out;
}

}  // namespace internal
}  // namespace sweptccd
