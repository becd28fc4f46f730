#include "core/world/entity_window.h"

#include <algorithm>
#include <utility>

#include "core/errors.h"

namespace sweptccd::world {

namespace {

const std::vector<EntityRule>& NoRules() {
  static const std::vector<EntityRule> none;
  return none;
}

// The sample indices [first, last] the pieces use.
std::pair<size_t, size_t> WindowSamples(size_t num_samples, const std::vector<Piece>& pieces) {
  SWEPTCCD_CHECK(!pieces.empty() && num_samples > 0);
  const size_t first = static_cast<size_t>(pieces.front().k);
  const size_t last = std::min(static_cast<size_t>(pieces.back().k) + 1, num_samples - 1);
  SWEPTCCD_CHECK(first <= last);
  return {first, last};
}

double MeshScale(const Environment& mesh) {
  return mesh.num_objects() > 0 ? mesh.object(0).bvh.max_abs_coordinate() : 0.0;
}

}  // namespace

AvatarWindow WindowOfAvatar(const World& world, AvatarIndex a) {
  const AvatarEntity& e = world.avatars[static_cast<size_t>(a)];
  const std::vector<EntityRule>& rules =
      static_cast<size_t>(a) < world.rules.size() ? world.rules[static_cast<size_t>(a)] : NoRules();
  return AvatarWindow{FilterSide{e.id, rules}, e.skeleton, e.motion, e.used};
}

ObjectWindow WindowOfObject(const World& world, TrackedObjectIndex o) {
  const ObjectEntity& e = world.objects[static_cast<size_t>(o)];
  return ObjectWindow{e.id, *e.mesh, e.used};
}

double SampleScale(const Pose& pose) {
  double scale = 0;
  for (const LinkPose& l : pose.links) scale = std::max(scale, l.p.cwiseAbs().maxCoeff());
  return scale;
}

double SkeletonScale(const Skeleton& skeleton) {
  double scale = 0;
  for (const Link& l : skeleton.links()) scale = std::max({scale, l.a_L.norm(), l.b_L.norm()});
  return scale;
}

double EntityScale(const AvatarWindow& e) {
  double scale = 0;
  for (const Pose& p : e.samples) scale = std::max(scale, SampleScale(p));
  return std::max(scale, SkeletonScale(e.skeleton));
}

double EntityScale(const ObjectWindow& e) {
  double scale = MeshScale(e.mesh);
  for (const RigidSample& x : e.samples) scale = std::max(scale, x.p.cwiseAbs().maxCoeff());
  return scale;
}

double WindowScale(const AvatarWindow& e, const std::vector<Piece>& pieces) {
  const auto [first, last] = WindowSamples(e.samples.size(), pieces);
  double scale = 0;
  for (size_t k = first; k <= last; ++k) scale = std::max(scale, SampleScale(e.samples[k]));
  return std::max(scale, SkeletonScale(e.skeleton));
}

double WindowScale(const ObjectWindow& e, const std::vector<Piece>& pieces) {
  const auto [first, last] = WindowSamples(e.samples.size(), pieces);
  double scale = MeshScale(e.mesh);
  for (size_t k = first; k <= last; ++k)
    scale = std::max(scale, e.samples[k].p.cwiseAbs().maxCoeff());
  return scale;
}

double EntityScale(const AvatarEntity& e) {
  return EntityScale(AvatarWindow{FilterSide{e.id, NoRules()}, e.skeleton, e.motion, e.used});
}
double EntityScale(const ObjectEntity& e) {
  return EntityScale(ObjectWindow{e.id, *e.mesh, e.used});
}
double WindowScale(const AvatarEntity& e, const std::vector<Piece>& pieces) {
  return WindowScale(AvatarWindow{FilterSide{e.id, NoRules()}, e.skeleton, e.motion, e.used},
                     pieces);
}
double WindowScale(const ObjectEntity& e, const std::vector<Piece>& pieces) {
  return WindowScale(ObjectWindow{e.id, *e.mesh, e.used}, pieces);
}

}  // namespace sweptccd::world
