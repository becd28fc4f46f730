#pragma once
// The device descent (issue 30; docs/GPU.md, "The free part of the descent
// on the device"): for a batch of pairs, the GPU clears the free intervals
// of every (pair, link)'s dyadic time-slicing tree down to a few levels, in
// a few dispatches for the whole batch (breadth first, one dispatch per
// level, the next level's work appended on the device with atomic
// counters). The device only clears: it proves an interval's swept capsule
// meets no unfiltered triangle, never closes one with a witness. Each pair's
// query then runs on the CPU (CcdEngine::Query with the pair's PairClears),
// skipping the cleared intervals, and decides everything else with its
// unchanged code: the same records as the CPU backend.

#include <cstdint>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <vector>

#include "core/avatar/pose.h"
#include "core/gpu/gpu_culler.h"
#include "core/query/ccd_query.h"
#include "core/query/pair_clears.h"

namespace sweptccd {
class WorkerPool;
}  // namespace sweptccd

namespace sweptccd::gpu {

struct DescentOptions {
  /// Depths of the tree cleared on the device: 0 .. levels - 1 (1 to
  /// PairClears::kMaxLevels; 5: 31 intervals per link).
  int levels = PairClears::kMaxLevels;
  /// Intervals below the whole pair that one pair may have tested on the
  /// device (all its links together); past it the pair's deeper intervals
  /// are left to the CPU (its record is the same either way).
  int pair_budget = 256;
  /// Work items one level's queue holds (all pairs); past it alike.
  int queue_capacity = 1 << 18;
  /// Steps one interval's search may take on the device (objects, BVH
  /// nodes, triangles; 1 to 16,384, the culler's cap): past it the interval
  /// "may touch" (never cleared), its halves are tested, and the CPU decides
  /// what stays open. Smaller than the culler's: an interval whose search is
  /// that long is near the geometry, and one long invocation holds up its
  /// whole level's dispatch.
  int max_steps = 2048;
  /// Threads of Run's host preparation (the pairs' motions, the tracks'
  /// grid points: independent, computed in parallel, assembled in order, so
  /// the tracks, grid and items sent are the same for any count); 1: the
  /// calling thread alone. The callers pass their worker count (--threads,
  /// the daemon's workers).
  int host_threads = 1;
};

/// Counts over every batch so far.
struct DescentStats {
  int64_t batches = 0;
  int64_t dispatches = 0;
  int64_t pairs = 0;
  int64_t tracks = 0;       // (pair, link) trees sent.
  int64_t refused = 0;      // (pair, link) trees a float could not hold (left to the CPU).
  int64_t items = 0;        // Intervals tested on the device.
  int64_t cleared = 0;      // Intervals cleared on the device.
  int64_t over_budget = 0;  // Pairs cut short by their budget or the queue's capacity.
  // Where Run's time went (wall clock, microseconds, summed over the batches;
  // from the batch's lock taken to its return): the host's preparation (the
  // pairs' motions, the tracks' growth constants, the grid written and its
  // points computed), the
  // device's part (every context().Run: uploads, dispatches, waits,
  // read-backs), and the rest (the clears reset, the items and tracks
  // assembled, the cleared words handed back).
  double host_us = 0, device_us = 0, other_us = 0;
};

/// Where Run's time went, for the logs: "in Run: host preparation X ms,
/// device Y ms, rest Z ms" (DescentStats::host_us, device_us, other_us).
std::string DescentTimes(const DescentStats& stats);

class DeviceDescent {
 public:
  /// On `environment`'s upload; the engines added must query `source`
  /// (the environment uploaded, compared by content_id). Throws GpuError.
  DeviceDescent(std::shared_ptr<const GpuEnvironment> environment, const Environment& source,
                DescentOptions options);
  ~DeviceDescent();
  DeviceDescent(const DeviceDescent&) = delete;
  DeviceDescent& operator=(const DeviceDescent&) = delete;

  /// Registers an engine (its skeleton and collision filter) whose pairs Run
  /// clears; returns its index for DescentPair::engine. The engine must
  /// outlive this object. Throws GpuError (a GPU failure, or an engine on
  /// another environment).
  int AddEngine(const CcdEngine& engine);
  /// Forgets engine `index` (its engine may then be destroyed): no Run may
  /// name it any more. Never waits for the GPU or a batch (its filter's
  /// masks are freed by the next AddEngine or Run); its index may be handed
  /// out again by AddEngine. Thread-safe.
  void RemoveEngine(int index);

  struct Pair {
    int engine = 0;
    const Pose* pose0 = nullptr;
    const Pose* pose1 = nullptr;
    /// The pair's motion model when it is not `options.motion` (the shared
    /// world: each avatar moves by its own model).
    std::optional<MotionModel> motion;
  };
  /// Sets (*clears)[i] to what the device cleared of pairs[i] (poses valid,
  /// pose1 later; `options` as the queries will use them, the motion model
  /// pairs[i].motion when set). Returns false when
  /// the GPU failed (logged once; every clears[i] is then empty, and from
  /// then on Run clears nothing: the CPU answers alone). Thread-safe (one
  /// batch at a time).
  bool Run(const std::vector<Pair>& pairs, const QueryOptions& options,
           std::vector<PairClears>* clears);

  DescentStats stats() const;
  const DescentOptions& options() const { return options_; }

 private:
  struct State;
  std::shared_ptr<const GpuEnvironment> env_;
  uint64_t content_id_;
  DescentOptions options_;
  std::unique_ptr<State> state_;
  // The host preparation's workers (null: one thread); used under mutex_
  // only, one batch at a time.
  std::unique_ptr<WorkerPool> pool_;
  mutable std::mutex mutex_;
  // Engines removed, their masks not yet freed (RemoveEngine never takes
  // mutex_, which a batch holds); under retired_mutex_.
  std::mutex retired_mutex_;
  std::vector<int> retired_;
  // Under mutex_: frees the retired engines' masks.
  void FreeRetiredLocked();
};

}  // namespace sweptccd::gpu
