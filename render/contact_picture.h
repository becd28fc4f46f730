#pragma once
// The contact picture of `sweptccd render`: the scene near a pair's first
// contact, the avatar at both poses, the links' swept volumes, the avatar at
// the first contact with the touching link, the witness triangle, a marker on
// the witness point and an arrow along the normal, with a caption. Drawn
// through SceneRenderer (the headless GL context); the caller writes the PNG.

#include <Eigen/Core>
#include <nlohmann/json.hpp>
#include <optional>

#include "core/avatar/motion.h"
#include "core/avatar/pose.h"
#include "core/avatar/skeleton.h"
#include "core/query/ccd_query.h"
#include "core/scene/environment.h"
#include "render/raster_image.h"
#include "render/scene_renderer.h"

namespace sweptccd::gpu {

struct ContactPictureOptions {
  int width = 1280, height = 720;              // Pixels, within [1, SceneRenderer::MaxSize()].
  double fov_deg = 50;                         // Vertical field of view, in (1, 170).
  std::optional<Eigen::Vector3d> eye, target;  // Empty: chosen from the contact.
  int up_axis = 2;                             // 0, 1 or 2 (x, y, z).
  double clip_radius_m = 4;  // Scene triangles farther from the target are not drawn.
  int swept_steps = 12;      // In-between times drawn per link, >= 0.
};

struct ContactPicture {
  RgbaImage image;
  /// What the picture shows, for scripts: the pair and its answer, the
  /// witness, the marker's pixel and colours, the camera, triangle counts.
  nlohmann::json info;
};

/// Draws pair `pair` (valid) answered by `result`. Markers and the normal use
/// pure colours nothing lit can produce (named in `info`). Throws GpuError on
/// a GL failure; std::invalid_argument for a size the renderer refuses. Any
/// thread (the drawing runs on the context's owner thread).
ContactPicture DrawContactPicture(const ContactPictureOptions& options, const Skeleton& skeleton,
                                  const Environment& env, const PairOutcome& pair,
                                  const QueryResult& result, MotionModel model,
                                  SceneRenderer* renderer);

/// The axis along which the scene's bounding box is thinnest (rooms are wider
/// than tall), else z (2) for an empty scene. Pure.
int GuessUpAxis(const Environment& env);

}  // namespace sweptccd::gpu
