#include "tools/world_bench_scene.h"

#include <algorithm>
#include <cmath>
#include <fstream>
#include <nlohmann/json.hpp>
#include <utility>

#include "core/avatar/motion.h"
#include "core/errors.h"
#include "tools/bench_common.h"

namespace sweptccd::world_bench {

void WriteText(const std::filesystem::path& path, const std::string& text) {
  std::ofstream out(path, std::ios::binary | std::ios::trunc);
  out << text;
  out.flush();
  if (!out) throw InputError(path.string() + ": cannot write");
}

std::string BoxObj(const Eigen::Vector3d& half) {
  std::string s;
  for (int c = 0; c < 8; ++c) {
    s += "v " + std::to_string((c & 1) ? half.x() : -half.x()) + ' ' +
         std::to_string((c & 2) ? half.y() : -half.y()) + ' ' +
         std::to_string((c & 4) ? half.z() : -half.z()) + '\n';
  }
  // Faces as quads of corner indices (1-based), outward.
  static const int kQuads[6][4] = {{1, 3, 7, 5}, {2, 6, 8, 4}, {1, 5, 6, 2},
                                   {3, 4, 8, 7}, {1, 2, 4, 3}, {5, 7, 8, 6}};
  for (const auto& q : kQuads) {
    s += "f " + std::to_string(q[0]) + ' ' + std::to_string(q[1]) + ' ' + std::to_string(q[2]) +
         '\n';
    s += "f " + std::to_string(q[0]) + ' ' + std::to_string(q[2]) + ' ' + std::to_string(q[3]) +
         '\n';
  }
  return s;
}

std::string ObjectPoseLine(int64_t utime, const Eigen::Vector3d& p, const Eigen::Quaterniond& q) {
  nlohmann::ordered_json j;
  j["utime"] = utime;
  j["pose"] = {p.x(), p.y(), p.z(), q.w(), q.x(), q.y(), q.z()};
  return j.dump() + '\n';
}

std::vector<Pose> Resample(const MocapClip& clip, double start_s, double rate_hz, double seconds) {
  if (clip.poses.size() < 2) throw InputError("world-bench: a clip with fewer than two frames");
  const double length_s = clip.frame_time_s * static_cast<double>(clip.poses.size() - 1);
  start_s = std::min(start_s, std::max(0.0, length_s - seconds));
  const double end_s = std::min(length_s, start_s + seconds);
  std::vector<Pose> out;
  for (int k = 0; start_s + k / rate_hz <= end_s; ++k) {
    const double f = (start_s + k / rate_hz) / clip.frame_time_s;
    const size_t i = std::min(static_cast<size_t>(f), clip.poses.size() - 2);
    const PairMotion m(clip.skeleton, clip.poses[i], clip.poses[i + 1], MotionModel::kArticulated);
    Pose pose;
    pose.utime = std::llround(k * 1e6 / rate_hz);
    m.PosesAt(std::clamp(f - static_cast<double>(i), 0.0, 1.0), &pose.links);
    out.push_back(std::move(pose));
  }
  return out;
}

MocapClip GridAvatarClip(const std::string& data, int k, int cols, int rows, double spacing,
                         double seconds) {
  const ClipChoice& choice = kClips[k % std::size(kClips)];
  MocapImportOptions mo;
  mo.up_axis = 'y';
  MocapClip clip = ImportBvhFile(bench::DataFile(data + "/mocap/" + choice.file), mo);
  const double rate = kRates[k % std::size(kRates)];
  clip.poses = Resample(clip, choice.start_s, rate, seconds);
  const Eigen::Vector2d cell((k % cols - 0.5 * (cols - 1)) * spacing,
                             (k / cols - 0.5 * (rows - 1)) * spacing);
  bench::PlaceClipOnFloor(&clip, 'y', kFloor, kCentre + cell);
  for (Pose& pose : clip.poses) pose.utime += kUtime0 + 1000 * k;  // Clocks a little apart too.
  return clip;
}

}  // namespace sweptccd::world_bench
