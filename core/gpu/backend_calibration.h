#pragma once
// `--backend auto` decided by measurement (issue 11): a short calibration of
// both backends on the loaded scene, and the rule that picks the faster one.
// Both backends give the same answers (docs/GPU.md), so the choice only
// affects speed.

#include <utility>
#include <vector>

#include "core/avatar/pose.h"
#include "core/avatar/skeleton.h"
#include "core/gpu/backend.h"
#include "core/query/ccd_query.h"
#include "core/scene/environment.h"

namespace sweptccd::gpu {

/// The GPU must be faster than the CPU by more than this fraction of the
/// CPU's median to be chosen; anything closer is a tie, and ties go to the
/// CPU (no context to keep, no dispatch whose cost varies with load).
inline constexpr double kAutoTieFraction = 0.05;

/// What the rule decided, with the figures it decided on.
struct AutoChoice {
  BackendKind kind = BackendKind::kCpu;  // kCpu or kGpu, never kAuto.
  double cpu_median_us = 0;              // Median per-pair time, microseconds (0 when no sample).
  double gpu_median_us = 0;
};

/// The median of `samples` (mean of the two middle values for an even
/// count); 0 for an empty set.
double MedianUs(std::vector<double> samples);

/// The choice rule, a pure function of the two timing sets (query times in
/// microseconds, one per calibration pair): the GPU iff both sets are
/// non-empty, every sample is finite and >= 0, and median(gpu) <
/// (1 - kAutoTieFraction) * median(cpu); otherwise the CPU.
AutoChoice ChooseFaster(const std::vector<double>& cpu_us, const std::vector<double>& gpu_us);

/// "cpu 41 us, gpu 380 us per pair" (medians, rounded to the microsecond).
std::string DescribeFigures(const AutoChoice& choice);

/// The skeleton calibrated with when the caller has none (a daemon with only
/// live clients): one capsule 0.5 m long, radius 0.05 m.
Skeleton CalibrationSkeleton();

/// The fixed calibration pairs: every link frame at one of kCalibrationPlaces
/// places inside the environment's bounds (the 2x2x2 points at 1/4 and 3/4
/// of the box; a 2 m box round the origin when it has no triangle), identity
/// orientation, swept 0.1 m along each axis and turned 0.3 rad about z over
/// 1/30 s. Deterministic: the same scene and skeleton give the same pairs.
inline constexpr int kCalibrationPlaces = 8;
std::vector<std::pair<Pose, Pose>> CalibrationPairs(const Skeleton& skeleton,
                                                    const Environment& environment);

/// Limits of one calibration.
struct CalibrationBudget {
  double max_seconds = 0.4;  // No pair starts past this (but see TimeBackends).
  int warmup_passes = 1;     // Untimed passes over the pairs.
  int max_rounds = 7;        // Timed passes over the pairs.
};

/// Query times (microseconds), one per timed pair and backend.
struct CalibrationTimes {
  std::vector<double> cpu_us, gpu_us;
};

/// Times `cpu` and `gpu` (engines on the same skeleton, environment and
/// filter; `gpu` with the GPU culler attached) on `pairs` with `options`:
/// warm-up passes (untimed), then up to max_rounds timed passes, each pair
/// on both backends in turn (alternating which goes first), so both sets
/// hold the same pairs. No pair starts once max_seconds have passed, except
/// that the first warm-up pair always runs and, when no timed pair ran, the
/// warm-up's times are returned instead: a calibration ends at most one pair
/// per backend past max_seconds. Empty only for empty `pairs`.
/// Single-threaded (the caller's thread); the answers are not used.
CalibrationTimes TimeBackends(const CcdEngine& cpu, const CcdEngine& gpu,
                              const std::vector<std::pair<Pose, Pose>>& pairs,
                              const QueryOptions& options, const CalibrationBudget& budget = {});

/// The batched calibration (issue 30), for a caller that answers many pairs
/// at once (`--threads` > 1): each timed sample is one batch of the pairs
/// (cycled to at least 4 x `threads` pairs) answered by `threads` workers on
/// one backend, then on the other (alternating which goes first), divided
/// by the batch's pair count: microseconds per pair at that concurrency,
/// where the GPU's requests share dispatches. One untimed batch per
/// backend, then up to max_rounds timed ones; no batch starts once
/// max_seconds have passed (the untimed batch stands in when no timed one
/// ran). `batch_pairs`, when not null, receives the batch size. Empty only
/// for empty `pairs`.
CalibrationTimes TimeBackendsBatched(const CcdEngine& cpu, const CcdEngine& gpu,
                                     const std::vector<std::pair<Pose, Pose>>& pairs,
                                     const QueryOptions& options, int threads,
                                     const CalibrationBudget& budget = {},
                                     size_t* batch_pairs = nullptr);

}  // namespace sweptccd::gpu
