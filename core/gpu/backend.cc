#include "core/gpu/backend.h"

#include <spdlog/spdlog.h>

#include <algorithm>
#include <cstdio>

#include "core/errors.h"
#include "core/gpu/backend_calibration.h"
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

Backend::Backend(const BackendOptions& options) : threads_(std::max(1, options.threads)) {
  const bool automatic = options.backend == BackendKind::kAuto;
  if (options.backend == BackendKind::kCpu) {
    reason_ = "cpu (requested)";
    return;
  }
  GlContextOptions context_options;
  context_options.device_index = options.device_index;
  context_options.require_hardware = options.require_hardware;
  try {
    context_ = std::make_shared<GlContext>(context_options);
  } catch (const GpuError& e) {
    if (automatic) {
      reason_ = std::string("cpu (auto: no GPU context, not calibrated; ") + e.what() + ")";
    } else {
      reason_ = std::string("cpu (gpu requested but unavailable: ") + e.what() + ")";
    }
    return;
  }
  if (automatic) {
    auto_pending_ = true;
    reason_ = "auto (not calibrated yet; " + context_->info().Summary() + ")";
    return;
  }
  reason_ = "gpu (requested; " + context_->info().Summary() + ")";
}

void Backend::ResolveAuto(const Environment& environment, const Skeleton* skeleton,
                          const CollisionFilter* filter, const QueryOptions& options) {
  if (!auto_pending_) return;
  auto_pending_ = false;
  const Skeleton fallback = skeleton == nullptr ? CalibrationSkeleton() : Skeleton();
  const Skeleton& sk = skeleton == nullptr ? fallback : *skeleton;
  CollisionFilter none(sk.num_links(), environment.num_objects());
  const CollisionFilter& fl = filter == nullptr ? none : *filter;
  const std::string renderer = context_->info().Summary();
  CcdEngine cpu_engine(sk, environment, fl);
  CcdEngine gpu_engine(sk, environment, fl);
  Attach(&gpu_engine);
  if (gpu_engine.culler() == nullptr) {
    // The upload failed (logged by Attach): the GPU cannot answer here.
    reason_ = "cpu (auto: the GPU could not take the scene, not calibrated; " + failure_ + ")";
    context_.reset();
    uploaded_.clear();
    return;
  }
  // Per pair, or (a caller with several workers) per pair of a batch
  // answered by that many workers, the GPU's requests sharing dispatches.
  size_t batch = 0;
  const CalibrationTimes times =
      threads_ > 1
          ? TimeBackendsBatched(cpu_engine, gpu_engine, CalibrationPairs(sk, environment), options,
                                threads_, CalibrationBudget(), &batch)
          : TimeBackends(cpu_engine, gpu_engine, CalibrationPairs(sk, environment), options);
  const AutoChoice choice = ChooseFaster(times.cpu_us, times.gpu_us);
  auto_figures_ = "auto: " + DescribeFigures(choice);
  const std::string samples = threads_ > 1
                                  ? " timed batches of " + std::to_string(batch) + " pairs on " +
                                        std::to_string(threads_) + " threads each; "
                                  : " timed pairs each; ";
  const std::string how =
      auto_figures_ + ", medians of " + std::to_string(times.cpu_us.size()) + samples + renderer;
  if (choice.kind == BackendKind::kGpu) {
    reason_ = "gpu (" + how + ")";
    return;
  }
  reason_ = "cpu (" + how + ")";
  // The GPU's culler dies with gpu_engine; the context and uploads go too.
  gpu_engine.SetCuller(nullptr);
  uploaded_.clear();
  context_.reset();
}

Backend::~Backend() = default;

std::string Backend::State() const {
  const std::string figures = auto_figures_.empty() ? "" : " (" + auto_figures_ + ")";
  if (!gpu()) return "cpu" + figures;
  if (context_->lost()) return "cpu (gpu failed: the OpenGL context was lost)";
  std::lock_guard<std::mutex> lock(mutex_);
  if (attach_failed_) return "cpu (gpu failed: " + failure_ + ")";
  return "gpu" + figures;
}

std::string Backend::renderer() const { return gpu() ? context_->info().renderer : std::string(); }

DispatchStats Backend::dispatch_stats() const {
  std::lock_guard<std::mutex> lock(mutex_);
  DispatchStats total;
  for (const auto& [id, upload] : uploaded_) {
    const DispatchStats s = upload->dispatch_stats();
    total.dispatches += s.dispatches;
    total.requests += s.requests;
    total.capsules += s.capsules;
    total.largest = std::max(total.largest, s.largest);
    total.most_requests = std::max(total.most_requests, s.most_requests);
  }
  return total;
}

std::string Backend::DispatchSummary() const {
  const DispatchStats s = dispatch_stats();
  char line[256];
  std::snprintf(line, sizeof(line),
                "%lld dispatches, %lld requests, %lld capsules (%.1f per dispatch, largest %lld; "
                "up to %lld requests in one)",
                static_cast<long long>(s.dispatches), static_cast<long long>(s.requests),
                static_cast<long long>(s.capsules),
                s.dispatches > 0 ? static_cast<double>(s.capsules) / s.dispatches : 0.0,
                static_cast<long long>(s.largest), static_cast<long long>(s.most_requests));
  return line;
}

void Backend::Attach(CcdEngine* engine) {
  SWEPTCCD_CHECK(!auto_pending_);  // ResolveAuto first (backend.h).
  if (!gpu()) return;
  std::lock_guard<std::mutex> lock(mutex_);
  if (attach_failed_) return;
  try {
    const std::shared_ptr<const GpuEnvironment> env = UploadLocked(engine->environment());
    engine->SetCuller(
        std::make_shared<GpuCuller>(env, engine->filter(), engine->skeleton().num_links()));
  } catch (const GpuError& e) {
    attach_failed_ = true;
    failure_ = e.what();
    spdlog::error("GPU backend failed, queries continue on the CPU: {}", e.what());
  }
}

std::shared_ptr<const GpuEnvironment> Backend::UploadLocked(const Environment& environment) {
  const uint64_t id = environment.content_id();
  for (const auto& [key, upload] : uploaded_) {
    if (key == id) return upload;
  }
  auto env = std::make_shared<const GpuEnvironment>(context_, environment);
  uploaded_.emplace_back(id, env);
  if (uploaded_.size() > kKeptUploads) uploaded_.pop_front();
  return env;
}

std::unique_ptr<DeviceDescent> Backend::MakeDescent(const Environment& environment,
                                                    const DescentOptions& options) {
  SWEPTCCD_CHECK(!auto_pending_);  // ResolveAuto first (backend.h).
  if (!gpu()) return nullptr;
  std::lock_guard<std::mutex> lock(mutex_);
  if (attach_failed_) return nullptr;
  try {
    return std::make_unique<DeviceDescent>(UploadLocked(environment), environment, options);
  } catch (const GpuError& e) {
    spdlog::error("GPU device descent unavailable, queries run on the CPU: {}", e.what());
    return nullptr;
  }
}

}  // namespace sweptccd::gpu
