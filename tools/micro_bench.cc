// Micro-benchmarks of the hot routines (Google Benchmark). Not a test: run
// build/bin/sweptccd_micro_bench [--benchmark_repetitions=10] by hand.

#include <benchmark/benchmark.h>

#include <algorithm>
#include <cmath>
#include <fstream>
#include <random>
#include <utility>
#include <vector>

#include "core/avatar/motion.h"
#include "core/geometry/bvh.h"
#include "core/geometry/distance.h"
#include "core/geometry/mesh.h"
#include "core/query/ccd_query.h"
#include "core/scene/environment.h"
#include "mocap/mocap_import.h"
#include "tools/bench_common.h"

namespace sweptccd {
namespace {

const std::string kData = SWEPTCCD_DATA_DIR;

void BM_SegmentTriangleDistance(benchmark::State& state) {
  std::mt19937_64 rng(1);
  std::uniform_real_distribution<double> u(-1, 1);
  std::vector<Eigen::Vector3d> p(5 * 1024);
  for (auto& v : p) v = Eigen::Vector3d(u(rng), u(rng), u(rng));
  size_t i = 0;
  for (auto _ : state) {
    const size_t k = 5 * (i++ % 1024);
    benchmark::DoNotOptimize(SegmentTriangleDistance(p[k], p[k + 1], p[k + 2], p[k + 3], p[k + 4]));
  }
}
BENCHMARK(BM_SegmentTriangleDistance);

void BM_BvhBuildBunny(benchmark::State& state) {
  const TriangleMesh mesh = LoadMeshFile(kData + "/env/stanford_bunny.obj.gz");
  for (auto _ : state) benchmark::DoNotOptimize(TriangleBvh(mesh));
  state.counters["triangles"] = static_cast<double>(mesh.num_triangles());
}
BENCHMARK(BM_BvhBuildBunny)->Unit(benchmark::kMillisecond);

void BM_SweptCapsule(benchmark::State& state) {
  const MocapClip clip = ImportBvhFile(kData + "/mocap/boxing_toes.bvh.gz");
  const PairMotion motion(clip.skeleton, clip.poses[100], clip.poses[103],
                          MotionModel::kArticulated);
  Eigen::Vector3d a, b;
  double g;
  LinkIndex link(0);
  for (auto _ : state) {
    motion.SweptCapsule(link, 0.25, 0.5, &a, &b, &g);
    benchmark::DoNotOptimize(g);
    link = LinkIndex((link + 1) % 16);
  }
}
BENCHMARK(BM_SweptCapsule);

// The motion of one pair of a 30 Hz walk (every link's relative transform,
// bounds, and poses and segments at s = 0, 0.5 and 1): the part of a pair's
// fixed cost that comes before any culling.
void BM_PairMotionWalk(benchmark::State& state) {
  MocapImportOptions mo;
  mo.frame_step = 4;
  const MocapClip clip = ImportBvhFile(kData + "/mocap/cmu_02_01_walk.bvh.gz", mo);
  size_t k = 0;
  for (auto _ : state) {
    const size_t i = k++ % (clip.poses.size() - 1);
    const PairMotion motion(clip.skeleton, clip.poses[i], clip.poses[i + 1],
                            MotionModel::kArticulated);
    benchmark::DoNotOptimize(motion);
  }
  state.counters["links"] = clip.skeleton.num_links();
}
BENCHMARK(BM_PairMotionWalk)->Unit(benchmark::kMicrosecond);

// One pair of a 30 Hz walk through the grey & white room (143k triangles).
void BM_QueryWalkGreyRoom(benchmark::State& state) {
  static const Environment env =
      Environment::LoadFiles({kData + "/env/bitterli_grey_white_room.ply.gz"});
  MocapImportOptions mo;
  mo.frame_step = 4;
  MocapClip clip = ImportBvhFile(kData + "/mocap/cmu_02_01_walk.bvh.gz", mo);
  TranslateClip(&clip, Eigen::Vector3d(2.3 - 0.57, 0.0, -1.5));
  const CcdEngine engine(clip.skeleton, env);
  size_t k = 0;
  for (auto _ : state) {
    const size_t i = k++ % (clip.poses.size() - 1);
    benchmark::DoNotOptimize(engine.Query(clip.poses[i], clip.poses[i + 1], QueryOptions()));
  }
}
BENCHMARK(BM_QueryWalkGreyRoom)->Unit(benchmark::kMicrosecond);

// The fixed cost of a pair: a 30 Hz walk 30 cm above the breakfast room's
// floor, in the middle of the room (269k triangles): every link is culled.
void BM_QueryCulledBreakfast(benchmark::State& state) {
  static const Environment env =
      Environment::LoadFiles({kData + "/env/bitterli_breakfast_room.ply.gz"});
  MocapImportOptions mo;
  mo.frame_step = 4;
  MocapClip clip = ImportBvhFile(kData + "/mocap/cmu_02_01_walk.bvh.gz", mo);
  const Eigen::Vector3d root = clip.poses.front().links[clip.skeleton.root()].p;
  TranslateClip(&clip, Eigen::Vector3d(-0.67 - root.x(), -1.42 + 0.3, -1.9 - root.z()));
  const CcdEngine engine(clip.skeleton, env);
  size_t k = 0;
  int64_t culled = 0, pairs = 0;
  for (auto _ : state) {
    const size_t i = k++ % (clip.poses.size() - 1);
    const QueryResult r = engine.Query(clip.poses[i], clip.poses[i + 1], QueryOptions());
    culled += r.stats.links_culled;
    ++pairs;
    benchmark::DoNotOptimize(r);
  }
  state.counters["culled_links_per_pair"] = pairs ? static_cast<double>(culled) / pairs : 0.0;
}
BENCHMARK(BM_QueryCulledBreakfast)->Unit(benchmark::kMicrosecond);

// The quiet rows of `sweptccd bench` (issue 11): every pair of its six
// clips at 30 Hz (at most 300 per clip), placed as the bench places them,
// through the MORSE apartment (first arg 0) or the breakfast room (1), all
// clips (second arg -1) or one (its index below). Mostly culled links; the
// time per iteration is one pair, averaged over them all.
void BM_QueryQuietScene(benchmark::State& state) {
  struct Scene {
    const char* file;
    char up;
    double floor;
    Eigen::Vector2d centre;
  };
  const Scene scenes[] = {{"morse_apartment.ply", 'z', 0.0, {1.0, 1.0}},
                          {"bitterli_breakfast_room.ply", 'y', -1.42, {-0.67, -1.9}}};
  const Scene& scene = scenes[state.range(0)];
  const Environment env = Environment::LoadFiles({bench::DataFile(kData + "/env/" + scene.file)});
  const char* clip_names[] = {"cmu_02_01_walk.bvh",
                              "cmu_02_03_run_jog.bvh",
                              "cmu_13_41_jump.bvh",
                              "cmu_05_06_dance_cartwheel_pirouettes_jete.bvh",
                              "cmu_01_03_playground_climb_hang_swing.bvh",
                              "boxing_toes.bvh"};
  std::vector<MocapClip> clips;
  for (int c = 0; c < 6; ++c) {
    if (state.range(1) >= 0 && state.range(1) != c) continue;
    const char* name = clip_names[c];
    const std::string path = bench::DataFile(kData + "/mocap/" + name);
    if (!std::ifstream(path)) continue;  // Not every data folder holds every clip.
    MocapImportOptions mo;
    mo.up_axis = scene.up;
    MocapClip clip = ImportBvhFile(path, mo);
    const int step = std::max(1, static_cast<int>(std::lround(1.0 / (clip.frame_time_s * 30))));
    std::vector<Pose> poses;
    for (size_t f = 0; f < clip.poses.size() && poses.size() < 301; f += step) {
      poses.push_back(clip.poses[f]);
    }
    clip.poses = poses;
    bench::PlaceClipOnFloor(&clip, scene.up, scene.floor, scene.centre);
    clips.push_back(std::move(clip));
  }
  std::vector<std::pair<const MocapClip*, size_t>> pairs;
  for (const MocapClip& clip : clips) {
    for (size_t i = 0; i + 1 < clip.poses.size(); ++i) pairs.emplace_back(&clip, i);
  }
  std::vector<CcdEngine> engines;
  engines.reserve(clips.size());
  for (const MocapClip& clip : clips) engines.emplace_back(clip.skeleton, env);
  size_t k = 0;
  for (auto _ : state) {
    const auto& [clip, i] = pairs[k++ % pairs.size()];
    const CcdEngine& engine = engines[clip - clips.data()];
    benchmark::DoNotOptimize(engine.Query(clip->poses[i], clip->poses[i + 1], QueryOptions()));
  }
}
BENCHMARK(BM_QueryQuietScene)
    ->Args({0, -1})
    ->Args({1, -1})
    ->Args({0, 3})
    ->Unit(benchmark::kMicrosecond);

}  // namespace
}  // namespace sweptccd

BENCHMARK_MAIN();
