// The full-body avatar benchmark (issue 31): per pair, the 81-link avatar of
// XR_META_body_tracking_full_body (84 joints, --hands full) against the
// 16-link CMU avatar, the same clips, scenes and pairs, same run.
//
// The body joints follow the CMU clip's 16 links (each joint on a link's
// segment). THE FINGERS ARE PROCEDURALLY ANIMATED, NOT CAPTURED: every hand
// cycles reach (open), grasp (curl), hold and release, 3 s a cycle, in the
// hand link's frame. The 81-link avatar is timed twice, with the engine's
// hierarchical link bounds (QueryOptions::link_groups, the default) and
// without (every link on its own, as before them), alternating which goes
// first; their answers must be equal (checked, the run aborts otherwise).
// Timings are wall-clock per pair (median, p99, max, microseconds); nothing
// is asserted about them.
//
//   build/bin/sweptccd_full_body_bench [--pairs N] [--rate HZ] [--clock wall|thread]
//       [--scene NAME] [--clip NAME] [--only 16|on|off]
//   build/bin/sweptccd_full_body_bench --convert SKEL16.json POSES16.jsonl OUT_DIR
//
// --clock thread times this thread's CPU time (CLOCK_THREAD_CPUTIME_ID),
// which leaves out time other processes held the core (on a shared machine,
// most of a wall-clock tail). --scene and --clip keep one scene or clip;
// --only runs one avatar (16 links, or 81 with groups on or off) and skips
// the on/off answer check, so that callgrind (tools/bench_callgrind.sh's
// --toggle-collect on CcdEngine::Query*) counts one avatar's instructions.

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
#include "mocap/mocap_import.h"
#include "tools/bench_common.h"

namespace sweptccd {
namespace {

using Eigen::Vector3d;

bool g_thread_clock = false;  // --clock thread: this thread's CPU time.

double NowS() {
  if (g_thread_clock) return bench::ThreadCpuSeconds();
  return std::chrono::duration<double>(std::chrono::steady_clock::now().time_since_epoch()).count();
}

double SmoothStep(double x) {
  x = std::clamp(x, 0.0, 1.0);
  return x * x * (3 - 2 * x);
}

// Grasp cycle, 3 s: open 0-1 s (reach), curl 1-1.4 s (grasp), closed to
// 2.2 s (hold), open 2.2-2.6 s (release), open to 3 s.
double Curl(double t_s) {
  const double t = std::fmod(t_s, 3.0);
  if (t < 1.0) return 0;
  if (t < 1.4) return SmoothStep((t - 1.0) / 0.4);
  if (t < 2.2) return 1;
  if (t < 2.6) return 1 - SmoothStep((t - 2.2) / 0.4);
  return 0;
}

class FrameBuilder {
 public:
  FrameBuilder(const JointSet& set, const Skeleton& mocap) : set_(set), mocap_(mocap) {}

