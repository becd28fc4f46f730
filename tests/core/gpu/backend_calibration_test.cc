// `--backend auto` by measurement (issue 11): the choice rule as a pure
// function of two timing sets, the calibration pairs and rounds, and the
// Backend resolving auto on llvmpipe (whichever it picks, it must name both
// figures and keep to its pick). No assertion depends on how fast anything is.

#include "core/gpu/backend_calibration.h"

#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <regex>

#include "core/gpu/backend.h"

namespace sweptccd::gpu {
namespace {

using Eigen::Vector3d;

TEST(BackendCalibrationTest, MedianOfOddEvenAndEmptySets) {
  EXPECT_EQ(MedianUs({}), 0);
  EXPECT_EQ(MedianUs({7}), 7);
  EXPECT_EQ(MedianUs({9, 1, 5}), 5);
  EXPECT_EQ(MedianUs({4, 1, 3, 2}), 2.5);
  EXPECT_EQ(MedianUs({1000, 1, 2}), 2);  // One outlier does not move it.
}

TEST(BackendCalibrationTest, ChoiceRuleTakesTheFasterMedianWithTiesToTheCpu) {
  // Clearly faster GPU.
  AutoChoice c = ChooseFaster({40, 41, 42}, {10, 11, 500});
  EXPECT_EQ(c.kind, BackendKind::kGpu);
  EXPECT_EQ(c.cpu_median_us, 41);
  EXPECT_EQ(c.gpu_median_us, 11);
  // Clearly faster CPU (the llvmpipe case).
  c = ChooseFaster({41, 40, 45}, {380, 390, 370});
  EXPECT_EQ(c.kind, BackendKind::kCpu);
  EXPECT_EQ(c.gpu_median_us, 380);
  // Equal, and within the tie band: the CPU.
  EXPECT_EQ(ChooseFaster({100}, {100}).kind, BackendKind::kCpu);
  EXPECT_EQ(ChooseFaster({100}, {96}).kind, BackendKind::kCpu);
  EXPECT_EQ(ChooseFaster({100}, {100 * (1 - kAutoTieFraction)}).kind, BackendKind::kCpu);
  // Just past the band: the GPU.
  EXPECT_EQ(ChooseFaster({100}, {94}).kind, BackendKind::kGpu);
  // The median decides, not the best or the mean.
  EXPECT_EQ(ChooseFaster({50, 50, 50}, {1, 60, 60}).kind, BackendKind::kCpu);
  EXPECT_EQ(ChooseFaster({50, 50, 1}, {40, 40, 40}).kind, BackendKind::kGpu);
  // No figures, or figures that mean nothing: the CPU.
  EXPECT_EQ(ChooseFaster({}, {1}).kind, BackendKind::kCpu);
  EXPECT_EQ(ChooseFaster({100}, {}).kind, BackendKind::kCpu);
  const double nan = std::numeric_limits<double>::quiet_NaN();
  const double inf = std::numeric_limits<double>::infinity();
  EXPECT_EQ(ChooseFaster({100, 100, nan}, {1, 1, 1}).kind, BackendKind::kCpu);
  EXPECT_EQ(ChooseFaster({100, 100, 100}, {1, 1, nan}).kind, BackendKind::kCpu);
  EXPECT_EQ(ChooseFaster({inf}, {1}).kind, BackendKind::kCpu);
  EXPECT_EQ(ChooseFaster({100}, {-1}).kind, BackendKind::kCpu);
  // The same sets give the same choice whatever their order.
  EXPECT_EQ(ChooseFaster({30, 10, 20}, {9, 30, 12}).kind,
            ChooseFaster({10, 20, 30}, {12, 9, 30}).kind);
}

TEST(BackendCalibrationTest, FiguresAreWordedOnce) {
  AutoChoice c;
  c.cpu_median_us = 41.4;
  c.gpu_median_us = 379.6;
  EXPECT_EQ(DescribeFigures(c), "cpu 41 us, gpu 380 us per pair");
}

Environment Box(const Vector3d& lo, const Vector3d& hi) {
  TriangleMesh mesh;
  for (const Vector3d& v : {lo, Vector3d(hi.x(), lo.y(), lo.z()), Vector3d(hi.x(), hi.y(), lo.z()),
                            Vector3d(lo.x(), hi.y(), hi.z()), hi}) {
    mesh.vertices.push_back(v.cast<float>());
  }
  mesh.indices = {0, 1, 2, 0, 3, 4};
  Environment env;
  env.AddMesh(mesh, "box");
  return env;
}

TEST(BackendCalibrationTest, PairsAreFixedAndInsideTheScene) {
  const Skeleton skeleton = CalibrationSkeleton();
  const Environment env = Box(Vector3d(10, 20, 30), Vector3d(14, 28, 31));
  const auto pairs = CalibrationPairs(skeleton, env);
  ASSERT_EQ(pairs.size(), static_cast<size_t>(kCalibrationPlaces));
  const auto again = CalibrationPairs(skeleton, env);
  for (size_t k = 0; k < pairs.size(); ++k) {
    const auto& [p0, p1] = pairs[k];
    ASSERT_EQ(p0.links.size(), 1u);
    EXPECT_LT(p0.utime, p1.utime);
    EXPECT_EQ(p0.links[0].p, again[k].first.links[0].p);
    EXPECT_EQ(p1.links[0].q.coeffs(), again[k].second.links[0].q.coeffs());
    for (int axis = 0; axis < 3; ++axis) {
      EXPECT_GT(p0.links[0].p[axis], Vector3d(10, 20, 30)[axis]) << k;
      EXPECT_LT(p0.links[0].p[axis], Vector3d(14, 28, 31)[axis]) << k;
    }
  }
  // The 8 places are distinct.
  for (size_t i = 0; i < pairs.size(); ++i) {
    for (size_t j = i + 1; j < pairs.size(); ++j) {
      EXPECT_NE(pairs[i].first.links[0].p, pairs[j].first.links[0].p);
    }
  }
  // Regression (QueryCommandTest.CorruptedInputsNeverCrash): a scene at
  // 1e30 m once gave places no pose may have, and the check aborted.
  for (const auto& [p0, p1] :
       CalibrationPairs(skeleton, Box(Vector3d(-3e38, 1e30, 0), Vector3d(3e38, 2e30, 1)))) {
    EXPECT_LE(p0.links[0].p.cwiseAbs().maxCoeff(), kMaxCoordinate);
    EXPECT_LE(p1.links[0].p.cwiseAbs().maxCoeff(), kMaxCoordinate);
  }
  // An environment with no triangle: a box round the origin.
  const auto empty = CalibrationPairs(skeleton, Environment());
  ASSERT_EQ(empty.size(), static_cast<size_t>(kCalibrationPlaces));
  EXPECT_LE(empty[0].first.links[0].p.norm(), 1.0);
}

TEST(BackendCalibrationTest, RoundsStopAtTheLimitsAndAlwaysMeasureOnce) {
  const Skeleton skeleton = CalibrationSkeleton();
  const Environment env = Box(Vector3d(0, 0, 0), Vector3d(2, 2, 2));
  CcdEngine a(skeleton, env), b(skeleton, env);
  const auto pairs = CalibrationPairs(skeleton, env);
  CalibrationBudget budget;
  budget.max_seconds = 1e9;
  budget.max_rounds = 3;
  CalibrationTimes t = TimeBackends(a, b, pairs, QueryOptions(), budget);
  EXPECT_EQ(t.cpu_us.size(), 3u * pairs.size());  // Every pair of every round, both backends.
  EXPECT_EQ(t.gpu_us.size(), 3u * pairs.size());
  // Past the budget at once: the one warm-up pair stands in.
  budget.max_seconds = 0;
  budget.max_rounds = 7;
  t = TimeBackends(a, b, pairs, QueryOptions(), budget);
  EXPECT_EQ(t.cpu_us.size(), 1u);
  EXPECT_EQ(t.gpu_us.size(), 1u);
  EXPECT_TRUE(std::isfinite(t.cpu_us[0]) && t.cpu_us[0] >= 0);
  // No warm-up: the first timed pair still runs.
  budget.warmup_passes = 0;
  t = TimeBackends(a, b, pairs, QueryOptions(), budget);
  EXPECT_EQ(t.cpu_us.size(), 1u);
  EXPECT_EQ(t.gpu_us.size(), 1u);
  EXPECT_TRUE(TimeBackends(a, b, {}, QueryOptions(), budget).cpu_us.empty());
}

// Issue 30: the batched calibration: one sample per batch and backend, the
// batch at least 4 x threads pairs (the calibration pairs cycled), the same
// limits (rounds, the budget, the untimed batch standing in).
TEST(BackendCalibrationTest, BatchedRoundsStopAtTheLimitsAndAlwaysMeasureOnce) {
  const Skeleton skeleton = CalibrationSkeleton();
  const Environment env = Box(Vector3d(0, 0, 0), Vector3d(2, 2, 2));
  CcdEngine a(skeleton, env), b(skeleton, env);
  const auto pairs = CalibrationPairs(skeleton, env);
  CalibrationBudget budget;
  budget.max_seconds = 1e9;
  budget.max_rounds = 3;
  size_t batch = 0;
  CalibrationTimes t = TimeBackendsBatched(a, b, pairs, QueryOptions(), 5, budget, &batch);
  EXPECT_EQ(batch, 20u);  // 4 x 5 > the 8 calibration pairs.
  EXPECT_EQ(t.cpu_us.size(), 3u);
  EXPECT_EQ(t.gpu_us.size(), 3u);
  for (double us : t.cpu_us) EXPECT_TRUE(std::isfinite(us) && us >= 0);
  TimeBackendsBatched(a, b, pairs, QueryOptions(), 1, budget, &batch);
  EXPECT_EQ(batch, pairs.size());
  budget.max_seconds = 0;  // Past the budget at once: the untimed batch stands in.
  t = TimeBackendsBatched(a, b, pairs, QueryOptions(), 2, budget);
  EXPECT_EQ(t.cpu_us.size(), 1u);
  EXPECT_EQ(t.gpu_us.size(), 1u);
  EXPECT_TRUE(TimeBackendsBatched(a, b, {}, QueryOptions(), 2, budget).cpu_us.empty());
}

// On this machine (llvmpipe) auto makes a context, calibrates, and names both
// figures; whichever it picks, gpu(), reason(), State() and Attach agree.
void ExpectResolvedConsistently(Backend& backend, const Skeleton& skeleton,
                                const Environment& env) {
  const std::regex figures("auto: cpu [0-9]+ us, gpu [0-9]+ us per pair");
  EXPECT_TRUE(std::regex_search(backend.reason(), figures)) << backend.reason();
  EXPECT_TRUE(std::regex_search(backend.State(), figures)) << backend.State();
  const std::string chosen = backend.gpu() ? "gpu (" : "cpu (";
  EXPECT_EQ(backend.reason().rfind(chosen, 0), 0u) << backend.reason();
  EXPECT_EQ(backend.State().rfind(chosen, 0), 0u) << backend.State();
  EXPECT_EQ(backend.renderer().empty(), !backend.gpu());
  CcdEngine engine(skeleton, env);
  backend.Attach(&engine);
  EXPECT_EQ(engine.culler() != nullptr, backend.gpu());
}

TEST(BackendCalibrationTest, AutoMeasuresBothBackendsOnTheScene) {
  BackendOptions options;
  options.backend = BackendKind::kAuto;
  Backend backend(options);
  ASSERT_NE(backend.context(), nullptr) << "llvmpipe must give a context: " << backend.reason();
  EXPECT_NE(backend.reason().find("not calibrated yet"), std::string::npos) << backend.reason();
  const Skeleton skeleton = CalibrationSkeleton();
  const Environment env = Box(Vector3d(0, 0, 0), Vector3d(2, 2, 2));
  backend.ResolveAuto(env, &skeleton, nullptr, QueryOptions());
  ExpectResolvedConsistently(backend, skeleton, env);
  // A second call changes nothing.
  const std::string reason = backend.reason();
  backend.ResolveAuto(env, &skeleton, nullptr, QueryOptions());
  EXPECT_EQ(backend.reason(), reason);
}

// auto with several workers calibrates on a batch and says so.
TEST(BackendCalibrationTest, AutoWithThreadsMeasuresABatch) {
  BackendOptions options;
  options.backend = BackendKind::kAuto;
  options.threads = 3;
  Backend backend(options);
  ASSERT_NE(backend.context(), nullptr) << "llvmpipe must give a context: " << backend.reason();
  const Skeleton skeleton = CalibrationSkeleton();
  const Environment env = Box(Vector3d(0, 0, 0), Vector3d(2, 2, 2));
  backend.ResolveAuto(env, &skeleton, nullptr, QueryOptions());
  ExpectResolvedConsistently(backend, skeleton, env);
  EXPECT_TRUE(std::regex_search(
      backend.reason(), std::regex("per pair, medians of [1-9] timed batches of 12 pairs on 3 "
                                   "threads each; ")))
      << backend.reason();
}

TEST(BackendCalibrationTest, AutoWithoutASkeletonUsesTheCalibrationCapsule) {
  BackendOptions options;
  options.backend = BackendKind::kAuto;
  Backend backend(options);
  ASSERT_NE(backend.context(), nullptr) << backend.reason();
  const Environment env = Box(Vector3d(-1, -1, 0), Vector3d(1, 1, 3));
  backend.ResolveAuto(env, nullptr, nullptr, QueryOptions());
  ExpectResolvedConsistently(backend, CalibrationSkeleton(), env);
}

// auto with require_hardware on a software renderer: no context, the CPU,
// and the reason says it was not calibrated and why.
TEST(BackendCalibrationTest, AutoWithoutAContextIsTheCpuAndSaysWhy) {
  BackendOptions options;
  options.backend = BackendKind::kAuto;
  options.require_hardware = true;
  options.device_index = 31;  // No such device, hardware or not.
  Backend backend(options);
  EXPECT_FALSE(backend.gpu());
  const Environment env = Box(Vector3d(0, 0, 0), Vector3d(1, 1, 1));
  backend.ResolveAuto(env, nullptr, nullptr, QueryOptions());
  EXPECT_EQ(backend.reason().rfind("cpu (auto: no GPU context, not calibrated; ", 0), 0u)
      << backend.reason();
  EXPECT_NE(backend.reason().find("EGL device 31 does not exist"), std::string::npos)
      << backend.reason();
  EXPECT_EQ(backend.State(), "cpu");
}

// gpu and cpu still force: ResolveAuto leaves them as they are.
TEST(BackendCalibrationTest, GpuAndCpuAreNotCalibrated) {
  const Environment env = Box(Vector3d(0, 0, 0), Vector3d(1, 1, 1));
  BackendOptions options;
  options.backend = BackendKind::kGpu;
  Backend gpu_backend(options);
  ASSERT_TRUE(gpu_backend.gpu()) << gpu_backend.reason();
  gpu_backend.ResolveAuto(env, nullptr, nullptr, QueryOptions());
  EXPECT_TRUE(gpu_backend.gpu());
  EXPECT_EQ(gpu_backend.reason().rfind("gpu (requested; ", 0), 0u) << gpu_backend.reason();
  EXPECT_EQ(gpu_backend.State(), "gpu");
  options.backend = BackendKind::kCpu;
  Backend cpu_backend(options);
  cpu_backend.ResolveAuto(env, nullptr, nullptr, QueryOptions());
  EXPECT_EQ(cpu_backend.reason(), "cpu (requested)");
  EXPECT_EQ(cpu_backend.State(), "cpu");
}

}  // namespace
}  // namespace sweptccd::gpu
