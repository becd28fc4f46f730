#pragma once
// Joint sets: the joint enumerations of body and hand tracking runtimes
// (OpenXR, WebXR, VRM) and which joints bound each capsule link
// (docs/SKELETONS.md). The tables are data, one file per joint set in
// core/avatar/joint_sets/, each naming its specification; this file holds
// the types, the registry and the rule that gives each link its parent.

#include <string>
#include <vector>

namespace sweptccd {

/// Which `--hands` option includes a link.
enum class HandPart {
  kBody,        // Always (not a hand link).
  kHandSimple,  // --hands simple: one capsule per hand.
  kHandFull,    // --hands full: the palm and every finger bone.
};

/// How much of the hands a skeleton built from a joint set has.
enum class HandsOption { kNone, kSimple, kFull };

/// One joint, in the specification's order (its index is the runtime's).
struct JointDef {
  std::string name;  // The specification's identifier, exactly.
  int parent = -1;   // Index of the parent joint, -1 for a root.
};

/// One capsule link.
/// - A bone: the segment from joint_a to joint_b (joint_b >= 0).
/// - An extension (joint_b < 0, joint_from >= 0): from joint_a onwards along
///   the direction joint_from -> joint_a, `length` long (a head above the
///   neck, a finger beyond its last joint where the set has no tip joint).
/// - A sphere (joint_b < 0, joint_from < 0): at joint_a.
struct LinkDef {
  std::string name;
  int joint_a = -1;
  int joint_b = -1;
  int joint_from = -1;
  HandPart part = HandPart::kBody;
  /// A bone whose length is not the joints' distance (a hand from the wrist
  /// towards the knuckles, whatever the fingers do): the segment starts at
  /// joint_a, points at joint_b and keeps its own length.
  bool fixed_length = false;
  /// Default length (bones without a calibration frame, extensions) and
  /// radius, as fractions of the user's height (docs/SKELETONS.md, sources).
  double length_per_height = 0;
  double radius_per_height = 0;
};

struct JointSet {
  std::string id;      // `--from` name, e.g. "meta-full-body".
  std::string title;   // e.g. "OpenXR XR_META_body_tracking_full_body".
  std::string source;  // Where the enumeration comes from: URL, path, licence.
  /// True when the runtime reports a radius per joint (XR_EXT_hand_tracking,
  /// WebXR hand input): a calibration frame's radii then set the links'.
  bool runtime_radii = false;
  std::vector<JointDef> joints;
  std::vector<LinkDef> links;

  int num_joints() const { return static_cast<int>(joints.size()); }
  /// Index of the joint called `name`, or -1.
  int FindJoint(const std::string& name) const;
};

/// The links of `set` a skeleton built with `hands` has, in table order,
/// with their parents (indices into the returned list) by the one rule of
/// docs/SKELETONS.md: walking up from joint_a, the first included link that
/// ends at the joint (its joint_b), else the first earlier included link
/// that starts at it; a link that finds none is the root when it is the
/// first such, otherwise a child of that root. Where `hands` is kFull but
/// the set has no kHandFull links, its kHandSimple links are used.
struct PlannedLink {
  const LinkDef* def = nullptr;
  int parent = -1;
};
std::vector<PlannedLink> PlanLinks(const JointSet& set, HandsOption hands);

/// Every registered joint set's id, in documentation order.
std::vector<std::string> JointSetIds();

/// The joint set called `id`. Throws InputError naming `id` and listing the
/// known ids.
const JointSet& FindJointSet(const std::string& id);

/// Parses "none", "simple" or "full". Throws InputError.
HandsOption ParseHandsOption(const std::string& name);

namespace internal {
/// Builds a table by joint names (joint_sets/*.cc); aborts on a name that is
/// not in the table (a bug in a table, caught by every test).
class JointSetBuilder {
 public:
  JointSetBuilder(std::string id, std::string title, std::string source, bool runtime_radii);
  /// Adds the joints, in the specification's order (all roots at first).
  JointSetBuilder& Joints(const std::vector<std::string>& names);
  /// Sets `child`'s parent joint.
  JointSetBuilder& Parent(const std::string& child, const std::string& parent);
  JointSetBuilder& Bone(const std::string& a, const std::string& b, HandPart part,
                        double length_per_height, double radius_per_height);
  JointSetBuilder& Extension(const std::string& from, const std::string& a, HandPart part,
                             double length_per_height, double radius_per_height);
  JointSetBuilder& Toward(const std::string& a, const std::string& b, HandPart part,
                          double length_per_height, double radius_per_height);
  JointSetBuilder& Sphere(const std::string& a, HandPart part, double radius_per_height);
  JointSet Build();
  /// Whether a joint of that name exists.
  bool Has(const std::string& name) const { return set_.FindJoint(name) >= 0; }

 private:
  int Index(const std::string& name) const;
  JointSet set_;
};

/// A joint set derived from `base` (same structure, other names): joint i of
/// the result is base joint `base_index[i]`, named `names[i]`; parents map
/// to the nearest kept ancestor; links whose joints are all kept are kept,
/// renamed.
JointSet DeriveJointSet(const JointSet& base, std::string id, std::string title, std::string source,
                        const std::vector<std::string>& names, const std::vector<int>& base_index);

// The tables (core/avatar/joint_sets/).
JointSet MetaFullBodyJointSet();
JointSet FbBodyJointSet();
JointSet WebXrBodyJointSet();
JointSet HtcBodyJointSet();
JointSet BdBodyJointSet();
JointSet ExtHandJointSet();
JointSet WebXrHandJointSet();
JointSet VrmHumanoidJointSet();
}  // namespace internal

}  // namespace sweptccd
