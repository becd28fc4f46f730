#include "render/scene_renderer.h"

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>

#include "core/gpu/gl_api.h"
#include "core/gpu/gl_context.h"

namespace sweptccd::gpu {

namespace {

constexpr double kPi = 3.14159265358979323846;

const char* kVertexShader = R"(#version 430 core
layout(location = 0) in vec3 position;
uniform mat4 transform;
out vec3 world;
void main() {
  world = position;
  gl_Position = transform * vec4(position, 1.0);
}
)";

// Flat shading from the screen-space derivatives of the world position (no
// normals to upload); two-sided, a headlight plus a fixed key light.
const char* kFragmentShader = R"(#version 430 core
in vec3 world;
uniform vec4 colour;
uniform int lit;
uniform vec3 eye;
uniform vec3 key_light;
out vec4 frag;
void main() {
  if (lit == 0) {
    frag = colour;
    return;
  }
  vec3 n = cross(dFdx(world), dFdy(world));
  float len = length(n);
  n = len > 0.0 ? n / len : vec3(0.0, 0.0, 1.0);
  vec3 view = normalize(eye - world);
  float k = 0.30 + 0.50 * abs(dot(n, view)) + 0.25 * abs(dot(n, key_light));
  frag = vec4(min(colour.rgb * k, vec3(1.0)), colour.a);
}
)";

void AppendVertex(const Eigen::Vector3d& p, std::vector<float>* v) {
  v->push_back(static_cast<float>(p.x()));
  v->push_back(static_cast<float>(p.y()));
  v->push_back(static_cast<float>(p.z()));
}

void AppendTriangle(const Eigen::Vector3d& a, const Eigen::Vector3d& b, const Eigen::Vector3d& c,
                    std::vector<float>* v) {
  AppendVertex(a, v);
  AppendVertex(b, v);
  AppendVertex(c, v);
}

// Two unit vectors perpendicular to `axis` (unit) and to each other.
void Basis(const Eigen::Vector3d& axis, Eigen::Vector3d* u, Eigen::Vector3d* w) {
  const Eigen::Vector3d helper =
      std::abs(axis.x()) < 0.9 ? Eigen::Vector3d::UnitX() : Eigen::Vector3d::UnitY();
  *u = axis.cross(helper).normalized();
  *w = axis.cross(*u);
}

Eigen::Matrix4f ToFloat(const Eigen::Matrix4d& m) { return m.cast<float>(); }

}  // namespace

Eigen::Matrix4d ViewProjection(const CameraView& camera, int width, int height) {
  const Eigen::Vector3d f = (camera.target - camera.eye).normalized();
  Eigen::Vector3d s = f.cross(camera.up);
  if (s.norm() < 1e-9)
    s = f.cross(std::abs(f.x()) < 0.9 ? Eigen::Vector3d::UnitX() : Eigen::Vector3d::UnitY());
  s.normalize();
  const Eigen::Vector3d u = s.cross(f);
  Eigen::Matrix4d view = Eigen::Matrix4d::Identity();
  view.block<1, 3>(0, 0) = s.transpose();
  view.block<1, 3>(1, 0) = u.transpose();
  view.block<1, 3>(2, 0) = -f.transpose();
  view(0, 3) = -s.dot(camera.eye);
  view(1, 3) = -u.dot(camera.eye);
  view(2, 3) = f.dot(camera.eye);
  const double aspect = static_cast<double>(width) / height;
  const double t = 1.0 / std::tan(camera.fov_y_deg * kPi / 360.0);
  const double n = camera.near_m, fa = camera.far_m;
  Eigen::Matrix4d proj = Eigen::Matrix4d::Zero();
  proj(0, 0) = t / aspect;
  proj(1, 1) = t;
  proj(2, 2) = -(fa + n) / (fa - n);
  proj(2, 3) = -2 * fa * n / (fa - n);
  proj(3, 2) = -1;
  return proj * view;
}

