#pragma once
// `sweptccd bench --sweep` (issue 30): the real scenes' pairs in batches of
// 1, 16, 64, 256 and 4,096 pairs, each batch answered by the CPU backend on
// one thread, by the CPU backend on --threads workers, and by the GPU
// backend on the same workers (their swept tests coalesced into shared
// dispatches), and by the device descent (the batch's free intervals
// cleared on the GPU in a few dispatches, then the CPU engines' queries on
// the same workers skipping them; core/gpu/device_descent.h), alternating
// batch by batch in one run. Per method: pairs per
// second at saturation (the batch's pairs over the batch's wall time, summed
// over the batches) and the batch's latency (median, p99, max); for the GPU,
// its dispatches and capsules per dispatch, and the pairs whose answer
// differs from the CPU's (must be 0); for the device descent, where its
// mean batch's time went (host preparation / device / rest of Run / CPU
// queries).

#include <string>
#include <vector>

#include "core/avatar/pose.h"
#include "core/avatar/skeleton.h"
#include "core/gpu/backend.h"
#include "core/percentile.h"
#include "core/query/ccd_query.h"
#include "core/scene/environment.h"

namespace sweptccd::bench {

/// One clip of a scene: its skeleton and the poses of its pairs.
struct SweepClip {
  const Skeleton* skeleton;
  const std::vector<Pose>* poses;
  int pairs;  // Pairs (k, k + 1) for k < pairs.
};

struct SweepOptions {
  std::vector<int> batch_sizes = {1, 16, 64, 256, 4096};
  int threads = 1;      // Workers of the "all threads" methods.
  int min_batches = 3;  // At least this many batches per size (the pairs cycle).
  QueryOptions query;
};

/// One method at one batch size.
struct SweepRow {
  std::string scene, method;
  int batch = 0;
  int64_t pairs = 0;
  double pairs_per_s = 0;
  Summary batch_us;
  // GPU only. For the device descent: capsules = intervals tested on the
  // device, requests = batches, and the intervals it cleared and the pairs
  // it left to the CPU past their budget.
  int64_t dispatches = 0, requests = 0, capsules = 0, differ = -1;
  int64_t cleared = 0, over_budget = 0;
  // The device descent only: the mean batch's time in DeviceDescent::Run's
  // host preparation, device part and rest (DescentStats), and in the CPU
  // queries after it (the batch's wall time less Run's), microseconds.
  double descent_host_us = 0, descent_device_us = 0, descent_other_us = 0, descent_queries_us = 0;
};

/// Runs the sweep on one scene; `gpu` null: the CPU methods only.
std::vector<SweepRow> RunSweep(const std::string& scene, const Environment& env,
                               const std::vector<SweepClip>& clips, const SweepOptions& options,
                               gpu::Backend* gpu);

/// The rows as a table (Markdown when `markdown`, else aligned text).
std::string FormatSweep(const std::vector<SweepRow>& rows, bool markdown);

}  // namespace sweptccd::bench