  JointFrame Build(const Pose& pose) const {
    JointFrame f;
    f.utime = pose.utime;
    f.joints.resize(set_.num_joints());
    auto A = [&](const char* link) { return pose.links[Index(link)].p; };
    auto B = [&](const char* link) {
      const int i = Index(link);
      return Vector3d(pose.links[i].p + pose.links[i].q * mocap_.link(i).b_L);
    };
    auto Q = [&](const char* link) { return pose.links[Index(link)].q; };
    auto lerp = [](const Vector3d& a, const Vector3d& b, double s) -> Vector3d {
      return a + s * (b - a);
    };
    auto put = [&](const std::string& word, const Vector3d& p, const Eigen::Quaterniond& q) {
      const int j = set_.FindJoint("XR_FULL_BODY_JOINT_" + word + "_META");
      if (j < 0) std::abort();
      f.joints[j].p = p;
      f.joints[j].q = q;
    };
    put("ROOT", A("pelvis"), Q("pelvis"));
    put("HIPS", A("pelvis"), Q("pelvis"));
    put("SPINE_LOWER", A("spine"), Q("spine"));
    put("SPINE_MIDDLE", lerp(A("spine"), B("spine"), 0.5), Q("spine"));
    put("SPINE_UPPER", A("chest"), Q("chest"));
    const Vector3d chest = lerp(A("chest"), B("chest"), 0.5);
    put("CHEST", chest, Q("chest"));
    put("NECK", A("head"), Q("head"));
    put("HEAD", lerp(A("head"), B("head"), 0.3), Q("head"));
    for (const char* side : {"LEFT", "RIGHT"}) {
      const bool left = side[0] == 'L';
      const std::string s = side;
      auto m = [&](const char* base) {
        static thread_local std::string name;
        name = std::string(base) + (left ? "_l" : "_r");
        return name;
      };
      const std::string ua = m("upper_arm"), fa = m("forearm"), ha = m("hand");
      const std::string th = m("thigh"), sh = m("shin"), fo = m("foot");
      put(s + "_SHOULDER", lerp(chest, A(ua.c_str()), 0.3), Q(ua.c_str()));
      put(s + "_SCAPULA", lerp(chest, A(ua.c_str()), 0.6), Q(ua.c_str()));
      put(s + "_ARM_UPPER", A(ua.c_str()), Q(ua.c_str()));
      put(s + "_ARM_LOWER", A(fa.c_str()), Q(fa.c_str()));
      put(s + "_HAND_WRIST_TWIST", lerp(A(fa.c_str()), A(ha.c_str()), 0.8), Q(fa.c_str()));
      Hand(s, A(ha.c_str()), B(ha.c_str()), Q(ha.c_str()),
           Curl(1e-6 * pose.utime + (left ? 1.5 : 0)), put);
      put(s + "_UPPER_LEG", A(th.c_str()), Q(th.c_str()));
      put(s + "_LOWER_LEG", A(sh.c_str()), Q(sh.c_str()));
      put(s + "_FOOT_ANKLE_TWIST", lerp(A(sh.c_str()), A(fo.c_str()), 0.9), Q(sh.c_str()));
      put(s + "_FOOT_ANKLE", A(fo.c_str()), Q(fo.c_str()));
      put(s + "_FOOT_SUBTALAR", lerp(A(fo.c_str()), B(fo.c_str()), 0.15), Q(fo.c_str()));
      put(s + "_FOOT_TRANSVERSE", lerp(A(fo.c_str()), B(fo.c_str()), 0.55), Q(fo.c_str()));
      put(s + "_FOOT_BALL", B(fo.c_str()), Q(fo.c_str()));
    }
    return f;
  }

 private:
  int Index(const char* link) const {
    const int i = mocap_.FindLink(link);
    if (i < 0) std::abort();
    return i;
  }

