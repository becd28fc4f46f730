#pragma once
// `sweptccd query`: answers every pair of a pose stream file (SPEC section 7).

#include <string>
#include <vector>

#include "core/avatar/skeleton.h"
#include "core/geometry/mesh.h"
#include "core/gpu/backend.h"
#include "core/query/ccd_query.h"
#include "core/worker_pool.h"
#include "tools/command_common.h"

namespace sweptccd {

struct QueryCommandOptions {
  std::string skeleton_path;
  std::string poses_path;
  std::vector<std::string> env_paths;
  std::string output_path;  // Empty: standard output.
  BackendFlags backend;     // --backend, --gpu-device, --require-hardware.
  std::string filter_path;
  std::vector<std::string> ignore_rules;  // LINK:OBJECT
  QueryOptions query;
  MeshLoadOptions mesh;                // --max-mesh-bytes.
  int max_links = kDefaultMaxLinks;    // --max-links.
  int threads = DefaultThreadCount();  // --threads: workers answering the pairs.
  /// --device-descent: with the GPU chosen, each chunk's free intervals are
  /// cleared on the GPU (core/gpu/device_descent.h) and the CPU engine
  /// answers the pairs skipping them, instead of the per-pair round trips.
  bool device_descent = false;
};

/// Runs the command. Returns the exit status: 0 when the inputs could be
/// read (even with invalid pairs), 2 with a one-line message on stderr when not.
int RunQueryCommand(const QueryCommandOptions& options);

}  // namespace sweptccd
