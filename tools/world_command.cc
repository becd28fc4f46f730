#include "tools/world_command.h"

#include <spdlog/spdlog.h>

#include <cstdio>
#include <fstream>
#include <iostream>

#include "core/errors.h"
#include "core/world/world_query.h"

namespace sweptccd {

int RunWorldCommand(const WorldCommandOptions& options) {
  try {
    const std::string problem = ValidateQueryOptions(options.query);
    if (!problem.empty()) throw InputError("sweptccd world: " + problem);
    const world::LoadedWorld loaded = world::LoadWorldFile(options.world_path, options.load);
    std::ofstream file_out;
    std::ostream* out = &std::cout;
    if (!options.output_path.empty()) {
      file_out.open(options.output_path, std::ios::binary | std::ios::trunc);
      if (!file_out) throw InputError(options.output_path + ": cannot open the output file");
      out = &file_out;
    }
    world::WorldAnswerer answerer(loaded, options.query);
    // The static-environment part runs on the chosen backend; the parts
    // between entities run on the CPU under every backend (same answers).
    gpu::BackendOptions backend_options;
    backend_options.backend = options.backend;
    gpu::Backend backend(backend_options);
    if (options.backend != gpu::BackendKind::kCpu) {
      std::fprintf(stderr, "sweptccd world: backend %s\n", backend.reason().c_str());
    }
    answerer.ForEachEngine([&](CcdEngine* engine) { backend.Attach(engine); });
    int64_t records = 0;
    for (int a = 0; a < static_cast<int>(loaded.world.avatars.size()); ++a) {
      for (size_t r = 0; r < loaded.world.avatars[a].records.size(); ++r) {
        *out << answerer.RecordJson(a, r) << '\n';
        ++records;
      }
    }
    out->flush();
    if (!*out) {
      throw InputError((options.output_path.empty() ? std::string("standard output")
                                                    : options.output_path) +
                       ": error while writing the results");
    }
    spdlog::info("{} records", records);
    return 0;
  } catch (const InputError& e) {
    std::fprintf(stderr, "error: %s\n", e.what());
    return 2;
  } catch (const std::bad_alloc&) {
    std::fprintf(stderr, "error: out of memory\n");
    return 3;
  }
}

}  // namespace sweptccd
