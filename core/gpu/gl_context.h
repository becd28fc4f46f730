#pragma once
// A long-lived headless OpenGL context (EGL, no window, no display server),
// owned by one thread that other threads hand work to.
//
// Display choice (never the default display): the configured EGL device,
// else the first EGL device that gives an OpenGL >= 4.3 core context
// (EGL_EXT_device_enumeration + EGL_EXT_platform_device), else Mesa's
// surfaceless platform (EGL_MESA_platform_surfaceless).

#include <functional>
#include <memory>
#include <stdexcept>
#include <string>

namespace sweptccd::gpu {

/// The context could not be made, or was lost. The message says why.
class GpuError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

struct GlContextOptions {
  /// >= 0: use only this EGL device (index in eglQueryDevicesEXT order).
  int device_index = -1;
  /// Skip the device platform and go straight to the surfaceless platform.
  bool surfaceless_only = false;
  /// Refuse software renderers (llvmpipe, softpipe, swrast).
  bool require_hardware = false;
};

struct GlContextInfo {
  std::string display;  // How it was opened, e.g. "EGL device 1 of 2" or "Mesa surfaceless".
  std::string vendor, renderer, version, glsl_version;
  int major = 0, minor = 0;  // OpenGL version of the context.
  bool software = false;     // llvmpipe, softpipe or swrast.
  /// One line for logs and `status_t`: renderer, version and display.
  std::string Summary() const;
};

class GlContext {
 public:
  /// Starts the owner thread and makes the context there (core profile 4.3
  /// or later, current with no surface). Throws GpuError naming every display
  /// tried and why it failed. Logs the vendor, renderer and version.
  explicit GlContext(const GlContextOptions& options = {});
  /// Finishes the work already handed over, destroys the context, releases
  /// the display and joins the owner thread.
  ~GlContext();
  GlContext(const GlContext&) = delete;
  GlContext& operator=(const GlContext&) = delete;

  const GlContextInfo& info() const;

  /// Runs `work` on the owner thread with the context current and waits for
  /// it; rethrows what it throws. Any thread may call it (calls are served
  /// one at a time, in order); from the owner thread it runs inline. Throws
  /// GpuError when the context is lost (checked after every piece of work
  /// through GL_KHR_robustness where the driver offers it).
  void Run(const std::function<void()>& work);

  /// True once the context was found lost; Run then throws at once.
  bool lost() const;

  /// Whether the calling thread is the owner thread.
  bool OnOwnerThread() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace sweptccd::gpu
