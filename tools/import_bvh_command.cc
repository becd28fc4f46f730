#include "tools/import_bvh_command.h"

#include <spdlog/spdlog.h>

#include <CLI/CLI.hpp>
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <map>
#include <nlohmann/json.hpp>

#include "core/avatar/pose.h"
#include "core/bounded_file.h"
#include "core/errors.h"
#include "msgs/text.h"
#include "tools/output_paths.h"

namespace sweptccd {

void AddImportBvhOptions(CLI::App* app, ImportBvhCommandOptions* o) {
  app->add_option("--bvh", o->bvh_path, "BVH motion-capture file")->required();
  app->add_option("--skeleton-out", o->skeleton_out, "Skeleton JSON to write")->required();
  app->add_option("--poses-out", o->poses_out, "Pose stream (JSON Lines) to write")->required();
  app->add_option("--up", o->up_axis, "Up axis of the output: y (as BVH) or z")
      ->check(CLI::IsMember({'y', 'z'}));
  app->add_option("--unit", o->unit_scale_m, "Metres per file unit (default: detect)");
  app->add_option("--rate", o->rate_hz, "Output rate in Hz by frame skipping (default: clip rate)");
  app->add_option("--start", o->start_frame, "First frame (default: skip a reference T-pose)");
  app->add_option("--frames", o->frame_count, "Frames to read (default: all)");
  app->add_option("--offset", o->offset, "x y z metres added to every position")->expected(3);
  app->add_option("--utime-start", o->utime_start, "Microseconds added to every utime");
  app->add_option("--radii", o->radii_path,
                  "JSON file {\"LINK\": RADIUS_M, ...} overriding the default capsule radii");
}

namespace {

// The --radii file: an object of link name -> radius in metres (> 0, finite).
std::map<std::string, double> ReadRadiiFile(const std::string& path) {
  std::ifstream in = OpenInputFile(path, "radii file");
  nlohmann::json j;
  try {
    j = nlohmann::json::parse(in);
  } catch (const nlohmann::json::exception& e) {
    throw InputError(path + ": not JSON (" + e.what() + ")");
  }
  if (!j.is_object()) {
    throw InputError(path + ": expected an object {\"link name\": radius in metres, ...}");
  }
  std::map<std::string, double> radii;
  for (const auto& [name, value] : j.items()) {
    if (!value.is_number() || !std::isfinite(value.get<double>()) || !(value.get<double>() > 0)) {
      throw InputError(path + ": radius of '" + name +
                       "' must be a finite number of metres > 0, got " + value.dump());
    }
    const std::vector<std::string>& links = MocapLinkNames();
    if (std::find(links.begin(), links.end(), name) == links.end()) {
      std::string known;
      for (const std::string& l : links) known += (known.empty() ? "" : ", ") + l;
      throw InputError(path + ": unknown link '" + name + "' (links: " + known + ")");
    }
    radii[name] = value.get<double>();
  }
  return radii;
}

}  // namespace

MocapClip ImportBvhClip(const ImportBvhCommandOptions& o) {
  MocapImportOptions mo;
  mo.up_axis = o.up_axis;
  mo.unit_scale_m = o.unit_scale_m;
  mo.start_frame = o.start_frame;
  mo.frame_count = o.frame_count;
  if (!o.radii_path.empty()) mo.radius_override_m = ReadRadiiFile(o.radii_path);
  if (o.rate_hz < 0 || !std::isfinite(o.rate_hz)) {
    throw InputError("import-bvh: --rate must be a positive number of Hz");
  }
  MocapClip probe = ImportBvhFile(o.bvh_path, mo);
  if (o.rate_hz > 0) {
    mo.frame_step =
        std::max(1, static_cast<int>(std::lround(1.0 / (probe.frame_time_s * o.rate_hz))));
    probe = ImportBvhFile(o.bvh_path, mo);
  }
  return probe;
}

namespace {

void CheckPlacement(const ImportBvhCommandOptions& o, const MocapClip& clip) {
  for (double v : o.offset) {
    if (!std::isfinite(v) || std::fabs(v) > kMaxCoordinate) {
      throw InputError("import-bvh: --offset must be three finite numbers of metres within 1e9");
    }
  }
  // utime_start plus the clip's utimes must stay an int64 (SPEC utime).
  if (!std::isfinite(o.utime_start) || std::fabs(o.utime_start) > 4e18 ||
      (!clip.poses.empty() &&
       std::fabs(static_cast<double>(clip.poses.back().utime)) + std::fabs(o.utime_start) > 9e18)) {
    throw InputError(
        "import-bvh: --utime-start must be finite and keep every utime within int64 "
        "(|value| <= 4e18 microseconds)");
  }
}

// Writes `text` to `path`; throws InputError naming the file when it fails.
void WriteWhole(const std::string& path, const std::string& text, const char* what) {
  std::ofstream out(path, std::ios::binary | std::ios::trunc);
  if (!out) throw InputError(path + ": cannot write the " + what);
  out << text;
  out.flush();
  if (!out) throw InputError(path + ": error while writing the " + what);
}

}  // namespace

int RunImportBvhCommand(const ImportBvhCommandOptions& o) {
  try {
    RefuseClashingPaths({{"--bvh", o.bvh_path}, {"--radii", o.radii_path}},
                        {{"--skeleton-out", o.skeleton_out}, {"--poses-out", o.poses_out}});
    MocapClip probe = ImportBvhClip(o);
    CheckPlacement(o, probe);
    if (o.offset.size() == 3) {
      TranslateClip(&probe, Eigen::Vector3d(o.offset[0], o.offset[1], o.offset[2]));
    }
    // Both files are made in memory first, so a refusal writes nothing; a
    // write that fails names its file (and removes the skeleton written
    // before it, so no half of the pair is left behind).
    std::string poses_text;
    for (Pose pose : probe.poses) {
      pose.utime += static_cast<int64_t>(o.utime_start);
      Pose check = pose;  // Validated as `query` would read it; written as is.
      const std::string error = ValidateAndNormalizePose(&check, probe.skeleton.num_links());
      if (!error.empty()) {
        throw InputError("import-bvh: pose at utime " + std::to_string(pose.utime) +
                         " would be invalid: " + error);
      }
      poses_text += PoseToJsonLine(pose) + '\n';
    }
    WriteWhole(o.skeleton_out, SkeletonToJson(probe.skeleton) + '\n', "skeleton");
    try {
      WriteWhole(o.poses_out, poses_text, "poses");
    } catch (const InputError&) {
      std::error_code ec;
      if (std::filesystem::is_regular_file(o.skeleton_out, ec)) {
        std::filesystem::remove(o.skeleton_out, ec);
      }
      throw;
    }
    spdlog::info("{}: {} links, {} poses at {:.1f} Hz, {:.4f} m per unit", o.bvh_path,
                 probe.skeleton.num_links(), probe.poses.size(), 1.0 / probe.frame_time_s,
                 probe.unit_scale_m);
    return 0;
  } catch (const InputError& e) {
    std::fprintf(stderr, "error: %s\n", DisplayError(e.what()).c_str());
    return 2;
  }
}

}  // namespace sweptccd