bool ProjectToPixel(const CameraView& camera, int width, int height, const Eigen::Vector3d& p_W,
                    Eigen::Vector2d* pixel) {
  const Eigen::Vector4d clip = ViewProjection(camera, width, height) * p_W.homogeneous();
  if (clip.w() <= 0) return false;
  const Eigen::Vector3d ndc = clip.head<3>() / clip.w();
  if (ndc.z() < -1 || ndc.z() > 1) return false;
  *pixel = Eigen::Vector2d((ndc.x() + 1) * 0.5 * width, (1 - ndc.y()) * 0.5 * height);
  return true;
}

void AppendCapsule(const Eigen::Vector3d& a, const Eigen::Vector3d& b, double radius, int slices,
                   int stacks, std::vector<float>* v) {
  Eigen::Vector3d axis = b - a;
  const double length = axis.norm();
  axis = length > 1e-12 ? Eigen::Vector3d(axis / length) : Eigen::Vector3d::UnitZ();
  Eigen::Vector3d u, w;
  Basis(axis, &u, &w);
  // Rings from the bottom pole (at a) to the top pole (at b): latitude
  // -90..0 around a, 0..90 around b.
  std::vector<Eigen::Vector3d> centres;
  std::vector<double> lat;
  for (int i = 0; i <= stacks; ++i) {
    centres.push_back(a);
    lat.push_back(-kPi / 2 + kPi / 2 * i / stacks);
  }
  for (int i = 0; i <= stacks; ++i) {
    centres.push_back(b);
    lat.push_back(kPi / 2 * i / stacks);
  }
  auto point = [&](size_t ring, int slice) {
    const double phi = 2 * kPi * slice / slices;
    const double c = std::cos(lat[ring]), s = std::sin(lat[ring]);
    return Eigen::Vector3d(centres[ring] +
                           radius * (c * (std::cos(phi) * u + std::sin(phi) * w) + s * axis));
  };
  for (size_t r = 0; r + 1 < lat.size(); ++r) {
    for (int j = 0; j < slices; ++j) {
      const Eigen::Vector3d p00 = point(r, j), p01 = point(r, j + 1);
      const Eigen::Vector3d p10 = point(r + 1, j), p11 = point(r + 1, j + 1);
      if ((p00 - p01).squaredNorm() > 1e-18) AppendTriangle(p00, p01, p11, v);
      if ((p10 - p11).squaredNorm() > 1e-18) AppendTriangle(p00, p11, p10, v);
    }
  }
}

void AppendCone(const Eigen::Vector3d& base, const Eigen::Vector3d& tip, double radius, int slices,
                std::vector<float>* v) {
  const Eigen::Vector3d axis = (tip - base).normalized();
  Eigen::Vector3d u, w;
  Basis(axis, &u, &w);
  for (int j = 0; j < slices; ++j) {
    const double p0 = 2 * kPi * j / slices, p1 = 2 * kPi * (j + 1) / slices;
    const Eigen::Vector3d r0 = base + radius * (std::cos(p0) * u + std::sin(p0) * w);
    const Eigen::Vector3d r1 = base + radius * (std::cos(p1) * u + std::sin(p1) * w);
    AppendTriangle(r0, r1, tip, v);
    AppendTriangle(r1, r0, base, v);
  }
}

void AppendScreenRect(double x0, double y0, double x1, double y1, std::vector<float>* v) {
  const Eigen::Vector3d a(x0, y0, 0), b(x1, y0, 0), c(x1, y1, 0), d(x0, y1, 0);
  AppendTriangle(a, b, c, v);
  AppendTriangle(a, c, d, v);
}

struct SceneRenderer::Impl {
  GlContext* context = nullptr;
  GLuint program = 0, vao = 0, vbo = 0;
  GLint u_transform = -1, u_colour = -1, u_lit = -1, u_eye = -1, u_key = -1;
  int max_size = 0, max_samples = 0;

