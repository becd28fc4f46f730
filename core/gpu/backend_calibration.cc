#include "core/gpu/backend_calibration.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <string>

#include "core/errors.h"
#include "core/worker_pool.h"

namespace sweptccd::gpu {

double MedianUs(std::vector<double> samples) {
  if (samples.empty()) return 0;
  std::sort(samples.begin(), samples.end());
  const size_t n = samples.size();
  return n % 2 == 1 ? samples[n / 2] : 0.5 * (samples[n / 2 - 1] + samples[n / 2]);
}

AutoChoice ChooseFaster(const std::vector<double>& cpu_us, const std::vector<double>& gpu_us) {
  AutoChoice choice;
  choice.cpu_median_us = MedianUs(cpu_us);
  choice.gpu_median_us = MedianUs(gpu_us);
  auto usable = [](const std::vector<double>& samples) {
    return !samples.empty() && std::all_of(samples.begin(), samples.end(),
                                           [](double v) { return std::isfinite(v) && v >= 0; });
  };
  if (usable(cpu_us) && usable(gpu_us) &&
      choice.gpu_median_us < (1 - kAutoTieFraction) * choice.cpu_median_us) {
    choice.kind = BackendKind::kGpu;
  }
  return choice;
}

std::string DescribeFigures(const AutoChoice& choice) {
  return "cpu " + std::to_string(std::llround(choice.cpu_median_us)) + " us, gpu " +
         std::to_string(std::llround(choice.gpu_median_us)) + " us per pair";
}

Skeleton CalibrationSkeleton() {
  Link link;
  link.name = "calibration";
  link.b_L = Eigen::Vector3d(0, 0, 0.5);
  link.radius = 0.05;
  return Skeleton::FromLinks("calibration", {link}, "calibration skeleton");
}

// Well inside kMaxCoordinate, with room for the skeleton and the sweep.
constexpr double kMaxPlaceCoordinate = 1e8;

std::vector<std::pair<Pose, Pose>> CalibrationPairs(const Skeleton& skeleton,
                                                    const Environment& environment) {
  Aabb box{Eigen::Vector3d::Constant(-1), Eigen::Vector3d::Constant(1)};
  bool any = false;
  for (int i = 0; i < environment.num_objects(); ++i) {
    const TriangleBvh& bvh = environment.object(i).bvh;
    if (bvh.num_triangles() == 0) continue;
    const Aabb b = bvh.bounds();
    box.lo = any ? box.lo.cwiseMin(b.lo) : b.lo;
    box.hi = any ? box.hi.cwiseMax(b.hi) : b.hi;
    any = true;
  }
  const Eigen::Vector3d step(0.1, 0.1, 0.1);
  const Eigen::Quaterniond turn(Eigen::AngleAxisd(0.3, Eigen::Vector3d::UnitZ()));
  std::vector<std::pair<Pose, Pose>> pairs;
  for (int k = 0; k < kCalibrationPlaces; ++k) {
    const Eigen::Vector3d f((k & 1) ? 0.75 : 0.25, (k & 2) ? 0.75 : 0.25, (k & 4) ? 0.75 : 0.25);
    Eigen::Vector3d place = box.lo + f.cwiseProduct(box.hi - box.lo);
    // A scene far beyond any tracked body (a corrupted or hostile file, up to
    // float's 3e38) must not give an invalid pose (SPEC 2: |p| <= 1e9).
    for (int axis = 0; axis < 3; ++axis) {
      const double c = place[axis];
      place[axis] = std::isfinite(c) ? std::clamp(c, -kMaxPlaceCoordinate, kMaxPlaceCoordinate) : 0;
    }
    Pose p0, p1;
    p0.utime = 0;
    p1.utime = 33333;
    for (int l = 0; l < skeleton.num_links(); ++l) {
      p0.links.push_back({place, Eigen::Quaterniond::Identity()});
      p1.links.push_back({place + step, turn});
    }
    // Finite, unit quaternions and increasing times: valid by construction.
    SWEPTCCD_CHECK(ValidateAndNormalizePose(&p0, skeleton.num_links()).empty());
    SWEPTCCD_CHECK(ValidateAndNormalizePose(&p1, skeleton.num_links()).empty());
    pairs.emplace_back(std::move(p0), std::move(p1));
  }
  return pairs;
}

CalibrationTimes TimeBackends(const CcdEngine& cpu, const CcdEngine& gpu,
                              const std::vector<std::pair<Pose, Pose>>& pairs,
                              const QueryOptions& options, const CalibrationBudget& budget) {
  using Clock = std::chrono::steady_clock;
  if (pairs.empty()) return {};
  QueryOptions query = options;
  query.per_link = false;
  const auto start = Clock::now();
  auto over_budget = [&] {
    return std::chrono::duration<double>(Clock::now() - start).count() > budget.max_seconds;
  };
  auto time_one = [&](const CcdEngine& engine, size_t k) {
    const auto t0 = Clock::now();
    engine.Query(pairs[k].first, pairs[k].second, query);
    return std::chrono::duration<double, std::micro>(Clock::now() - t0).count();
  };
  // Pair k on both backends, alternating which goes first, so neither always
  // runs on the warmer cache.
  auto time_pair = [&](size_t k, bool cpu_first, CalibrationTimes* into) {
    if (cpu_first) into->cpu_us.push_back(time_one(cpu, k));
    into->gpu_us.push_back(time_one(gpu, k));
    if (!cpu_first) into->cpu_us.push_back(time_one(cpu, k));
  };
  // Warm-up (its first pair always runs), then timed rounds. The budget is
  // checked before each pair, so a calibration ends at most one pair per
  // backend past it; when even that pair would start past it with no timed
  // sample yet, the warm-up's figures stand in (a scene where one pair takes
  // longer than the whole budget needs no finer measurement).
  CalibrationTimes warm, timed;
  for (int w = 0; w < budget.warmup_passes; ++w) {
    for (size_t k = 0; k < pairs.size(); ++k) {
      if (!warm.cpu_us.empty() && over_budget()) break;
      time_pair(k, (k + w) % 2 == 0, &warm);
    }
  }
  for (int round = 0; round < std::max(1, budget.max_rounds); ++round) {
    for (size_t k = 0; k < pairs.size(); ++k) {
      if ((!timed.cpu_us.empty() || !warm.cpu_us.empty()) && over_budget()) {
        return timed.cpu_us.empty() ? warm : timed;
      }
      time_pair(k, (k + round) % 2 == 0, &timed);
    }
  }
  return timed;
}

CalibrationTimes TimeBackendsBatched(const CcdEngine& cpu, const CcdEngine& gpu,
                                     const std::vector<std::pair<Pose, Pose>>& pairs,
                                     const QueryOptions& options, int threads,
                                     const CalibrationBudget& budget, size_t* batch_pairs) {
  using Clock = std::chrono::steady_clock;
  if (pairs.empty()) return {};
  QueryOptions query = options;
  query.per_link = false;
  WorkerPool pool(std::max(1, threads));
  const size_t batch = std::max(pairs.size(), 4 * static_cast<size_t>(pool.size()));
  if (batch_pairs != nullptr) *batch_pairs = batch;
  const auto start = Clock::now();
  auto over_budget = [&] {
    return std::chrono::duration<double>(Clock::now() - start).count() > budget.max_seconds;
  };
  // One batch on one backend: microseconds per pair.
  auto time_batch = [&](const CcdEngine& engine) {
    const auto t0 = Clock::now();
    pool.Run(batch, [&](size_t i, int) {
      const auto& pair = pairs[i % pairs.size()];
      engine.Query(pair.first, pair.second, query);
    });
    return std::chrono::duration<double, std::micro>(Clock::now() - t0).count() /
           static_cast<double>(batch);
  };
  auto time_both = [&](bool cpu_first, CalibrationTimes* into) {
    if (cpu_first) into->cpu_us.push_back(time_batch(cpu));
    into->gpu_us.push_back(time_batch(gpu));
    if (!cpu_first) into->cpu_us.push_back(time_batch(cpu));
  };
  CalibrationTimes warm, timed;
  time_both(true, &warm);
  for (int round = 0; round < std::max(1, budget.max_rounds); ++round) {
    if (over_budget()) break;
    time_both(round % 2 == 1, &timed);
  }
  return timed.cpu_us.empty() ? warm : timed;
}

}  // namespace sweptccd::gpu
