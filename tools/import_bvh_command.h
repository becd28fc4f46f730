#pragma once
// `sweptccd import-bvh`: a BVH motion-capture clip becomes a SPEC skeleton
// file and a pose stream file.

#include <string>
#include <vector>

#include "mocap/mocap_import.h"

namespace CLI {
class App;
}

namespace sweptccd {

struct ImportBvhCommandOptions {
  std::string bvh_path;
  std::string skeleton_out;
  std::string poses_out;
  char up_axis = 'y';
  double unit_scale_m = 0;    // 0: detect.
  double rate_hz = 0;         // 0: the clip's own rate.
  int start_frame = -1;       // -1: auto (skips a reference T-pose frame).
  int frame_count = -1;       // -1: to the end.
  std::vector<double> offset;  // x y z added to every position (metres).
  double utime_start = 0;     // Microseconds added to every utime.
  std::string radii_path;     // JSON {"link name": radius in metres, ...}; empty: defaults.
};

void AddImportBvhOptions(CLI::App* app, ImportBvhCommandOptions* options);
int RunImportBvhCommand(const ImportBvhCommandOptions& options);

/// Imports `options.bvh_path` as `sweptccd import-bvh` does: up axis, unit,
/// start, frames and the --rate subsampling (frame skipping). `offset` and
/// `utime_start` are NOT applied (callers place the clip themselves).
/// Throws InputError for a bad file or bad options. Also used in-process by
/// `sweptccd simulate-tracker --bvh`, so both give the same poses.
MocapClip ImportBvhClip(const ImportBvhCommandOptions& options);

}  // namespace sweptccd
