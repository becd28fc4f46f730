#include <memory>
#include <mutex>

#include "core/gpu/gl_context.h"
#include "core/gpu/gpu_culler.h"
#include "tests/core/backend_under_test.h"

namespace sweptccd::testing {

const char* BackendName() { return "gpu"; }

void AttachBackend(CcdEngine* engine) {
  // One context for the whole test binary, as the daemon keeps one; each
  // engine's environment is uploaded once and stays resident while it lives.
  static std::mutex mutex;
  static std::shared_ptr<gpu::GlContext> context;
  std::lock_guard<std::mutex> lock(mutex);
  if (context == nullptr) context = std::make_shared<gpu::GlContext>();
  auto env = std::make_shared<const gpu::GpuEnvironment>(context, engine->environment());
  engine->SetCuller(std::make_shared<gpu::GpuCuller>(env, engine->filter(),
                                                     engine->skeleton().num_links()));
}

}  // namespace sweptccd::testing
