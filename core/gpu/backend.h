#pragma once
// Choosing the query backend (`--backend cpu|gpu|auto`) and attaching the GPU
// one to engines. The process keeps one Backend: one headless context, each
// environment uploaded once.

#include <deque>
#include <memory>
#include <mutex>
#include <optional>
#include <string>

#include "core/gpu/device_descent.h"
#include "core/gpu/gl_context.h"
#include "core/gpu/gpu_culler.h"
#include "core/query/ccd_query.h"

namespace sweptccd::gpu {

class GpuEnvironment;

/// Which backend answers queries (`--backend`, the daemon's `backend` key).
enum class BackendKind {
  kCpu,   // The CPU engine only.
  kGpu,   // The GPU swept-volume test; the CPU when no context can be had.
  kAuto,  // Whichever a short calibration on the loaded scene finds faster
          // (Backend::ResolveAuto); the CPU when no context can be made.
};

/// Parses "cpu", "gpu" or "auto" (the only place the names are read).
/// Throws InputError("WHERE must be cpu, gpu or auto, got 'NAME'"), `where`
/// naming the flag or key (e.g. "--backend", "FILE: backend").
BackendKind ParseBackendKind(const std::string& name, const std::string& where);

/// "cpu", "gpu" or "auto".
const char* BackendKindName(BackendKind kind);

struct BackendOptions {
  BackendKind backend = BackendKind::kAuto;
  int device_index = -1;          // EGL device to use; -1: the first that works.
  bool require_hardware = false;  // gpu and auto: refuse software renderers.
  /// Pairs the caller answers at once (`--threads`): auto calibrates on a
  /// batch answered by this many workers when > 1 (TimeBackendsBatched).
  int threads = 1;
};

class Backend {
 public:
  /// cpu: the CPU. gpu: the headless context on the configured device, else
  /// the first that works, software renderers included unless
  /// require_hardware. auto: makes the context as gpu does, then waits for
  /// ResolveAuto to measure which backend is faster on the scene (until then
  /// gpu() is true when a context was made). A GPU that cannot be had is not
  /// an error: the CPU is chosen and reason() says why (the caller shows it
  /// once: `query` on stderr, the daemon in its log). Does not throw for a
  /// missing GPU.
  explicit Backend(const BackendOptions& options);
  ~Backend();

  /// auto only (a no-op otherwise, and after the first call): times both
  /// backends on `environment` with `skeleton` (nullptr: a one-capsule
  /// calibration skeleton) and `filter` (nullptr: none) over the fixed
  /// calibration pairs (core/gpu/backend_calibration.h, under 0.5 s) and
  /// keeps the faster, ties to the CPU; choosing the CPU releases the
  /// context. reason() and State() then name both figures, e.g.
  /// "cpu (auto: cpu 41 us, gpu 380 us per pair; ...)". Call before Attach
  /// and before queries start; not thread-safe against Attach. Throws only
  /// what a CPU query throws (std::bad_alloc).
  void ResolveAuto(const Environment& environment, const Skeleton* skeleton,
                   const CollisionFilter* filter, const QueryOptions& options);

  bool gpu() const { return context_ != nullptr; }
  /// "cpu" or "gpu": what was chosen at start.
  const char* name() const { return gpu() ? "gpu" : "cpu"; }
  /// What answers now: "gpu", or "cpu (gpu failed: CAUSE)" once the context
  /// was lost or an upload failed (queries then run on the CPU), or "cpu";
  /// after ResolveAuto, "gpu" and "cpu" carry the figures: "cpu (auto: cpu
  /// 41 us, gpu 380 us per pair)".
  std::string State() const;
  /// One line: what was asked, what was chosen, and why.
  const std::string& reason() const { return reason_; }
  /// The GPU renderer, empty on the CPU.
  std::string renderer() const;
  std::shared_ptr<GlContext> context() const { return context_; }

  /// The GPU's dispatches so far over the kept uploads (every engine and
  /// thread; zeros on the CPU), and one line saying them: "N dispatches, R
  /// requests, C capsules (C/N per dispatch, largest L; up to M requests in
  /// one)".
  DispatchStats dispatch_stats() const;
  std::string DispatchSummary() const;

  /// Gives `engine` the GPU swept-volume test. Its environment is uploaded
  /// once and stays resident while an engine uses it (later engines on the
  /// same environment share the upload). No-op on the CPU. On a GPU failure the cause is logged and
  /// the engine stays on the CPU. Thread-safe. auto: ResolveAuto must have been called (checked: a
  /// bug otherwise).
  void Attach(CcdEngine* engine);

  /// The device descent (core/gpu/device_descent.h) on `environment`'s
  /// upload (the one Attach uses). nullptr on the CPU, or when the upload
  /// or the program fails (logged; the CPU answers alone). Thread-safe.
  std::unique_ptr<DeviceDescent> MakeDescent(const Environment& environment,
                                             const DescentOptions& options);

 private:
  // The upload of `environment` (kept, shared); the mutex held. Throws GpuError.
  std::shared_ptr<const GpuEnvironment> UploadLocked(const Environment& environment);

  std::shared_ptr<GlContext> context_;
  std::string reason_;
  bool auto_pending_ = false;  // auto with a context, not yet resolved.
  int threads_ = 1;            // BackendOptions::threads.
  std::string auto_figures_;   // "auto: cpu 41 us, gpu 380 us per pair" once resolved.
  mutable std::mutex mutex_;
  // The latest uploads by Environment::content_id() (an address can be
  // reused by a later environment; the id cannot), oldest first. Engines keep
  // their own upload alive; this only saves re-uploading for the next engine.
  static constexpr size_t kKeptUploads = 8;
  std::deque<std::pair<uint64_t, std::shared_ptr<const GpuEnvironment>>> uploaded_;
  bool attach_failed_ = false;
  std::string failure_;
};

}  // namespace sweptccd::gpu