  // Procedural fingers in the hand link's frame: forward (wrist to the hand
  // link's end), lateral and palm normal; each finger curls about the
  // lateral axis by `curl` (0 open .. 1 closed).
  template <class Put>
  static void Hand(const std::string& s, const Vector3d& wrist, const Vector3d& end,
                   const Eigen::Quaterniond& q, double curl, const Put& put) {
    const Vector3d fwd = (end - wrist).normalized();
    Vector3d lat = q * Vector3d::UnitX();
    lat -= lat.dot(fwd) * fwd;
    if (lat.norm() < 1e-6) lat = fwd.unitOrthogonal();
    lat.normalize();
    const Vector3d normal = fwd.cross(lat);
    const std::string h = s + "_HAND_";
    put(h + "WRIST", wrist, q);
    put(h + "PALM", wrist + 0.05 * fwd, q);
    struct Finger {
      const char* name;
      double spread;     // Along lat, metres, at the knuckle.
      double meta;       // Wrist to knuckle, metres.
      double bones[3];   // Proximal, intermediate, distal to the tip.
      double angles[3];  // Full curl per joint, radians.
    };
    const Finger fingers[4] = {{"INDEX", 0.025, 0.085, {0.040, 0.024, 0.020}, {1.2, 1.5, 1.0}},
                               {"MIDDLE", 0.007, 0.085, {0.045, 0.027, 0.021}, {1.2, 1.5, 1.0}},
                               {"RING", -0.011, 0.080, {0.042, 0.026, 0.020}, {1.2, 1.5, 1.0}},
                               {"LITTLE", -0.028, 0.072, {0.034, 0.020, 0.018}, {1.2, 1.5, 1.0}}};
    for (const Finger& fg : fingers) {
      const std::string n = h + fg.name;
      put(n + "_METACARPAL", wrist + 0.015 * fwd + 0.5 * fg.spread * lat, q);
      Vector3d p = wrist + fg.meta * fwd + fg.spread * lat;
      put(n + "_PROXIMAL", p, q);
      Eigen::Quaterniond bend = Eigen::Quaterniond::Identity();
      const char* parts[3] = {"_INTERMEDIATE", "_DISTAL", "_TIP"};
      for (int k = 0; k < 3; ++k) {
        bend = Eigen::Quaterniond(Eigen::AngleAxisd(curl * fg.angles[k], lat)) * bend;
        p += fg.bones[k] * (bend * fwd);
        put(n + parts[k], p, bend * q);
      }
    }
    // Thumb: from the wrist's side, along (fwd + lat), curling about the
    // palm normal.
    const Vector3d dir0 = (fwd + lat).normalized();
    Vector3d p = wrist + 0.02 * fwd + 0.02 * lat;
    put(h + "THUMB_METACARPAL", p, q);
    const double lens[3] = {0.045, 0.032, 0.028};
    const char* parts[3] = {"_THUMB_PROXIMAL", "_THUMB_DISTAL", "_THUMB_TIP"};
    Eigen::Quaterniond bend = Eigen::Quaterniond::Identity();
    for (int k = 0; k < 3; ++k) {
      p += lens[k] * (bend * dir0);
      put(s + "_HAND" + parts[k], p, bend * q);
      bend = Eigen::Quaterniond(Eigen::AngleAxisd(-curl * 0.6, normal)) * bend;
    }
  }

  const JointSet& set_;
  const Skeleton& mocap_;
};

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
  const FrameBuilder fb(set, mocap);
  const JointFrame cal = fb.Build(poses[0]);
  JointSkeletonOptions so;
  so.calibration = &cal;
  so.hands = HandsOption::kFull;
  so.length_tolerance_m = 0.05;  // As the bench: the clip's clavicles move a little.
  so.length_tolerance_fraction = 0.25;
  const JointSkeleton js = JointSkeleton::Build(set, so);
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
  std::string only_scene, only_clip, only;
  for (int i = 1; i + 1 < argc; i += 2) {
    const std::string a = argv[i];
    if (a == "--pairs") max_pairs = std::atoi(argv[i + 1]);
    if (a == "--rate") rate_hz = std::atof(argv[i + 1]);
    if (a == "--clock") g_thread_clock = std::string(argv[i + 1]) == "thread";
    if (a == "--scene") only_scene = argv[i + 1];
    if (a == "--clip") only_clip = argv[i + 1];
    if (a == "--only") only = argv[i + 1];
  }
  SWEPTCCD_CHECK(only.empty() || only == "16" || only == "on" || only == "off");
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
      bench::PlaceClipOnFloor(&clip, 'y', sc.floor, sc.centre);
      const FrameBuilder fb(set, clip.skeleton);
      const JointFrame cal = fb.Build(clip.poses[0]);
      JointSkeletonOptions so;
      so.calibration = &cal;
      so.hands = HandsOption::kFull;
      // The clip's clavicles move the shoulder joints against the chest a
      // little: a generous tolerance keeps those frames.
      so.length_tolerance_m = 0.05;
      so.length_tolerance_fraction = 0.25;
      const JointSkeleton js = JointSkeleton::Build(set, so);
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
      "release; 3 s cycle), not captured.\n\n",
      rate_hz, g_thread_clock ? "thread CPU" : "wall");
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