  // On the owner thread.
  void Init() {
    if (program != 0) return;
    program = internal::CompileProgram(kVertexShader, kFragmentShader);
    u_transform = glGetUniformLocation(program, "transform");
    u_colour = glGetUniformLocation(program, "colour");
    u_lit = glGetUniformLocation(program, "lit");
    u_eye = glGetUniformLocation(program, "eye");
    u_key = glGetUniformLocation(program, "key_light");
    glGenVertexArrays(1, &vao);
    glGenBuffers(1, &vbo);
    GLint rb = 0, vp[2] = {0, 0};
    glGetIntegerv(GL_MAX_RENDERBUFFER_SIZE, &rb);
    glGetIntegerv(GL_MAX_VIEWPORT_DIMS, vp);
    max_size = std::min({rb, vp[0], vp[1]});
    glGetIntegerv(GL_MAX_SAMPLES, &max_samples);
    internal::CheckGl("scene renderer setup");
  }

  void Free() {
    if (program == 0) return;
    glDeleteBuffers(1, &vbo);
    glDeleteVertexArrays(1, &vao);
    glDeleteProgram(program);
    program = 0;
  }
};

SceneRenderer::SceneRenderer(GlContext* context) : impl_(std::make_unique<Impl>()) {
  impl_->context = context;
}

SceneRenderer::~SceneRenderer() {
  try {
    impl_->context->Run([this] { impl_->Free(); });
  } catch (...) {
    // A lost context frees its objects with it.
  }
}

int SceneRenderer::MaxSize() {
  impl_->context->Run([this] { impl_->Init(); });
  return impl_->max_size;
}

