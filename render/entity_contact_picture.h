#pragma once
// The picture of `sweptccd render --world`: an avatar and another entity of a
// shared world (another avatar or a tracked object) at their first contact
// within one of the avatar's pairs, with both witness points marked. Drawn
// through SceneRenderer (the headless GL context); the caller writes the PNG.

#include <Eigen/Core>
#include <nlohmann/json.hpp>
#include <optional>

#include "core/world/entity_query.h"
#include "core/world/world.h"
#include "render/raster_image.h"
#include "render/scene_renderer.h"

namespace sweptccd::gpu {

/// Exact, unlit colours (so that scripts and tests can find each entity's
/// pixels): the avatar, the other entity, and the witness markers.
inline constexpr Rgba kEntityAvatarColour{255, 140, 0, 255};   // Orange.
inline constexpr Rgba kEntityOtherColour{0, 110, 255, 255};    // Blue.
inline constexpr Rgba kEntityWitnessColour{255, 0, 255, 255};  // Magenta.

struct EntityPictureOptions {
  int width = 1280, height = 720;              // Pixels, within [1, SceneRenderer::MaxSize()].
  double fov_deg = 50;                         // Vertical field of view, in (1, 170).
  int up_axis = 2;                             // 0, 1 or 2 (x, y, z).
  std::optional<Eigen::Vector3d> eye, target;  // Empty: chosen from the contact.
};

struct EntityPicture {
  RgbaImage image;
  /// The pair, the contact time, the witness points and their pixels, the
  /// colours and the camera.
  nlohmann::json info;
};

/// Draws avatar `a` (its valid record `r`) and the other entity (avatar `b`
/// or object `o`, exactly one >= 0) at the time of `answer`'s earliest
/// witness (else the bracket's tau_lo), each in its own colour, the witness
/// points as magenta squares drawn over everything. `answer` must be a
/// contact of that record against that entity (WorldAnswerer::AnswerEntity).
/// Throws GpuError on a GL failure. Any thread.
EntityPicture DrawEntityPicture(const EntityPictureOptions& options, const world::World& world,
                                int a, size_t r, int b, int o, const world::OtherAnswer& answer,
                                SceneRenderer* renderer);

}  // namespace sweptccd::gpu
