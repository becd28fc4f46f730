#include "tools/query_command.h"

#include <spdlog/spdlog.h>

#include <chrono>
#include <cstdio>
#include <fstream>
#include <iostream>
#include <memory>

#include "core/avatar/pose.h"
#include "core/avatar/skeleton.h"
#include "core/bounded_file.h"
#include "core/errors.h"
#include "core/gpu/backend.h"
#include "core/query/query_scene.h"
#include "core/query/result_json.h"
#include "core/scene/collision_filter.h"
#include "core/scene/environment.h"
#include "msgs/text.h"
#include "tools/command_common.h"

namespace sweptccd {

int RunQueryCommand(const QueryCommandOptions& options) {
  try {
    const std::string problem = ValidateQueryOptions(options.query);
    if (!problem.empty()) throw InputError("sweptccd query: " + problem);
    std::vector<NamedPath> inputs = {{"--skeleton", options.skeleton_path},
                                     {"--poses", options.poses_path},
                                     {"--filter", options.filter_path}};
    for (const std::string& e : options.env_paths) inputs.push_back({"--env", e});
    ResultsOutput results(options.output_path, inputs);  // Refuses an output that is an input.
    const Skeleton skeleton = LoadSkeletonFile(options.skeleton_path, options.max_links);
    std::ifstream poses = OpenInputFile(options.poses_path, "pose stream file");

    QuerySceneSpec spec;
    spec.env_paths = options.env_paths;
    spec.filter_path = options.filter_path;
    spec.ignore_rules = options.ignore_rules;
    spec.mesh = options.mesh;
    const std::unique_ptr<QueryScene> scene = LoadQueryScene(spec, skeleton, "sweptccd query");
    const Environment& env = scene->env;

    results.Open();
    std::ostream* out = &results.stream();

    CcdEngine engine(skeleton, env, std::move(scene->filter));
    // The backend: says on stderr which it picked and why (a GPU that cannot
    // be had is logged and the CPU answers).
    gpu::BackendOptions backend_options = options.backend.Options();
    backend_options.threads = options.threads;  // auto: calibrated on a batch of that many.
    gpu::Backend backend(backend_options);
    // auto: a short calibration on this scene and skeleton picks the faster.
    backend.ResolveAuto(env, &skeleton, &engine.filter(), options.query);
    if (options.backend.backend != gpu::BackendKind::kCpu) {
      std::fprintf(stderr, "sweptccd query: backend %s\n", backend.reason().c_str());
    }
    // --device-descent: the chunk's free intervals on the GPU, then the CPU
    // engine (no culler: what the device left is decided by the CPU).
    std::unique_ptr<gpu::DeviceDescent> descent;
    if (options.device_descent && backend.gpu()) {
      gpu::DescentOptions descent_options;
      descent_options.host_threads = options.threads;
      descent = backend.MakeDescent(env, descent_options);
    }
    int descent_engine = 0;
    if (descent != nullptr) {
      descent_engine = descent->AddEngine(engine);
    } else {
      backend.Attach(&engine);
    }
    std::vector<gpu::DeviceDescent::Pair> descent_pairs;
    std::vector<size_t> descent_slot;  // The outcome of each descent pair.
    std::vector<PairClears> clears;
    std::vector<const PairClears*> clears_of;
    PoseStreamReader reader(poses, skeleton.num_links());
    // The pairs are read in chunks; a chunk's valid pairs are answered by the
    // workers (each into its own slot), then written in input order, so the
    // records are the same for any --threads (elapsed_us aside).
    WorkerPool pool(options.threads);
    const size_t chunk = 64 * static_cast<size_t>(pool.size());
    std::vector<PairOutcome> outcomes;
    std::vector<std::string> lines;
    int64_t pairs = 0, invalid = 0, contacts = 0;
    for (bool more = true; more;) {
      outcomes.clear();
      while (outcomes.size() < chunk) {
        std::optional<PairOutcome> outcome = reader.Next();
        if (!outcome) {
          more = false;
          break;
        }
        outcomes.push_back(std::move(*outcome));
      }
      lines.assign(outcomes.size(), std::string());
      std::vector<uint8_t> contact(outcomes.size(), 0);
      clears_of.assign(outcomes.size(), nullptr);
      if (descent != nullptr) {
        descent_pairs.clear();
        descent_slot.clear();
        for (size_t i = 0; i < outcomes.size(); ++i) {
          if (!outcomes[i].valid) continue;
          descent_pairs.push_back({descent_engine, &outcomes[i].pose0, &outcomes[i].pose1, {}});
          descent_slot.push_back(i);
        }
        (void)descent->Run(descent_pairs, options.query, &clears);  // Failed: clears nothing.
        for (size_t j = 0; j < descent_slot.size(); ++j) clears_of[descent_slot[j]] = &clears[j];
      }
      pool.Run(outcomes.size(), [&](size_t i, int) {
        const PairOutcome& o = outcomes[i];
        if (!o.valid) {
          lines[i] = InvalidResultToJson(o.pair, o.utime0, o.utime1, o.error);
          return;
        }
        const auto start = std::chrono::steady_clock::now();
        const QueryResult result = engine.Query(o.pose0, o.pose1, options.query, clears_of[i]);
        const double elapsed_us =
            std::chrono::duration<double, std::micro>(std::chrono::steady_clock::now() - start)
                .count();
        contact[i] = result.contact;
        lines[i] = ResultToJson(o.pair, o.pose0.utime, o.pose1.utime, result,
                                options.query.per_link, elapsed_us);
      });
      for (size_t i = 0; i < outcomes.size(); ++i) {
        if (outcomes[i].valid) {
          ++pairs;
          contacts += contact[i];
        } else {
          ++invalid;
        }
        *out << lines[i] << '\n';
      }
    }
    if (reader.bad()) throw InputError(options.poses_path + ": error while reading");
    if (!reader.first_line_error().empty()) {
      spdlog::warn("{}: {}", options.poses_path, reader.first_line_error());
    }
    results.Finish();
    spdlog::info("{} pairs queried ({} contact), {} invalid", pairs, contacts, invalid);
    LogGpuWork(backend, descent.get());
    return 0;
  } catch (const InputError& e) {
    std::fprintf(stderr, "error: %s\n", DisplayError(e.what()).c_str());
    return 2;
  } catch (const std::bad_alloc&) {
    std::fprintf(stderr, "error: out of memory\n");
    return 3;
  }
}

}  // namespace sweptccd
