#pragma once
// `sweptccd world`: answers every avatar pair of a shared world file
// (SPEC section 8, "Offline").

#include <string>

#include "core/gpu/backend.h"
#include "core/query/ccd_query.h"
#include "core/worker_pool.h"
#include "core/world/world_file.h"
#include "tools/command_common.h"

namespace sweptccd {

struct WorldCommandOptions {
  std::string world_path;
  std::string output_path;       // Empty: standard output.
  BackendFlags backend;          // --backend, --gpu-device, --require-hardware.
  QueryOptions query;            // eps, delta, per-link, work limit (motion: per avatar).
  world::WorldLoadOptions load;  // --max-links (load.max_links).
  /// --bench: answer every record as usual but print a table (counts and
  /// time per record) instead of the records.
  bool bench = false;
  int threads = DefaultThreadCount();  // --threads: workers answering the records.
  /// --device-descent: with the GPU chosen, the environment parts of each
  /// chunk of records have their free intervals cleared on the GPU
  /// (core/gpu/device_descent.h) and the CPU engines answer them skipping
  /// those, instead of the per-pair round trips; the parts between entities
  /// stay on the CPU. The same records.
  bool device_descent = false;
};

/// Runs the command. Returns 0 when the inputs could be read, 2 with a
/// one-line message on stderr when not.
int RunWorldCommand(const WorldCommandOptions& options);

}  // namespace sweptccd
