#include "tools/world_command.h"

#include <spdlog/spdlog.h>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <fstream>
#include <iostream>
#include <memory>
#include <nlohmann/json.hpp>
#include <vector>

#include "core/errors.h"
#include "core/gpu/device_descent.h"
#include "core/percentile.h"
#include "core/query/pair_clears.h"
#include "core/world/world_query.h"
#include "msgs/text.h"

namespace sweptccd {

int RunWorldCommand(const WorldCommandOptions& options) {
  try {
    const std::string problem = ValidateQueryOptions(options.query);
    if (!problem.empty()) throw InputError("sweptccd world: " + problem);
    const world::LoadedWorld loaded = world::LoadWorldFile(options.world_path, options.load);
    // Every file the world names is an input the output must not be.
    std::vector<NamedPath> inputs = {{"--world", options.world_path}};
    for (const auto& [role, path] : loaded.files) inputs.push_back({"--world's " + role, path});
    ResultsOutput results(options.output_path, inputs);
    results.Open();
    std::ostream* out = &results.stream();
    // One answerer per worker (an answerer keeps per-record state and is not
    // thread-safe); the records are answered in chunks by the workers and
    // written in order, the same for any --threads.
    WorkerPool pool(options.threads);
    std::vector<std::unique_ptr<world::WorldAnswerer>> answerers;
    for (int w = 0; w < pool.size(); ++w) {
      answerers.push_back(std::make_unique<world::WorldAnswerer>(loaded, options.query));
    }
    // The static-environment part runs on the chosen backend; the parts
    // between entities run on the CPU under every backend (same answers).
    gpu::BackendOptions backend_options = options.backend.Options();
    backend_options.threads = options.threads;  // auto: calibrated on a batch of that many.
    gpu::Backend backend(backend_options);
    // auto: calibrated with the first avatar's engine (the one-capsule
    // calibration skeleton when the world has no avatar).
    const CcdEngine* first = nullptr;
    answerers[0]->ForEachEngine([&](CcdEngine* engine) {
      if (first == nullptr) first = engine;
    });
    backend.ResolveAuto(loaded.env, first ? &first->skeleton() : nullptr,
                        first ? &first->filter() : nullptr, options.query);
    if (options.backend.backend != gpu::BackendKind::kCpu) {
      std::fprintf(stderr, "sweptccd world: backend %s\n", backend.reason().c_str());
    }
    // --device-descent: each chunk's environment parts cleared on the GPU in
    // one batch, then the CPU engines (no culler: what the device left is
    // decided by the CPU). Not with an empty environment (every part free).
    std::unique_ptr<gpu::DeviceDescent> descent;
    if (options.device_descent && backend.gpu() && loaded.env.num_objects() > 0) {
      gpu::DescentOptions descent_options;
      descent_options.host_threads = options.threads;
      descent = backend.MakeDescent(loaded.env, descent_options);
    }
    // The descent's engine of each avatar: answerers[0]'s (every answerer's
    // engine of an avatar has the same skeleton, filter and environment).
    std::vector<int> descent_engine;
    if (descent != nullptr) {
      answerers[0]->ForEachEngine(
          [&](CcdEngine* engine) { descent_engine.push_back(descent->AddEngine(*engine)); });
      SWEPTCCD_CHECK(descent_engine.size() == loaded.world.avatars.size());
    } else {
      for (auto& answerer : answerers) {
        answerer->ForEachEngine([&](CcdEngine* engine) { backend.Attach(engine); });
      }
    }
    std::vector<gpu::DeviceDescent::Pair> descent_pairs;
    std::vector<size_t> descent_slot;  // The record (in the chunk) of each descent pair.
    std::vector<PairClears> clears;
    std::vector<const PairClears*> clears_of;
    std::vector<std::pair<world::AvatarIndex, size_t>> all;
    for (int a = 0; a < static_cast<int>(loaded.world.avatars.size()); ++a) {
      for (size_t r = 0; r < loaded.world.avatars[a].records.size(); ++r) {
        all.emplace_back(world::AvatarIndex(a), r);
      }
    }
    int64_t records = 0, entries = 0, contacts = 0, culled = 0;
    std::vector<double> record_us(all.size());
    // Runs of consecutive records go to one worker (an answerer reuses the
    // motion of the record before), a chunk of runs at a time.
    constexpr size_t kRun = 8;
    const size_t chunk = kRun * 16 * static_cast<size_t>(pool.size());
    std::vector<std::string> lines;
    for (size_t begin = 0; begin < all.size(); begin += chunk) {
      const size_t end = std::min(all.size(), begin + chunk);
      lines.assign(end - begin, std::string());
      clears_of.assign(end - begin, nullptr);
      if (descent != nullptr) {
        descent_pairs.clear();
        descent_slot.clear();
        for (size_t i = begin; i < end; ++i) {
          const world::AvatarEntity& A = loaded.world.avatars[all[i].first];
          const PairOutcome& rec = A.records[all[i].second];
          if (!rec.valid) continue;
          descent_pairs.push_back({descent_engine[static_cast<size_t>(all[i].first)], &rec.pose0,
                                   &rec.pose1, A.motion});
          descent_slot.push_back(i - begin);
        }
        (void)descent->Run(descent_pairs, options.query, &clears);  // Failed: clears nothing.
        for (size_t j = 0; j < descent_slot.size(); ++j) clears_of[descent_slot[j]] = &clears[j];
      }
      pool.Run((end - begin + kRun - 1) / kRun, [&](size_t run, int worker) {
        for (size_t i = begin + run * kRun; i < std::min(end, begin + (run + 1) * kRun); ++i) {
          const auto start = std::chrono::steady_clock::now();
          lines[i - begin] =
              answerers[worker]->RecordJson(all[i].first, all[i].second, clears_of[i - begin]);
          record_us[i] =
              std::chrono::duration<double, std::micro>(std::chrono::steady_clock::now() - start)
                  .count();
        }
      });
      for (const std::string& line : lines) {
        ++records;
        if (!options.bench) {
          *out << line << '\n';
          continue;
        }
        const nlohmann::json record = nlohmann::json::parse(line);
        for (const auto& e : record["others"]) {
          ++entries;
          contacts += e["result"] == "contact";
          culled += e["stats"]["culled_by_box"].get<bool>();
        }
      }
    }
    if (options.bench) {
      const Summary us = Summarise(record_us);  // The one percentile rule.
      double total = 0;
      for (double v : record_us) total += v;
      std::fprintf(stderr, "sweptccd world --bench: %s\n", options.world_path.c_str());
      *out << "avatars " << loaded.world.avatars.size() << "\nobjects "
           << loaded.world.objects.size() << "\nrecords " << records << "\nentity_entries "
           << entries << "\nentity_contacts " << contacts << "\nculled_by_box " << culled
           << "\ntotal_s " << total * 1e-6 << "\nrecord_us_p50 " << us.median << "\nrecord_us_p99 "
           << us.p99 << "\nrecord_us_max " << us.max << '\n';
    }
    results.Finish();
    spdlog::info("{} records", records);
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
