#include <algorithm>
#include <cstdio>
#include <nlohmann/json.hpp>
#include <utility>

#include "core/gpu/backend.h"
#include "core/gpu/device_descent.h"
#include "core/query/pair_clears.h"
#include "core/world/world_query.h"
#include "tests/core/world/world_backend_under_test.h"

namespace sweptccd::testing {
namespace {

// One Backend for the whole test binary, as `sweptccd world` and the daemon
// keep one: one context (any renderer: llvmpipe in CI), uploads shared by
// environment.
gpu::Backend& TheBackend() {
  static gpu::Backend backend([] {
    gpu::BackendOptions options;
    options.backend = gpu::BackendKind::kGpu;
    return options;
  }());
  if (!backend.gpu()) throw gpu::GpuError("no GPU backend for the suite: " + backend.reason());
  static const bool said = [] {
    std::printf("GPU backend on %s\n", backend.renderer().c_str());
    return true;
  }();
  (void)said;
  return backend;
}

// Every (avatar, record) of the world, in the order `sweptccd world` writes them.
std::vector<std::pair<world::AvatarIndex, size_t>> AllRecords(const world::LoadedWorld& w) {
  std::vector<std::pair<world::AvatarIndex, size_t>> all;
  for (int a = 0; a < static_cast<int>(w.world.avatars.size()); ++a) {
    for (size_t r = 0; r < w.world.avatars[a].records.size(); ++r) {
      all.emplace_back(world::AvatarIndex(a), r);
    }
  }
  return all;
}

// `--backend gpu`: the culler attached to every avatar's environment engine.
class CullerWay : public WorldWay {
 public:
  std::string name() const override { return "gpu culler"; }
  std::vector<std::string> Answer(const world::LoadedWorld& w,
                                  const QueryOptions& options) override {
    gpu::Backend& backend = TheBackend();
    world::WorldAnswerer answerer(w, options);
    answerer.ForEachEngine([&](CcdEngine* engine) {
      backend.Attach(engine);
      if (engine->culler() == nullptr) throw gpu::GpuError("the GPU backend could not attach");
    });
    std::vector<std::string> lines;
    for (const auto& [a, r] : AllRecords(w)) {
      lines.push_back(answerer.RecordJson(a, r));
      // The culler's share of the environment part (result_json.cc).
      const nlohmann::json stats =
          nlohmann::json::parse(lines.back()).value("stats", nlohmann::json());
      if (stats.contains("gpu_cleared")) cleared_ += stats["gpu_cleared"].get<int64_t>();
    }
    return lines;
  }
  int64_t device_work() const override { return cleared_; }

 private:
  int64_t cleared_ = 0;
};

// `--backend gpu --device-descent` (tools/world_command.cc): each batch of
// records' environment parts cleared on the device, then the CPU engines
// (no culler) answer the rest with the pairs' clears.
class DescentWay : public WorldWay {
 public:
  std::string name() const override { return "gpu device descent"; }
  std::vector<std::string> Answer(const world::LoadedWorld& w,
                                  const QueryOptions& options) override {
    gpu::Backend& backend = TheBackend();
    world::WorldAnswerer answerer(w, options);
    std::unique_ptr<gpu::DeviceDescent> descent = backend.MakeDescent(w.env, gpu::DescentOptions());
    if (descent == nullptr) throw gpu::GpuError("no device descent on the suite's environment");
    std::vector<int> engine_of;
    answerer.ForEachEngine(
        [&](CcdEngine* engine) { engine_of.push_back(descent->AddEngine(*engine)); });
    const auto all = AllRecords(w);
    std::vector<std::string> lines;
    // Batches of records as `sweptccd world` makes them on one thread (8 x 16).
    constexpr size_t kBatch = 128;
    std::vector<gpu::DeviceDescent::Pair> pairs;
    std::vector<size_t> slot;
    std::vector<PairClears> clears;
    std::vector<const PairClears*> clears_of;
    for (size_t begin = 0; begin < all.size(); begin += kBatch) {
      const size_t end = std::min(all.size(), begin + kBatch);
      pairs.clear();
      slot.clear();
      clears_of.assign(end - begin, nullptr);
      for (size_t i = begin; i < end; ++i) {
        const world::AvatarEntity& A = w.world.avatars[all[i].first];
        const PairOutcome& rec = A.records[all[i].second];
        if (!rec.valid) continue;
        pairs.push_back(
            {engine_of[static_cast<size_t>(all[i].first)], &rec.pose0, &rec.pose1, A.motion});
        slot.push_back(i - begin);
      }
      if (!descent->Run(pairs, options, &clears)) throw gpu::GpuError("the device descent failed");
      for (size_t j = 0; j < slot.size(); ++j) clears_of[slot[j]] = &clears[j];
      for (size_t i = begin; i < end; ++i) {
        lines.push_back(answerer.RecordJson(all[i].first, all[i].second, clears_of[i - begin]));
      }
    }
    cleared_ += descent->stats().cleared;
    return lines;
  }
  int64_t device_work() const override { return cleared_; }

 private:
  int64_t cleared_ = 0;
};

}  // namespace

const char* WorldBackendName() { return "gpu"; }

std::vector<std::unique_ptr<WorldWay>> WorldWays() {
  std::vector<std::unique_ptr<WorldWay>> ways;
  ways.push_back(std::make_unique<CullerWay>());
  ways.push_back(std::make_unique<DescentWay>());
  return ways;
}

}  // namespace sweptccd::testing
