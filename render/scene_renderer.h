#pragma once
// Offscreen pictures of 3D scenes through the headless GlContext: batches of
// triangles (flat-shaded by their normal, or in one exact colour), drawn in
// order into a multisampled framebuffer object and read back. No GL or EGL
// in this header (pimpl); the drawing runs on the context's owner thread.

#include <Eigen/Core>
#include <array>
#include <memory>
#include <vector>

#include "render/raster_image.h"

namespace sweptccd::gpu {

class GlContext;

/// A pinhole camera. Pixels: x to the right, y down, origin at the top-left
/// corner of the picture; pixel (i, j) covers [i, i+1) x [j, j+1).
struct CameraView {
  Eigen::Vector3d eye{0, -3, 1};
  Eigen::Vector3d target{0, 0, 1};
  Eigen::Vector3d up{0, 0, 1};  // Need not be unit; must not be parallel to target - eye.
  double fov_y_deg = 50;        // Vertical field of view.
  double near_m = 0.05, far_m = 200;
};

/// World to clip coordinates (OpenGL conventions) for a width x height picture.
Eigen::Matrix4d ViewProjection(const CameraView& camera, int width, int height);
/// Where `p_W` lands in the picture (pixel coordinates, see CameraView).
/// False when it is behind the camera or outside the near/far range.
bool ProjectToPixel(const CameraView& camera, int width, int height, const Eigen::Vector3d& p_W,
                    Eigen::Vector2d* pixel);

/// Triangles drawn with one colour and one set of states.
struct DrawBatch {
  /// x, y, z per vertex, three vertices per triangle: world frame (metres), or
  /// pixel coordinates (z ignored) when `screen_space`.
  std::vector<float> vertices;
  Rgba colour{200, 200, 200, 255};  // a < 255: blended over what is behind.
  bool lit = true;                  // Shade by the triangle's normal; false: the exact colour.
  bool depth_test = true;           // false: never hidden (markers).
  bool depth_write = true;          // Translucent batches usually false.
  bool screen_space = false;
};

/// Appends a capsule (segment a-b, radius r) as a closed triangle mesh:
/// `slices` around the axis, `stacks` rings per hemisphere.
void AppendCapsule(const Eigen::Vector3d& a, const Eigen::Vector3d& b, double radius, int slices,
                   int stacks, std::vector<float>* vertices);
/// Appends a cone with its base centred at `base` and its tip at `tip`.
void AppendCone(const Eigen::Vector3d& base, const Eigen::Vector3d& tip, double radius, int slices,
                std::vector<float>* vertices);
/// Appends the square [x0, x1] x [y0, y1] in pixels (for screen_space batches).
void AppendScreenRect(double x0, double y0, double x1, double y1, std::vector<float>* vertices);

class SceneRenderer {
 public:
  /// Keeps `context` (must outlive the renderer). GL objects are made on the
  /// first Render and freed by the destructor, both on the owner thread.
  explicit SceneRenderer(GlContext* context);
  ~SceneRenderer();
  SceneRenderer(const SceneRenderer&) = delete;
  SceneRenderer& operator=(const SceneRenderer&) = delete;

  /// Largest width or height the context can render (GL_MAX_RENDERBUFFER_SIZE,
  /// GL_MAX_VIEWPORT_DIMS).
  int MaxSize();

  /// Draws the batches in order over `background` (depth cleared first) with
  /// up to `samples` samples per pixel, and returns the picture (top row
  /// first). Any thread may call it. Throws GpuError on a GL failure and
  /// std::invalid_argument for a size outside [1, MaxSize()].
  RgbaImage Render(const std::vector<DrawBatch>& batches, const CameraView& camera, int width,
                   int height, Rgba background, int samples = 4);

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace sweptccd::gpu
