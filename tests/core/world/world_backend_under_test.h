#pragma once
// The backend the shared world's environment suite (world_environment_test)
// runs against, as tests/core/query/backend_under_test.h is for the
// collision suites. The suite is built twice: with world_backend_cpu.cc (no
// way but the CPU engine's) and with world_backend_gpu.cc (the GPU backend
// on the headless EGL context, llvmpipe in CI: the swept-volume culler
// attached to every avatar's engine, and the device descent as `sweptccd
// world --backend gpu --device-descent` runs it). Every way's records must
// equal the CPU-only answerer's, timing and work counters aside.

#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "core/query/ccd_query.h"
#include "core/world/world_file.h"

namespace sweptccd::testing {

/// "cpu" or "gpu".
const char* WorldBackendName();

/// One way the backend under test answers a world.
class WorldWay {
 public:
  virtual ~WorldWay() = default;
  /// E.g. "gpu culler", "gpu device descent".
  virtual std::string name() const = 0;
  /// Every record of every avatar (avatars in world order, records in
  /// stream order) as `sweptccd world` writes it (WorldAnswerer::RecordJson).
  /// Throws (failing the test, never skipping it) when the GPU cannot be
  /// set up or fails.
  virtual std::vector<std::string> Answer(const world::LoadedWorld& world,
                                          const QueryOptions& options) = 0;
  /// Work the backend did on the device over every Answer so far (culler
  /// round trips, or intervals the descent cleared): a way that never ran
  /// on the device proves nothing.
  virtual int64_t device_work() const = 0;
};

/// The ways of this build: none for the CPU (its records are the
/// reference), the culler and the device descent for the GPU.
std::vector<std::unique_ptr<WorldWay>> WorldWays();

}  // namespace sweptccd::testing
