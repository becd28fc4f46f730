// The full-body avatar benchmark (issue 31): per pair, the 81-link avatar of
// XR_META_body_tracking_full_body (84 joints, --hands full) against the
// 16-link CMU avatar, the same clips, scenes and pairs, same run.
//
// The body joints follow the CMU clip's 16 links (each joint on a link's
// segment; mocap/full_body_frames.h). THE FINGERS ARE PROCEDURALLY ANIMATED,
// NOT CAPTURED: every hand cycles reach (open), grasp (curl), hold and
// release, 3 s a cycle, in the hand link's frame. The 81-link avatar is timed twice, with the
// engine's hierarchical link bounds (QueryOptions::link_groups, the default) and without (every
// link on its own, as before them), alternating which goes first; their answers must be equal
// (checked, the run aborts otherwise). Timings are wall-clock per pair (median, p99, max,
// microseconds); nothing is asserted about them.
//
//   build/bin/sweptccd_full_body_bench [--pairs N] [--rate HZ] [--clock wall|thread]
//       [--scene NAME] [--clip NAME] [--only 16|on|off] [--lift M]
//   build/bin/sweptccd_full_body_bench --convert SKEL16.json POSES16.jsonl OUT_DIR
//
// --clock thread times this thread's CPU time (CLOCK_THREAD_CPUTIME_ID),
// which leaves out time other processes held the core (on a shared machine,
// most of a wall-clock tail). --scene and --clip keep one scene or clip;
// --only runs one avatar (16 links, or 81 with groups on or off) and skips
// the on/off answer check, so that callgrind (tools/bench_callgrind.sh's
// --toggle-collect on CcdEngine::Query*) counts one avatar's instructions.
// --lift M raises both avatars M metres above the scene's floor (e.g. 20:
// pairs with nothing near, against the walk's feet near the floor).

#include <Eigen/Geometry>
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <optional>
#include <string>
#include <vector>

#include "core/avatar/joint_frame.h"
#include "core/avatar/joint_set.h"
#include "core/avatar/pose.h"
#include "core/avatar/skeleton.h"
#include "core/errors.h"
#include "core/query/ccd_query.h"
#include "core/scene/environment.h"
#include "mocap/full_body_frames.h"
#include "mocap/mocap_import.h"
#include "tools/bench_common.h"

