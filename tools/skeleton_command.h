#pragma once
// `sweptccd skeleton`: the SPEC skeleton of a tracking runtime's joint set
// (OpenXR, WebXR, VRM; docs/SKELETONS.md), and its joint frames converted
// to a SPEC pose stream.

#include <string>

namespace CLI {
class App;
}

namespace sweptccd {

struct SkeletonCommandOptions {
  std::string from;  // Joint set id (core/avatar/joint_set.h).
  double height_m = 1.75;
  std::string hands = "full";  // none, simple or full.
  std::string calibrate_path;  // Joint frames; the first sets lengths (and radii).
  std::string out_path;        // Skeleton JSON to write.
  std::string joints_path;     // Joint frames (JSON Lines) to convert.
  std::string poses_out_path;  // SPEC pose stream to write.
  double length_tolerance_m = 0.01;
  bool describe = false;  // Print the joints and links to standard output.
};

void AddSkeletonOptions(CLI::App* app, SkeletonCommandOptions* options);
int RunSkeletonCommand(const SkeletonCommandOptions& options);

}  // namespace sweptccd
