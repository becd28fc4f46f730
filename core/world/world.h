#pragma once
// A shared world (SPEC section 8): avatars and tracked rigid objects, each
// with its own stream of samples on one time base, plus the filters that say
// which (link, entity) and (link, link) pairs never count as contact.

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <cstdint>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "core/avatar/motion.h"
#include "core/avatar/pose.h"
#include "core/avatar/skeleton.h"
#include "core/scene/environment.h"
#include "core/typed_index.h"

namespace sweptccd::world {

struct AvatarTag;
struct TrackedObjectTag;
/// An avatar of a World (0-based, in file order).
using AvatarIndex = TypedIndex<AvatarTag>;
/// A tracked object of a World (0-based, in file order); not an object of
/// an Environment (ObjectIndex).
using TrackedObjectIndex = TypedIndex<TrackedObjectTag>;

/// Whether `id` is a valid entity id: 1-64 characters from [A-Za-z0-9_.-].
bool IsValidEntityId(const std::string& id);

/// A rigid pose X_WO of a tracked object at a time (unit quaternion).
struct RigidSample {
  int64_t utime = 0;
  Eigen::Vector3d p{0, 0, 0};
  Eigen::Quaterniond q{1, 0, 0, 0};
};

/// Why an object pose [px, py, pz, qw, qx, qy, qz] is unusable (SPEC 8,
/// "Trajectory"), or nullopt: the rule of an avatar's link pose
/// (FindPoseProblem over one link, reported as link 0): a non-finite
/// number, a coordinate beyond 1e9 m, a quaternion norm below 1e-6. The one
/// rule of object pose lines (MakeRigidSample) and of the service's
/// object_pose_t, which maps its kind to a rejection code. Pure.
std::optional<PoseProblem> FindRigidProblem(const double pose[7]);

/// A rigid sample from its utime and pose (as above): empty and *out set
/// (quaternion normalised) when usable, else FindRigidProblem's problem as
/// the world file words it ("non-finite number", "position beyond 1e9 m",
/// "quaternion norm below 1e-6"). Pure.
std::string MakeRigidSample(int64_t utime, const double pose[7], RigidSample* out);

/// An avatar: its skeleton, motion model, the records of its stream (SPEC 2
/// numbering) and its used samples (the first valid pose, then every pose
/// that closed a valid pair: strictly increasing utimes, unit quaternions).
struct AvatarEntity {
  std::string id;
  Skeleton skeleton;
  MotionModel motion = MotionModel::kArticulated;
  std::vector<PairOutcome> records;
  std::vector<Pose> used;
};

/// A tracked object: its mesh (one-object Environment, in the object's
/// frame; shared and immutable, so the live service hands it to every
/// answer without a copy) and its used samples (strictly increasing utimes).
struct ObjectEntity {
  std::string id;
  std::shared_ptr<const Environment> mesh = std::make_shared<const Environment>();
  std::vector<RigidSample> used;
};

/// One ignore rule of an avatar towards another entity (SPEC 8 "Filters").
/// link / other_link: -1 means every link ("*"); other_link is -1 also when
/// the rule names no other_link.
struct EntityRule {
  LinkIndex link;  // Invalid (kAllLinks): every link.
  std::string entity;
  LinkIndex other_link;  // Invalid (kAllLinks): every link of `entity`.
};

/// Who an entity is to the filters: its id and its rules (an object has
/// none). The one rule of the filters, whoever holds the entities (a World,
/// the daemon's shared world):
struct FilterSide {
  const std::string& id;
  const std::vector<EntityRule>& rules;
};
/// Whether link `link_a` of avatar `a` and link `link_b` of avatar `b`
/// never count as contact (a rule of either avatar applies).
bool IgnoresLinkPair(const FilterSide& a, LinkIndex link_a, const FilterSide& b, LinkIndex link_b);
/// Whether link `link_a` of avatar `a` never touches the object `object`.
bool IgnoresObject(const FilterSide& a, LinkIndex link_a, const std::string& object);
/// Whether some rule of `a` names `other` (only then can a rule of `a`
/// ignore a link pair with it).
bool NamesEntity(const FilterSide& a, const std::string& other);

/// The whole world. Plain data, immutable while queried.
struct World {
  std::vector<AvatarEntity> avatars;
  std::vector<ObjectEntity> objects;
  /// Per avatar (same index): its entity rules.
  std::vector<std::vector<EntityRule>> rules;

  /// Whether link `link_a` of avatar `a` and link `link_b` of avatar `b`
  /// never count as contact (a rule of either avatar applies).
  bool IgnoresLinkPair(AvatarIndex a, LinkIndex link_a, AvatarIndex b, LinkIndex link_b) const;
  /// Whether link `link_a` of avatar `a` never touches object `o`.
  bool IgnoresObject(AvatarIndex a, LinkIndex link_a, TrackedObjectIndex o) const;
};

/// The rigid motion of a one-link `independent` body between two samples
/// (SPEC 3): p(s) linear, q(s) shortest-arc slerp.
struct RigidMotion {
  RigidSample x0, x1;
  double angle = 0;  // SlerpAngle(q0, q1): radians per unit s.
  RigidMotion(const RigidSample& a, const RigidSample& b);
  Eigen::Vector3d PositionAt(double s) const { return (1 - s) * x0.p + s * x1.p; }
  Eigen::Quaterniond RotationAt(double s) const { return Slerp(x0.q, x1.q, s); }
};

}  // namespace sweptccd::world
