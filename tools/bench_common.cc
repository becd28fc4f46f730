#include "tools/bench_common.h"

#include <algorithm>
#include <ctime>
#include <filesystem>

namespace sweptccd::bench {

double ThreadCpuSeconds() {
  timespec ts;
  clock_gettime(CLOCK_THREAD_CPUTIME_ID, &ts);
  return static_cast<double>(ts.tv_sec) + 1e-9 * static_cast<double>(ts.tv_nsec);
}

std::string DataFile(const std::string& path) {
  std::error_code ec;
  return std::filesystem::exists(path, ec) ? path : path + ".gz";
}

void PlaceClipOnFloor(MocapClip* clip, char up_axis, double floor, const Eigen::Vector2d& centre) {
  const int up = up_axis == 'z' ? 2 : 1;
  const int h0 = 0, h1 = up_axis == 'z' ? 1 : 2;
  double lowest = 1e300;
  Eigen::Vector3d lo = Eigen::Vector3d::Constant(1e300), hi = -lo;
  for (const Pose& pose : clip->poses) {
    for (int i = 0; i < clip->skeleton.num_links(); ++i) {
      const Link& l = clip->skeleton.link(i);
      const LinkPose& X = pose.links[i];
      for (const Eigen::Vector3d& e : {l.a_L, l.b_L}) {
        lowest = std::min(lowest, (X.p + X.q * e)[up] - l.radius);
      }
    }
    const Eigen::Vector3d& root = pose.links[clip->skeleton.root()].p;
    lo = lo.cwiseMin(root);
    hi = hi.cwiseMax(root);
  }
  Eigen::Vector3d offset = Eigen::Vector3d::Zero();
  offset[up] = floor + 0.02 - lowest;
  offset[h0] = centre[0] - 0.5 * (lo[h0] + hi[h0]);
  offset[h1] = centre[1] - 0.5 * (lo[h1] + hi[h1]);
  TranslateClip(clip, offset);
}

}  // namespace sweptccd::bench