RgbaImage SceneRenderer::Render(const std::vector<DrawBatch>& batches, const CameraView& camera,
                                int width, int height, Rgba background, int samples) {
  const int max_size = MaxSize();
  if (width < 1 || height < 1 || width > max_size || height > max_size) {
    throw std::invalid_argument("picture size " + std::to_string(width) + "x" +
                                std::to_string(height) + " is outside 1.." +
                                std::to_string(max_size));
  }
  RgbaImage image(width, height, background);
  const Eigen::Matrix4f world_to_clip = ToFloat(ViewProjection(camera, width, height));
  // Pixels (top-left origin, y down) to clip coordinates.
  Eigen::Matrix4f pixels_to_clip = Eigen::Matrix4f::Identity();
  pixels_to_clip(0, 0) = 2.0f / width;
  pixels_to_clip(0, 3) = -1.0f;
  pixels_to_clip(1, 1) = -2.0f / height;
  pixels_to_clip(1, 3) = 1.0f;
  pixels_to_clip(2, 2) = 0.0f;
  const Eigen::Vector3f key = Eigen::Vector3f(0.3f, 0.5f, 0.8f).normalized();
  impl_->context->Run([&] {
    Impl& g = *impl_;
    const int n_samples = std::clamp(samples, 0, std::max(g.max_samples, 0));
    GLuint fbo[2] = {0, 0}, rbo[3] = {0, 0, 0};
    glGenFramebuffers(2, fbo);
    glGenRenderbuffers(3, rbo);
    // fbo[0]: multisampled colour + depth; fbo[1]: the resolved colour.
    glBindRenderbuffer(GL_RENDERBUFFER, rbo[0]);
    glRenderbufferStorageMultisample(GL_RENDERBUFFER, n_samples, GL_RGBA8, width, height);
    glBindRenderbuffer(GL_RENDERBUFFER, rbo[1]);
    glRenderbufferStorageMultisample(GL_RENDERBUFFER, n_samples, GL_DEPTH_COMPONENT24, width,
                                     height);
    glBindRenderbuffer(GL_RENDERBUFFER, rbo[2]);
    glRenderbufferStorage(GL_RENDERBUFFER, GL_RGBA8, width, height);
    glBindFramebuffer(GL_FRAMEBUFFER, fbo[1]);
    glFramebufferRenderbuffer(GL_FRAMEBUFFER, GL_COLOR_ATTACHMENT0, GL_RENDERBUFFER, rbo[2]);
    glBindFramebuffer(GL_FRAMEBUFFER, fbo[0]);
    glFramebufferRenderbuffer(GL_FRAMEBUFFER, GL_COLOR_ATTACHMENT0, GL_RENDERBUFFER, rbo[0]);
    glFramebufferRenderbuffer(GL_FRAMEBUFFER, GL_DEPTH_ATTACHMENT, GL_RENDERBUFFER, rbo[1]);
    auto cleanup = [&] {
      glBindFramebuffer(GL_FRAMEBUFFER, 0);
      glDeleteFramebuffers(2, fbo);
      glDeleteRenderbuffers(3, rbo);
    };
    if (glCheckFramebufferStatus(GL_FRAMEBUFFER) != GL_FRAMEBUFFER_COMPLETE) {
      cleanup();
      throw GpuError("scene renderer: incomplete framebuffer for " + std::to_string(width) + "x" +
                     std::to_string(height));
    }
    glViewport(0, 0, width, height);
    glClearColor(background.r / 255.0f, background.g / 255.0f, background.b / 255.0f, 1.0f);
    glClearDepth(1.0);
    glClear(GL_COLOR_BUFFER_BIT | GL_DEPTH_BUFFER_BIT);
    glDisable(GL_CULL_FACE);
    glDepthFunc(GL_LEQUAL);  // A batch may redraw a triangle already drawn (highlights).
    glBlendFunc(GL_SRC_ALPHA, GL_ONE_MINUS_SRC_ALPHA);
    glUseProgram(g.program);
    glUniform3f(g.u_eye, static_cast<float>(camera.eye.x()), static_cast<float>(camera.eye.y()),
                static_cast<float>(camera.eye.z()));
    glUniform3f(g.u_key, key.x(), key.y(), key.z());
    glBindVertexArray(g.vao);
    glBindBuffer(GL_ARRAY_BUFFER, g.vbo);
    glEnableVertexAttribArray(0);
    for (const DrawBatch& batch : batches) {
      const GLsizei count = static_cast<GLsizei>(batch.vertices.size() / 3);
      if (count < 3) continue;
      glBufferData(GL_ARRAY_BUFFER, static_cast<GLsizeiptr>(batch.vertices.size() * sizeof(float)),
                   batch.vertices.data(), GL_STREAM_DRAW);
      glVertexAttribPointer(0, 3, GL_FLOAT, GL_FALSE, 0, nullptr);
      const Eigen::Matrix4f& m = batch.screen_space ? pixels_to_clip : world_to_clip;
      glUniformMatrix4fv(g.u_transform, 1, GL_FALSE, m.data());  // Eigen is column-major.
      glUniform4f(g.u_colour, batch.colour.r / 255.0f, batch.colour.g / 255.0f,
                  batch.colour.b / 255.0f, batch.colour.a / 255.0f);
      glUniform1i(g.u_lit, batch.lit ? 1 : 0);
      if (batch.depth_test)
        glEnable(GL_DEPTH_TEST);
      else
        glDisable(GL_DEPTH_TEST);
      glDepthMask(batch.depth_write ? GL_TRUE : GL_FALSE);
      if (batch.colour.a < 255)
        glEnable(GL_BLEND);
      else
        glDisable(GL_BLEND);
      glDrawArrays(GL_TRIANGLES, 0, count - count % 3);
    }
    glDepthMask(GL_TRUE);
    glDisable(GL_BLEND);
    glBindFramebuffer(GL_READ_FRAMEBUFFER, fbo[0]);
    glBindFramebuffer(GL_DRAW_FRAMEBUFFER, fbo[1]);
    glBlitFramebuffer(0, 0, width, height, 0, 0, width, height, GL_COLOR_BUFFER_BIT, GL_NEAREST);
    glBindFramebuffer(GL_READ_FRAMEBUFFER, fbo[1]);
    glPixelStorei(GL_PACK_ALIGNMENT, 1);
    std::vector<uint8_t> rows(static_cast<size_t>(width) * height * 4);
    glReadPixels(0, 0, width, height, GL_RGBA, GL_UNSIGNED_BYTE, rows.data());
    cleanup();
    internal::CheckGl("scene renderer draw");
    // GL's first row is the bottom one.
    const size_t stride = static_cast<size_t>(width) * 4;
    for (int y = 0; y < height; ++y) {
      std::copy_n(&rows[static_cast<size_t>(height - 1 - y) * stride], stride,
                  &image.pixels[static_cast<size_t>(y) * stride]);
    }
  });
  return image;
}

}  // namespace sweptccd::gpu
