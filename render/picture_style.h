#pragma once
// Shared by the pictures of render/ (contact_picture, timeline_picture):
// number formatting and the JSON forms of colours and vectors written into
// their sidecar information. Internal to render/.

#include <Eigen/Core>
#include <cstdio>
#include <nlohmann/json.hpp>
#include <string>

#include "render/raster_image.h"

namespace sweptccd::gpu::internal {

/// `v` with `digits` digits after the point.
inline std::string Fixed(double v, int digits) {
  char buf[64];
  std::snprintf(buf, sizeof buf, "%.*f", digits, v);
  return buf;
}

inline nlohmann::json ColourJson(Rgba c) { return nlohmann::json::array({c.r, c.g, c.b}); }

inline nlohmann::json VecJson(const Eigen::Vector3d& v) {
  return nlohmann::json::array({v.x(), v.y(), v.z()});
}

}  // namespace sweptccd::gpu::internal
