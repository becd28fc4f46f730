#include "tools/bench_sweep.h"

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <memory>

#include "core/worker_pool.h"

namespace sweptccd::bench {

namespace {

using Clock = std::chrono::steady_clock;

// What must agree between the methods, pair by pair.
struct Brief {
  bool contact = false, undecided = false, initially = false;
  double s_lo = 0, s_hi = 0;
  bool operator==(const Brief& o) const {
    return contact == o.contact && undecided == o.undecided && initially == o.initially &&
           s_lo == o.s_lo && s_hi == o.s_hi;
  }
};

Brief BriefOf(const QueryResult& r) {
  return Brief{r.contact, r.undecided, r.initially_colliding, r.s_lo, r.s_hi};
}

const char* const kMethods[4] = {"cpu, 1 thread", "cpu, all threads", "gpu, all threads",
                                 "gpu descent, all threads"};

}  // namespace

std::vector<SweepRow> RunSweep(const std::string& scene, const Environment& env,
                               const std::vector<SweepClip>& clips, const SweepOptions& options,
                               gpu::Backend* gpu) {
  std::vector<std::unique_ptr<CcdEngine>> cpu_engines, gpu_engines;
  bool with_gpu = gpu != nullptr;
  struct PairRef {
    int clip, k;
  };
  std::vector<PairRef> pairs;
  for (size_t c = 0; c < clips.size(); ++c) {
    cpu_engines.push_back(std::make_unique<CcdEngine>(*clips[c].skeleton, env));
    gpu_engines.push_back(std::make_unique<CcdEngine>(*clips[c].skeleton, env));
    if (gpu != nullptr) gpu->Attach(gpu_engines.back().get());
    with_gpu = with_gpu && gpu_engines.back()->culler() != nullptr;
    for (int k = 0; k < clips[c].pairs; ++k) pairs.push_back({static_cast<int>(c), k});
  }
  std::vector<SweepRow> rows;
  if (pairs.empty()) return rows;
  const size_t num_pairs = pairs.size();
  // The device descent (docs/GPU.md): the batch's free intervals cleared on
  // the GPU in a few dispatches, then the CPU engines' queries on the
  // workers, skipping them.
  std::unique_ptr<gpu::DeviceDescent> descent;
  std::vector<int> descent_engine;
  gpu::DescentOptions descent_options;
  descent_options.host_threads = options.threads;  // The same workers' count.
  if (with_gpu) descent = gpu->MakeDescent(env, descent_options);
  if (descent != nullptr) {
    for (const auto& engine : cpu_engines) descent_engine.push_back(descent->AddEngine(*engine));
  }
  WorkerPool pool(options.threads);
  auto query = [&](const std::vector<std::unique_ptr<CcdEngine>>& engines, size_t p,
                   const PairClears* clears = nullptr) {
    const PairRef& r = pairs[p % num_pairs];
    const std::vector<Pose>& poses = *clips[r.clip].poses;
    return BriefOf(engines[r.clip]->Query(poses[r.k], poses[r.k + 1], options.query, clears));
  };
  std::vector<gpu::DeviceDescent::Pair> descent_pairs;
  std::vector<PairClears> clears;
  // The batch [first, first + batch) by the device descent, then the workers.
  auto descend = [&](size_t first, size_t batch, std::vector<Brief>* out) {
    descent_pairs.clear();
    for (size_t i = 0; i < batch; ++i) {
      const PairRef& r = pairs[(first + i) % num_pairs];
      const std::vector<Pose>& poses = *clips[r.clip].poses;
      descent_pairs.push_back({descent_engine[r.clip], &poses[r.k], &poses[r.k + 1], {}});
    }
    (void)descent->Run(descent_pairs, options.query, &clears);  // Failed: clears nothing.
    pool.Run(batch, [&](size_t i, int) { (*out)[i] = query(cpu_engines, first + i, &clears[i]); });
  };
  // Warm-up, untimed, every method alike.
  for (size_t p = 0; p < std::min<size_t>(20, num_pairs); ++p) {
    (void)query(cpu_engines, p);
    if (with_gpu) (void)query(gpu_engines, p);
  }
  std::vector<Brief> warm(20);
  if (descent != nullptr) descend(0, std::min<size_t>(20, num_pairs), &warm);
  const int methods = descent != nullptr ? 4 : with_gpu ? 3 : 2;
  for (const int size : options.batch_sizes) {
    const size_t batch = static_cast<size_t>(size);
    const size_t batches =
        std::max<size_t>(static_cast<size_t>(options.min_batches), (num_pairs + batch - 1) / batch);
    std::vector<double> us[4];
    double seconds[4] = {0, 0, 0, 0};
    std::vector<Brief> answers[4];
    for (auto& a : answers) a.resize(batch);
    int64_t differ = 0;
    const gpu::DispatchStats before = with_gpu ? gpu->dispatch_stats() : gpu::DispatchStats();
    const gpu::DescentStats descent_before =
        descent != nullptr ? descent->stats() : gpu::DescentStats();
    for (size_t j = 0; j < batches; ++j) {
      const size_t first = j * batch;
      for (int turn = 0; turn < methods; ++turn) {
        const int m = static_cast<int>((j + static_cast<size_t>(turn)) % methods);
        const auto start = Clock::now();
        if (m == 0) {
          for (size_t i = 0; i < batch; ++i) answers[0][i] = query(cpu_engines, first + i);
        } else if (m == 3) {
          descend(first, batch, &answers[3]);
        } else {
          const auto& engines = m == 1 ? cpu_engines : gpu_engines;
          pool.Run(batch, [&](size_t i, int) { answers[m][i] = query(engines, first + i); });
        }
        const double s = std::chrono::duration<double>(Clock::now() - start).count();
        seconds[m] += s;
        us[m].push_back(1e6 * s);
      }
      for (size_t i = 0; i < batch; ++i) {
        bool same = answers[1][i] == answers[0][i];
        if (with_gpu) same = same && answers[2][i] == answers[0][i];
        if (descent != nullptr) same = same && answers[3][i] == answers[0][i];
        differ += !same;
      }
    }
    const gpu::DispatchStats after = with_gpu ? gpu->dispatch_stats() : gpu::DispatchStats();
    const gpu::DescentStats descent_after =
        descent != nullptr ? descent->stats() : gpu::DescentStats();
    for (int m = 0; m < methods; ++m) {
      SweepRow row;
      row.scene = scene;
      row.method = kMethods[m];
      row.batch = size;
      row.pairs = static_cast<int64_t>(batches * batch);
      row.pairs_per_s = seconds[m] > 0 ? static_cast<double>(row.pairs) / seconds[m] : 0;
      row.batch_us = Summarise(us[m]);
      row.differ = differ;
      if (m == 2) {
        row.dispatches = after.dispatches - before.dispatches;
        row.requests = after.requests - before.requests;
        row.capsules = after.capsules - before.capsules;
      }
      if (m == 3) {  // Capsules: intervals tested on the device; requests: batches.
        row.dispatches = descent_after.dispatches - descent_before.dispatches;
        row.requests = descent_after.batches - descent_before.batches;
        row.capsules = descent_after.items - descent_before.items;
        row.cleared = descent_after.cleared - descent_before.cleared;
        row.over_budget = descent_after.over_budget - descent_before.over_budget;
        const double n = static_cast<double>(batches);
        row.descent_host_us = (descent_after.host_us - descent_before.host_us) / n;
        row.descent_device_us = (descent_after.device_us - descent_before.device_us) / n;
        row.descent_other_us = (descent_after.other_us - descent_before.other_us) / n;
        row.descent_queries_us = std::max(0.0, 1e6 * seconds[m] / n - row.descent_host_us -
                                                   row.descent_device_us - row.descent_other_us);
      }
      rows.push_back(row);
    }
  }
  return rows;
}

std::string FormatSweep(const std::vector<SweepRow>& rows, bool markdown) {
  std::string out;
  char line[512];
  const char* head =
      "| scene | batch | method | pairs | pairs/s | batch median us | batch p99 us | batch max us "
      "| dispatches | capsules/dispatch | requests/dispatch | differ "
      "| descent mean us: host / device / rest / queries |\n";
  out += head;
  if (markdown) out += "|---|---:|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|\n";
  for (const SweepRow& r : rows) {
    const bool gpu = r.method.rfind("gpu", 0) == 0;
    char dispatch[128] = "";
    if (gpu) {
      std::snprintf(dispatch, sizeof(dispatch), "%lld | %.1f | %.2f",
                    static_cast<long long>(r.dispatches),
                    r.dispatches > 0 ? static_cast<double>(r.capsules) / r.dispatches : 0.0,
                    r.dispatches > 0 ? static_cast<double>(r.requests) / r.dispatches : 0.0);
    } else {
      std::snprintf(dispatch, sizeof(dispatch), "- | - | -");
    }
    char times[128] = "-";
    if (r.method.find("descent") != std::string::npos) {
      std::snprintf(times, sizeof(times), "%.1f / %.1f / %.1f / %.1f", r.descent_host_us,
                    r.descent_device_us, r.descent_other_us, r.descent_queries_us);
    }
    std::snprintf(line, sizeof(line),
                  "| %s | %d | %s | %lld | %.0f | %.1f | %.1f | %.1f | %s | %lld | %s |\n",
                  r.scene.c_str(), r.batch, r.method.c_str(), static_cast<long long>(r.pairs),
                  r.pairs_per_s, r.batch_us.median, r.batch_us.p99, r.batch_us.max, dispatch,
                  static_cast<long long>(r.differ), times);
    out += line;
  }
  return out;
}

}  // namespace sweptccd::bench
