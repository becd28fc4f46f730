#include "core/world/world.h"

#include <algorithm>
#include <cmath>

namespace sweptccd::world {

bool IsValidEntityId(const std::string& id) {
  if (id.empty() || id.size() > 64) return false;
  for (char c : id) {
    const bool ok = (c >= 'A' && c <= 'Z') || (c >= 'a' && c <= 'z') || (c >= '0' && c <= '9') ||
                    c == '_' || c == '.' || c == '-';
    if (!ok) return false;
  }
  return true;
}

namespace {
// `other_link` invalid: an object (no links), matched by any other_link.
bool RuleMatches(const EntityRule& r, LinkIndex link, const std::string& entity,
                 LinkIndex other_link) {
  return r.entity == entity && (!r.link.is_valid() || r.link == link) &&
         (!r.other_link.is_valid() || !other_link.is_valid() || r.other_link == other_link);
}
}  // namespace

bool IgnoresLinkPair(const FilterSide& a, LinkIndex link_a, const FilterSide& b, LinkIndex link_b) {
  for (const EntityRule& r : a.rules) {
    if (RuleMatches(r, link_a, b.id, link_b)) return true;
  }
  for (const EntityRule& r : b.rules) {
    if (RuleMatches(r, link_b, a.id, link_a)) return true;
  }
  return false;
}

bool IgnoresObject(const FilterSide& a, LinkIndex link_a, const std::string& object) {
  for (const EntityRule& r : a.rules) {
    if (RuleMatches(r, link_a, object, kAllLinks)) return true;
  }
  return false;
}

bool NamesEntity(const FilterSide& a, const std::string& other) {
  return std::any_of(a.rules.begin(), a.rules.end(),
                     [&](const EntityRule& r) { return r.entity == other; });
}

bool World::IgnoresLinkPair(AvatarIndex a, LinkIndex link_a, AvatarIndex b,
                            LinkIndex link_b) const {
  return world::IgnoresLinkPair(FilterSide{avatars[a].id, rules[a]}, link_a,
                                FilterSide{avatars[b].id, rules[b]}, link_b);
}

bool World::IgnoresObject(AvatarIndex a, LinkIndex link_a, TrackedObjectIndex o) const {
  return world::IgnoresObject(FilterSide{avatars[a].id, rules[a]}, link_a, objects[o].id);
}

RigidMotion::RigidMotion(const RigidSample& a, const RigidSample& b) : x0(a), x1(b) {
  angle = SlerpAngle(x0.q, x1.q);
}

std::optional<PoseProblem> FindRigidProblem(const double pose[7]) {
  Pose one;
  one.links.resize(1);
  one.links[0].p = Eigen::Vector3d(pose[0], pose[1], pose[2]);
  one.links[0].q = Eigen::Quaterniond(pose[3], pose[4], pose[5], pose[6]);
  return FindPoseProblem(one, 1);
}

std::string MakeRigidSample(int64_t utime, const double pose[7], RigidSample* out) {
  if (const std::optional<PoseProblem> problem = FindRigidProblem(pose)) {
    switch (problem->kind) {
      case PoseProblem::Kind::kNonFinite:
        return "non-finite number";
      case PoseProblem::Kind::kPositionOutOfRange:
        return "position beyond 1e9 m";
      default:
        return "quaternion norm below 1e-6";
    }
  }
  const Eigen::Quaterniond q(pose[3], pose[4], pose[5], pose[6]);
  out->utime = utime;
  out->p = Eigen::Vector3d(pose[0], pose[1], pose[2]);
  // Normalised as an avatar's link (ValidateAndNormalizePose), so that the
  // same numbers make the same rotation, bit for bit, on either path.
  out->q = Eigen::Quaterniond(q.coeffs() / q.coeffs().stableNorm());
  FlushTinyComponents(&out->q);
  return {};
}

}  // namespace sweptccd::world
