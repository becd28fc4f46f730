#pragma once
// Shared by the benchmark commands (`sweptccd bench`, `sweptccd
// world-bench`): the thread CPU clock, the percentile rule of every table (core/percentile.h),
// data files by plain name and how a clip is stood on a scene's floor.

#include <Eigen/Core>
#include <string>
#include <vector>

#include "core/percentile.h"
#include "mocap/mocap_import.h"

namespace sweptccd::bench {

/// This thread's CPU time in seconds (CLOCK_THREAD_CPUTIME_ID).
double ThreadCpuSeconds();

/// Median, p99, max and mean of a sample by the one percentile rule
/// (core/percentile.h); no value is dropped.
using Stats = ::sweptccd::Summary;
using ::sweptccd::Summarise;

/// A data file by its plain name: as named when present, else its gzip
/// (data/ ships NAME.gz; a larger folder may hold either).
std::string DataFile(const std::string& path);

/// Shifts the clip so the middle of its root path is at `centre` (the two
/// horizontal coordinates: x and z for `up` 'y', x and y for 'z') and its
/// lowest capsule point over the whole clip is 2 cm above `floor`.
void PlaceClipOnFloor(MocapClip* clip, char up, double floor, const Eigen::Vector2d& centre);

}  // namespace sweptccd::bench