namespace sweptccd {
namespace {

bool g_thread_clock = false;  // --clock thread: this thread's CPU time.

double NowS() {
  if (g_thread_clock) return bench::ThreadCpuSeconds();
  return std::chrono::duration<double>(std::chrono::steady_clock::now().time_since_epoch()).count();
}

struct Row {
  std::string scene, clip, groups;
  int links = 0, pairs = 0, contacts = 0, undecided = 0, refused = 0;
  bench::Stats us;
};

// The two 81-link answers (link groups on and off) must be the same.
bool SameAnswer(const QueryResult& x, const QueryResult& y) {
  if (x.contact != y.contact || x.undecided != y.undecided || x.s_lo != y.s_lo ||
      x.s_hi != y.s_hi || x.initially_colliding != y.initially_colliding ||
      x.contacts.size() != y.contacts.size()) {
    return false;
  }
  for (size_t i = 0; i < x.contacts.size(); ++i) {
    const ContactRecord& a = x.contacts[i];
    const ContactRecord& b = y.contacts[i];
    if (a.link != b.link || a.object != b.object || a.triangle != b.triangle || a.s != b.s ||
        a.separation != b.separation || a.point_link != b.point_link) {
      return false;
    }
  }
  return true;
}

// --convert SKEL16.json POSES16.jsonl OUT_DIR: the 16-link CMU avatar's
// stream (as `sweptccd import-bvh` writes it) as the 81-link meta-full-body
// avatar's, fingers procedurally animated as in the bench: OUT_DIR/
// skeleton.json (calibrated on the first pose) and OUT_DIR/poses.jsonl, one
// line per pose the conversion accepts (tools/service_bench/run.sh,
// FULL_BODY=1). Returns the process status.
int Convert(const std::string& skeleton_path, const std::string& poses_path,
            const std::string& out_dir) {
  const Skeleton mocap = LoadSkeletonFile(skeleton_path);
  std::ifstream in(poses_path);
  std::vector<Pose> poses;
  std::string line, error;
  while (std::getline(in, line)) {
    if (line.empty()) continue;
    std::optional<Pose> p = ParsePoseLine(line, mocap.num_links(), &error);
    if (!p) {
      std::fprintf(stderr, "%s: %s\n", poses_path.c_str(), error.c_str());
      return 1;
    }
    poses.push_back(*p);
  }
  if (poses.empty()) {
    std::fprintf(stderr, "%s: no poses\n", poses_path.c_str());
    return 1;
  }
  const JointSet& set = FindJointSet("meta-full-body");
  const full_body::FrameBuilder fb(set, mocap);
  const JointSkeleton js = full_body::CalibratedFullBody(set, fb.Build(poses[0]));
  std::ofstream skel_out(out_dir + "/skeleton.json");
  skel_out << SkeletonToJson(js.skeleton()) << "\n";
  std::ofstream poses_out(out_dir + "/poses.jsonl");
  int refused = 0;
  for (const Pose& p : poses) {
    Pose full;
    if (js.Convert(fb.Build(p), &full).empty()) {
      poses_out << PoseToJsonLine(full) << "\n";
    } else {
      ++refused;
    }
  }
  std::fprintf(stderr, "%zu poses, %d refused, %d links\n", poses.size(), refused,
               js.skeleton().num_links());
  return skel_out && poses_out ? 0 : 1;
}

int Main(int argc, char** argv) {
  if (argc == 5 && std::string(argv[1]) == "--convert") return Convert(argv[2], argv[3], argv[4]);
  int max_pairs = 600;
  double rate_hz = 120;
  double lift_m = 0;
  std::string only_scene, only_clip, only;
  for (int i = 1; i + 1 < argc; i += 2) {
    const std::string a = argv[i];
    if (a == "--pairs") max_pairs = std::atoi(argv[i + 1]);
    if (a == "--rate") rate_hz = std::atof(argv[i + 1]);
    if (a == "--clock") g_thread_clock = std::string(argv[i + 1]) == "thread";
    if (a == "--scene") only_scene = argv[i + 1];
    if (a == "--clip") only_clip = argv[i + 1];
    if (a == "--only") only = argv[i + 1];
    if (a == "--lift") lift_m = std::atof(argv[i + 1]);
  }
  SWEPTCCD_CHECK(only.empty() || only == "16" || only == "on" || only == "off");
  SWEPTCCD_CHECK(std::isfinite(lift_m));
  const bool run16 = only.empty() || only == "16";
  const bool run_on = only.empty() || only == "on";
  const bool run_off = only.empty() || only == "off";
  const std::string dir = SWEPTCCD_DATA_DIR;
  struct Scene {
    const char* name;
    const char* file;
    double floor;
    Eigen::Vector2d centre;
  };
  // The placements of `sweptccd bench` (tools/bench_command.cc).
  const Scene scenes[] = {{"grey_white_room", "bitterli_grey_white_room.ply", 0.0, {2.3, -1.5}},
                          {"breakfast_room", "bitterli_breakfast_room.ply", -1.42, {-0.67, -1.9}}};
  const char* clips[] = {"cmu_02_01_walk.bvh", "cmu_05_06_dance_cartwheel_pirouettes_jete.bvh",
                         "boxing_toes.bvh"};
  const JointSet& set = FindJointSet("meta-full-body");
  std::vector<Row> rows;
  for (const Scene& sc : scenes) {
    if (!only_scene.empty() && only_scene != sc.name) continue;
    const Environment env = Environment::LoadFiles({bench::DataFile(dir + "/env/" + sc.file)});
    for (const char* clip_name : clips) {
      if (!only_clip.empty() && only_clip != clip_name) continue;
      MocapImportOptions mo;
      mo.up_axis = 'y';
      MocapClip clip = ImportBvhFile(bench::DataFile(dir + "/mocap/" + clip_name), mo);
      const int step =
          std::max(1, static_cast<int>(std::lround(1.0 / (clip.frame_time_s * rate_hz))));
      std::vector<Pose> poses;
      for (size_t f = 0; f < clip.poses.size(); f += step) poses.push_back(clip.poses[f]);
      clip.poses = poses;
      bench::PlaceClipOnFloor(&clip, 'y', sc.floor + lift_m, sc.centre);
      const full_body::FrameBuilder fb(set, clip.skeleton);
      // Calibrated on the first frame; the clip's clavicles move the
      // shoulder joints against the chest a little: a generous tolerance
      // keeps those frames.
      const JointSkeleton js = full_body::CalibratedFullBody(set, fb.Build(clip.poses[0]));
      std::vector<std::optional<Pose>> full(clip.poses.size());
      for (size_t k = 0; k < clip.poses.size(); ++k) {
        Pose p;
        if (js.Convert(fb.Build(clip.poses[k]), &p).empty()) full[k] = p;
      }
      const CcdEngine small(clip.skeleton, env);
      const CcdEngine big(js.skeleton(), env);
      QueryOptions q;
      QueryOptions q_flat = q;  // Before hierarchical link bounds: every link on its own.
      q_flat.link_groups = false;
      Row r16, r84, r84_flat;
      r16.scene = r84.scene = r84_flat.scene = sc.name;
      r16.clip = r84.clip = r84_flat.clip = clip_name;
      r16.links = clip.skeleton.num_links();
      r84.links = r84_flat.links = js.skeleton().num_links();
      r16.groups = "-";
      r84.groups = "on";
      r84_flat.groups = "off";
      std::vector<double> t16, t84, t84_flat;
      const int n = std::min<int>(max_pairs, static_cast<int>(clip.poses.size()) - 1);
      // Warm-up, untimed, the same first pairs through both.
      for (int k = 0; k < std::min(n, 10); ++k) {
        if (run16) (void)small.Query(clip.poses[k], clip.poses[k + 1], q);
        if (run_on && full[k] && full[k + 1]) (void)big.Query(*full[k], *full[k + 1], q);
        if (run_off && full[k] && full[k + 1]) (void)big.Query(*full[k], *full[k + 1], q_flat);
      }
      for (int k = 0; k < n; ++k) {
        if (!full[k] || !full[k + 1]) {
          ++r84.refused;
          continue;
        }
        double a = NowS();
        QueryResult x;
        if (run16) {
          x = small.Query(clip.poses[k], clip.poses[k + 1], q);
          t16.push_back(1e6 * (NowS() - a));
        }
        // Groups on and off alternate which goes first, pair by pair.
        QueryResult y, z;
        for (int turn = 0; turn < 2; ++turn) {
          const bool flat = (turn == 0) == (k % 2 == 0);
          if (!(flat ? run_off : run_on)) continue;
          a = NowS();
          (flat ? z : y) = big.Query(*full[k], *full[k + 1], flat ? q_flat : q);
          (flat ? t84_flat : t84).push_back(1e6 * (NowS() - a));
        }
        if (run_on && run_off) SWEPTCCD_CHECK(SameAnswer(y, z));
        ++r16.pairs;
        ++r84.pairs;
        ++r84_flat.pairs;
        r16.contacts += x.contact;
        r84.contacts += y.contact;
        r84_flat.contacts += z.contact;
        r16.undecided += x.undecided;
        r84.undecided += y.undecided;
        r84_flat.undecided += z.undecided;
      }
      r84_flat.refused = r84.refused;
      r16.us = bench::Summarise(t16);
      r84.us = bench::Summarise(t84);
      r84_flat.us = bench::Summarise(t84_flat);
      if (run16) rows.push_back(r16);
      if (run_off) rows.push_back(r84_flat);
      if (run_on) rows.push_back(r84);
    }
  }
  std::printf(
      "Full-body avatar (XR_META_body_tracking_full_body, --hands full) vs the 16-link CMU "
      "avatar, %.0f Hz, same pairs, %s clock.\nFingers: PROCEDURALLY ANIMATED (reach, grasp, hold, "
      "release; 3 s cycle), not captured.\n%s\n",
      rate_hz, g_thread_clock ? "thread CPU" : "wall",
      lift_m != 0
          ? ("Both avatars lifted " + std::to_string(lift_m) + " m above the floor.\n").c_str()
          : "");
  std::printf(
      "| scene | clip | links | link groups | pairs | contact | undecided | refused | median us "
      "| p99 us | max us |\n|---|---|---|---|---|---|---|---|---|---|---|\n");
  for (const Row& r : rows) {
    std::printf("| %s | %s | %d | %s | %d | %d | %d | %d | %.1f | %.1f | %.1f |\n", r.scene.c_str(),
                r.clip.c_str(), r.links, r.groups.c_str(), r.pairs, r.contacts, r.undecided,
                r.refused, r.us.median, r.us.p99, r.us.max);
  }
  return 0;
}

}  // namespace
}  // namespace sweptccd

int main(int argc, char** argv) {
  try {
    return sweptccd::Main(argc, argv);
  } catch (const sweptccd::InputError& e) {
    std::fprintf(stderr, "error: %s\n", e.what());
    return 2;
  }
}
