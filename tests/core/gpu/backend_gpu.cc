#include <memory>

#include "core/gpu/backend.h"
#include "tests/core/query/backend_under_test.h"

namespace sweptccd::testing {

const char* BackendName() { return "gpu"; }

void AttachBackend(CcdEngine* engine) {
  // One Backend for the whole test binary, as the daemon keeps one: one
  // context (any renderer: llvmpipe in CI), uploads shared by environment.
  static gpu::Backend backend([] {
    gpu::BackendOptions options;
    options.backend = gpu::BackendKind::kGpu;
    return options;
  }());
  if (!backend.gpu()) throw gpu::GpuError("no GPU backend for the suite: " + backend.reason());
  backend.Attach(engine);
  if (engine->culler() == nullptr) throw gpu::GpuError("the GPU backend could not attach");
}

}  // namespace sweptccd::testing
