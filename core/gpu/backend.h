#pragma once
// Choosing the query backend (`--backend cpu|gpu|auto`) and attaching the GPU
// one to engines. The process keeps one Backend: one headless context, each
// environment uploaded once.

#include <deque>
#include <memory>
#include <mutex>
#include <optional>
#include <string>

#include "core/query/ccd_query.h"
#include "core/gpu/gl_context.h"

namespace sweptccd::gpu {

class GpuEnvironment;

/// Which backend answers queries (`--backend`, the daemon's `backend` key).
enum class BackendKind {
  kCpu,   // The CPU engine only.
  kGpu,   // The GPU swept-volume test; the CPU when no context can be had.
  kAuto,  // The GPU on a hardware EGL device, else the CPU.
};

/// Parses "cpu", "gpu" or "auto" (the only place the names are read).
/// Throws InputError("WHERE must be cpu, gpu or auto, got 'NAME'"), `where`
/// naming the flag or key (e.g. "--backend", "FILE: backend").
BackendKind ParseBackendKind(const std::string& name, const std::string& where);

/// "cpu", "gpu" or "auto".
const char* BackendKindName(BackendKind kind);

struct BackendOptions {
  BackendKind backend = BackendKind::kAuto;
  int device_index = -1;         // EGL device to use; -1: the first that works.
  bool require_hardware = false;  // gpu: refuse software renderers (auto always does).
};

class Backend {
 public:
  /// cpu: the CPU. gpu: the headless context on the configured device, else
  /// the first that works, software renderers included unless
  /// require_hardware. auto: the GPU only on a hardware device, else the CPU.
  /// A GPU that cannot be had is not an error: the CPU is chosen and
  /// reason() says why (the caller shows it once: `query` on stderr, the
  /// daemon in its log). Does not throw for a missing GPU.
  explicit Backend(const BackendOptions& options);
  ~Backend();

  bool gpu() const { return context_ != nullptr; }
  /// "cpu" or "gpu": what was chosen at start.
  const char* name() const { return gpu() ? "gpu" : "cpu"; }
  /// What answers now: "gpu", or "cpu (gpu failed: CAUSE)" once the context
  /// was lost or an upload failed (queries then run on the CPU), or "cpu".
  std::string State() const;
  /// One line: what was asked, what was chosen, and why.
  const std::string& reason() const { return reason_; }
  /// The GPU renderer, empty on the CPU.
  std::string renderer() const;
  std::shared_ptr<GlContext> context() const { return context_; }

  /// Gives `engine` the GPU swept-volume test. Its environment is uploaded
  /// once and stays resident while an engine uses it (later engines on the
  /// same environment share the upload). No-op on the CPU. On a GPU failure the cause is logged and the
  /// engine stays on the CPU. Thread-safe.
  void Attach(CcdEngine* engine);

 private:
  std::shared_ptr<GlContext> context_;
  std::string reason_;
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
