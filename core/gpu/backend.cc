#include "core/gpu/backend.h"

#include <spdlog/spdlog.h>

#include "core/errors.h"
#include "core/gpu/gpu_culler.h"

namespace sweptccd::gpu {

BackendKind ParseBackendKind(const std::string& name, const std::string& where) {
  if (name == "cpu") return BackendKind::kCpu;
  if (name == "gpu") return BackendKind::kGpu;
  if (name == "auto") return BackendKind::kAuto;
  throw InputError(where + " must be cpu, gpu or auto, got '" + name + "'");
}

const char* BackendKindName(BackendKind kind) {
  switch (kind) {
    case BackendKind::kCpu:
      return "cpu";
    case BackendKind::kGpu:
      return "gpu";
    case BackendKind::kAuto:
      return "auto";
  }
  return "auto";  // Not reached: every enumerator is handled above.
}

Backend::Backend(const BackendOptions& options) {
  const bool automatic = options.backend == BackendKind::kAuto;
  if (options.backend == BackendKind::kCpu) {
    reason_ = "cpu (requested)";
    return;
  }
  GlContextOptions context_options;
  context_options.device_index = options.device_index;
  context_options.require_hardware = options.require_hardware || automatic;
  try {
    context_ = std::make_shared<GlContext>(context_options);
  } catch (const GpuError& e) {
    if (automatic) {
      reason_ = std::string("cpu (auto: no hardware EGL device; ") + e.what() + ")";
    } else {
      reason_ = std::string("cpu (gpu requested but unavailable: ") + e.what() + ")";
    }
    return;
  }
  reason_ = "gpu (" + std::string(automatic ? "auto: hardware EGL device" : "requested") +
            "; " + context_->info().Summary() + ")";
}

Backend::~Backend() = default;

std::string Backend::State() const {
  if (!gpu()) return "cpu";
  if (context_->lost()) return "cpu (gpu failed: the OpenGL context was lost)";
  std::lock_guard<std::mutex> lock(mutex_);
  if (attach_failed_) return "cpu (gpu failed: " + failure_ + ")";
  return "gpu";
}

std::string Backend::renderer() const { return gpu() ? context_->info().renderer : std::string(); }

void Backend::Attach(CcdEngine* engine) {
  if (!gpu()) return;
  std::lock_guard<std::mutex> lock(mutex_);
  if (attach_failed_) return;
  try {
    const uint64_t id = engine->environment().content_id();
    std::shared_ptr<const GpuEnvironment> env;
    for (const auto& [key, upload] : uploaded_) {
      if (key == id) env = upload;
    }
    if (env == nullptr) {
      env = std::make_shared<const GpuEnvironment>(context_, engine->environment());
      uploaded_.emplace_back(id, env);
      if (uploaded_.size() > kKeptUploads) uploaded_.pop_front();
    }
    engine->SetCuller(
        std::make_shared<GpuCuller>(env, engine->filter(), engine->skeleton().num_links()));
  } catch (const GpuError& e) {
    attach_failed_ = true;
    failure_ = e.what();
    spdlog::error("GPU backend failed, queries continue on the CPU: {}", e.what());
  }
}

}  // namespace sweptccd::gpu
