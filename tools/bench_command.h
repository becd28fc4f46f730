#pragma once
// `sweptccd bench`: per-pair query times on real mocap through real scenes.

#include <string>
#include <vector>

#include "core/geometry/mesh.h"
#include "core/worker_pool.h"

namespace CLI {
class App;
}

namespace sweptccd {

struct BenchCommandOptions {
  std::string data_dir;  // Folder with env/ and mocap/ (default: the project's data/).
  std::vector<std::string> clips = {"cmu_02_01_walk.bvh",
                                    "cmu_02_03_run_jog.bvh",
                                    "cmu_13_41_jump.bvh",
                                    "cmu_05_06_dance_cartwheel_pirouettes_jete.bvh",
                                    "cmu_01_03_playground_climb_hang_swing.bvh",
                                    "boxing_toes.bvh"};
  std::vector<std::string> scenes;  // --scene: only these scenes (default all).
  int max_pairs = 1000;             // Per scene and clip.
  double rate_hz = 30;
  double eps_s = 1e-4;
  double delta_m = 1e-3;
  bool peers = true;  // Also time FCL and Bullet in the same run.
  /// Also time FCL's continuous query (fcl::continuousCollide, linear motion,
  /// its naive solver: FCL_CCD_STEPS discrete checks; its conservative
  /// advancement misses capsule-mesh contacts, see docs/BENCHMARKS.md).
  bool fcl_ccd = false;
  std::string motion = "articulated";  // --motion: articulated or independent.
  bool per_link = false;               // --per-link: a bracket for every link.
  /// What times a pair: "wall" (steady clock) or "thread" (this thread's CPU
  /// time, CLOCK_THREAD_CPUTIME_ID: leaves out time other processes held the
  /// core, which on a shared machine is most of a wall-clock tail).
  std::string clock = "wall";
  int warmup_pairs = 10;  // Untimed pairs per scene and clip before timing, for every method.
  /// Also time the GPU backend on the same pairs ("gpu": any renderer, also
  /// llvmpipe; "hardware": only a hardware EGL device; "off").
  std::string gpu = "gpu";
  int gpu_device = -1;
  std::string markdown_path;  // Also write the table as Markdown here.
  MeshLoadOptions mesh;       // --max-mesh-bytes.
  bool sweep = false;         // --sweep: the batch-size sweep (tools/bench_sweep.h).
  std::vector<int> sweep_sizes = {1, 16, 64, 256, 4096};
  int threads = DefaultThreadCount();  // --threads: the sweep's workers.
  /// --write-scene: write the one named scene's placed meshes as one binary
  /// PLY here and stop (the daemon takes mesh files, not placements).
  std::string write_scene;
};

void AddBenchOptions(CLI::App* app, BenchCommandOptions* options);
int RunBenchCommand(const BenchCommandOptions& options);

}  // namespace sweptccd
