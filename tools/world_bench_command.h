#pragma once
// `sweptccd world-bench`: the shared-world benchmark of issue 12. Writes a
// world file from real data (avatars from CMU and boxing mocap in a tight
// grid on the breakfast room's floor, objects held in a hand and one thrown
// through the group), then answers every avatar record single-threaded and
// prints a table: the environment-only part beside the whole answer (every
// other entity through the broad phase), on the thread CPU clock.

#include <cstdint>
#include <string>

namespace CLI {
class App;
}

namespace sweptccd {

struct WorldBenchOptions {
  std::string out_dir;   // The world file and everything it names go here.
  std::string data_dir;  // Folder with env/ and mocap/; empty: the project's data/.
  int avatars = 16;
  int objects = 4;       // The last is thrown, the others held (>= 0).
  double seconds = 3.0;  // Clip length per avatar.
  double spacing = 0.8;  // Metres between neighbouring grid cells.
  int warmup = 10;       // Records per avatar answered untimed first.
  bool generate_only = false;
  int threads = 1;  // --threads: workers answering the records (tallies equal for any number).
  /// "grid" (issue 12's world above) or "hands" (issue 31: hands reaching
  /// for, grasping and carrying objects, 81-link avatars beside 16-link
  /// ones; tools/world_bench_hands.h). --objects does not apply to "hands"
  /// (one object per avatar); it runs on one thread (--threads 1).
  std::string scenario = "grid";
  uint64_t seed = 31;  // --seed: the hands scenario's grasp times, boxes and grips.
};

void AddWorldBenchOptions(CLI::App* app, WorldBenchOptions* options);

/// Returns 0 when done, 2 with a one-line message on stderr for bad options
/// or unreadable data.
int RunWorldBenchCommand(const WorldBenchOptions& options);

}  // namespace sweptccd
