#include "tools/bench_command.h"

#include <fcl/fcl.h>
#include <spdlog/spdlog.h>

#include <CLI/CLI.hpp>
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <ctime>
#include <filesystem>
#include <fstream>
#include <map>
#include <memory>
#include <sstream>

#include "core/errors.h"
#include "core/geometry/mesh.h"
#include "core/gpu/backend.h"
#include "core/query/ccd_query.h"
#include "core/scene/environment.h"
#include "mocap/mocap_import.h"
#include "msgs/text.h"
#include "tools/bench_common.h"
#include "tools/bench_sweep.h"
#include "tools/bullet_peer.h"
#include "tools/ply_writer.h"

namespace sweptccd {

void AddBenchOptions(CLI::App* app, BenchCommandOptions* o) {
  app->add_option("--data", o->data_dir,
                  "Folder with env/ and mocap/ (default: the project's data/, " SWEPTCCD_DATA_DIR
                  ")");
  app->add_option("--clip", o->clips, "BVH clips in mocap/ to replay");
  app->add_option("--scene", o->scenes,
                  "Only these scenes (morse_apartment, grey_white_room, breakfast_room, "
                  "breakfast+dragon_1.1M; default all of these; also breakfast+dragons_10M, "
                  "10.7 M triangles, only when named)");
  app->add_option("--write-scene", o->write_scene,
                  "Write the one --scene's placed meshes as one binary PLY here and stop (for "
                  "the daemon, which takes mesh files)");
  app->add_option("--max-pairs", o->max_pairs, "Pairs per scene and clip")
      ->check(CLI::Range(1, 100000000));
  app->add_option("--rate", o->rate_hz, "Tracker rate, Hz (the clip is resampled)")
      ->check(CLI::Range(1.0, 1000.0));
  app->add_option("--eps", o->eps_s, "Time tolerance, seconds");
  app->add_option("--delta", o->delta_m, "Distance tolerance, metres");
  app->add_flag("!--no-peers", o->peers, "Skip the FCL and Bullet peers");
  app->add_flag("--fcl-ccd", o->fcl_ccd,
                "Also time FCL's continuous query per link (linear motion, naive solver)");
  app->add_option("--motion", o->motion, "Motion model: articulated or independent")
      ->check(CLI::IsMember({"articulated", "independent"}));
  app->add_flag("--per-link", o->per_link, "Per-link mode (a bracket for every link)");
  app->add_option("--clock", o->clock,
                  "What times a pair: wall (steady clock) or thread (the thread's CPU time, "
                  "without time other processes held the core)")
      ->check(CLI::IsMember({"wall", "thread"}));
  app->add_option("--warmup", o->warmup_pairs,
                  "Untimed warm-up pairs per scene and clip, run by every method alike")
      ->check(CLI::Range(0, 100000));
  app->add_option("--gpu", o->gpu,
                  "GPU backend beside the CPU: gpu (any renderer), hardware, or off")
      ->check(CLI::IsMember({"gpu", "hardware", "off"}));
  app->add_option("--gpu-device", o->gpu_device, "EGL device index for the GPU backend");
  app->add_option("--markdown", o->markdown_path, "Also write the tables as Markdown");
  app->add_flag("--sweep", o->sweep,
                "Batch-size sweep instead of the per-pair table: pairs/s and latency per batch "
                "for the CPU on 1 thread, on --threads threads, and the GPU (bench_sweep.h)");
  app->add_option("--sweep-sizes", o->sweep_sizes, "Pairs per batch (default 1 16 64 256 4096)")
      ->check(CLI::Range(1, 1000000));
  app->add_option("--threads", o->threads,
                  "Workers of the sweep's all-threads methods (default: the number of cores, " +
                      std::to_string(o->threads) + ")")
      ->check(CLI::Range(1, 1024));
  app->add_option("--max-mesh-bytes", o->mesh.max_bytes,
                  "Largest mesh file, before and after gunzip, bytes (default 1 GiB)")
      ->check(CLI::PositiveNumber);
}

namespace {

using Clock = std::chrono::steady_clock;

double Seconds(Clock::time_point a, Clock::time_point b) {
  return std::chrono::duration<double>(b - a).count();
}

// The clock that times pairs (--clock): steady wall-clock time, or this
// thread's CPU time. Every method is timed with the same one.
bool g_thread_clock = false;

double NowS() {
  if (g_thread_clock) return bench::ThreadCpuSeconds();
  return std::chrono::duration<double>(Clock::now().time_since_epoch()).count();
}

using bench::DataFile;
using bench::Stats;
using bench::Summarise;

long ResidentKiB() {
  std::ifstream in("/proc/self/status");
  std::string line;
  while (std::getline(in, line)) {
    if (line.rfind("VmRSS:", 0) == 0) return std::stol(line.substr(6));
  }
  return 0;
}

// A scene of the benchmark: meshes (optionally scaled and moved), its up axis
// and where the avatar walks.
struct MeshPlacement {
  std::string file;
  double scale = 1;
  Eigen::Vector3d offset{0, 0, 0};
  double yaw_deg = 0;  // Turn about +y (the up axis of the scenes that use it), before scaling.
};
struct SceneSpec {
  std::string name;
  std::vector<MeshPlacement> meshes;
  char up = 'y';
  double floor = 0;              // Height of the floor along the up axis.
  Eigen::Vector2d centre{0, 0};  // Horizontal centre of the walk.
  bool opt_in = false;           // Only when --scene names it (too large for every run).
};

// `m`'s mesh placed; each file is read once per scene (`cache`), so the
// 10 M-triangle scene's twelve dragons cost one load.
TriangleMesh PlacedMesh(const std::string& dir, const MeshPlacement& m,
                        const MeshLoadOptions& options,
                        std::map<std::string, TriangleMesh>* cache) {
  auto it = cache->find(m.file);
  if (it == cache->end()) {
    it = cache->emplace(m.file, LoadMeshFile(DataFile(dir + "/env/" + m.file), options)).first;
  }
  TriangleMesh mesh = it->second;
  const Eigen::Matrix3d turn =
      Eigen::AngleAxisd(m.yaw_deg * M_PI / 180.0, Eigen::Vector3d::UnitY()).toRotationMatrix();
  for (Eigen::Vector3f& v : mesh.vertices) {
    v = (turn * v.cast<double>() * m.scale + m.offset).cast<float>();
  }
  return mesh;
}

// The 10 M-triangle scene (issue 30): the breakfast room and twelve copies of
// the 0.87 M-triangle Stanford dragon (scale 10, 2 m long): the 1.1 M scene's
// dragon where the walk is, and eleven more on a ring of 2.2 m around it,
// each turned 30 degrees further. 269,538 + 12 x 871,414 = 10,726,506
// triangles; deterministic (the bundled files, fixed placements).
std::vector<MeshPlacement> DragonRing() {
  const Eigen::Vector3d centre(-0.67, -1.42 - 0.527, -1.9);
  std::vector<MeshPlacement> meshes = {{"bitterli_breakfast_room.ply"},
                                       {"stanford_dragon_vrip.ply", 10.0, centre}};
  for (int k = 0; k < 11; ++k) {
    const double a = 2 * M_PI * k / 11;
    meshes.push_back({"stanford_dragon_vrip.ply", 10.0,
                      centre + 2.2 * Eigen::Vector3d(std::cos(a), 0, std::sin(a)), 30.0 * (k + 1)});
  }
  return meshes;
}

// FCL peer: discrete collision of the 16 capsules at the second pose of each
// pair against an OBBRSS hierarchy of the same triangles (what a CCD-less
// system does at each tracker sample).
class FclPeer {
 public:
  explicit FclPeer(const std::vector<TriangleMesh>& meshes) {
    const auto t0 = Clock::now();
    for (const TriangleMesh& mesh : meshes) {
      auto model = std::make_shared<fcl::BVHModel<fcl::OBBRSSd>>();
      std::vector<fcl::Vector3d> verts;
      verts.reserve(mesh.vertices.size());
      for (const auto& v : mesh.vertices) verts.emplace_back(v.x(), v.y(), v.z());
      std::vector<fcl::Triangle> tris;
      tris.reserve(mesh.num_triangles());
      for (size_t t = 0; t < mesh.num_triangles(); ++t) {
        tris.emplace_back(mesh.indices[3 * t], mesh.indices[3 * t + 1], mesh.indices[3 * t + 2]);
      }
      model->beginModel();
      model->addSubModel(verts, tris);
      model->endModel();
      objects_.push_back(std::make_unique<fcl::CollisionObjectd>(model));
    }
    build_s_ = Seconds(t0, Clock::now());
  }
  double build_s() const { return build_s_; }

  // True when some capsule touches at the pose.
  bool Collide(const Skeleton& skel, const Pose& pose) const {
    bool hit = false;
    for (int i = 0; i < skel.num_links() && !hit; ++i) {
      const Link& l = skel.link(i);
      fcl::CollisionObjectd capsule(Capsule(l), CapsuleFrame(l, pose.links[i]));
      for (const auto& obj : objects_) {
        fcl::CollisionRequestd request;
        fcl::CollisionResultd result;
        if (fcl::collide(&capsule, obj.get(), request, result) > 0) {
          hit = true;
          break;
        }
      }
    }
    return hit;
  }

  // FCL's continuous query: true when some capsule, moving linearly from its
  // frame at pose0 to its frame at pose1, touches a mesh. The naive solver
  // checks kFclCcdSteps evenly spaced discrete poses (not certified: thin
  // geometry between them is missed).
  bool Sweep(const Skeleton& skel, const Pose& pose0, const Pose& pose1) const {
    fcl::ContinuousCollisionRequestd request;
    request.ccd_motion_type = fcl::CCDM_LINEAR;
    request.ccd_solver_type = fcl::CCDC_NAIVE;
    request.num_max_iterations = kFclCcdSteps;
    const fcl::Transform3d identity = fcl::Transform3d::Identity();
    for (int i = 0; i < skel.num_links(); ++i) {
      const Link& l = skel.link(i);
      const auto capsule = Capsule(l);
      const fcl::Transform3d X0 = CapsuleFrame(l, pose0.links[i]);
      const fcl::Transform3d X1 = CapsuleFrame(l, pose1.links[i]);
      for (const auto& obj : objects_) {
        fcl::ContinuousCollisionResultd result;
        fcl::continuousCollide<double>(capsule.get(), X0, X1, obj->collisionGeometry().get(),
                                       identity, identity, request, result);
        if (result.is_collide) return true;
      }
    }
    return false;
  }

  static constexpr int kFclCcdSteps = 10;  // FCL's default num_max_iterations.

 private:
  // fcl::Capsule is centred on its frame with its axis along z.
  static std::shared_ptr<fcl::Capsuled> Capsule(const Link& l) {
    return std::make_shared<fcl::Capsuled>(l.radius, (l.b_L - l.a_L).norm());
  }
  static fcl::Transform3d CapsuleFrame(const Link& l, const LinkPose& x) {
    const Eigen::Vector3d a = x.p + x.q * l.a_L;
    const Eigen::Vector3d b = x.p + x.q * l.b_L;
    const double len = (b - a).norm();
    fcl::Transform3d X = fcl::Transform3d::Identity();
    X.translation() = 0.5 * (a + b);
    if (len > 0) {
      X.linear() = Eigen::Quaterniond::FromTwoVectors(Eigen::Vector3d::UnitZ(), (b - a) / len)
                       .toRotationMatrix();
    }
    return X;
  }

  std::vector<std::unique_ptr<fcl::CollisionObjectd>> objects_;
  double build_s_ = 0;
};

struct Row {
  std::string scene, clip;
  size_t triangles = 0;
  double build_s = 0, bytes_per_tri = 0, rss_per_tri = 0;
  int pairs = 0, contacts = 0, undecided = 0;
  Stats ours_us;
  Stats fcl_us;
  Stats gpu_us;
  int gpu_mismatches = -1;  // Pairs whose GPU answer differs from the CPU's; -1: no GPU.
  int fcl_misses = 0;       // Pairs where we found contact and FCL's end-pose test saw none.
  double fcl_build_s = 0;
  Stats bullet_us;
  int bullet_misses = 0;  // Pairs where we found contact and Bullet's sweep saw none.
  double bullet_build_s = 0;
  Stats fcl_ccd_us;        // --fcl-ccd only.
  int fcl_ccd_misses = 0;  // Pairs where we found contact and FCL's continuous query saw none.
};

double Ratio(double num, double den) { return den > 0 ? num / den : 0.0; }

// The targets of issue 11, per row: median no slower than Bullet's sweep,
// at least 5x faster than FCL's end-pose check, p99 at least 10x faster than
// Bullet's, p99 at most 5x our own median. Without the peers (--no-peers)
// their three targets are not measured: "n/a", and not counted.
std::string TargetLines(const std::vector<Row>& rows, bool peers) {
  std::ostringstream out;
  char buf[512];
  int met = 0, total = 0;
  auto verdict = [&](bool ok) {
    ++total;
    met += ok;
    return ok ? "met" : "MISSED";
  };
  for (const Row& r : rows) {
    if (r.pairs == 0) continue;
    const double self = Ratio(r.ours_us.p99, r.ours_us.median);
    if (!peers) {
      std::snprintf(buf, sizeof(buf),
                    "target %-22s %-18s  median<=Bullet n/a;  median 5x FCL n/a;  p99 10x Bullet "
                    "n/a (--no-peers);  p99<=5x median (x%.2f) %s\n",
                    r.scene.c_str(), r.clip.substr(0, 18).c_str(), self, verdict(self <= 5));
      out << buf;
      continue;
    }
    const double bul_med = Ratio(r.bullet_us.median, r.ours_us.median);
    const double fcl_med = Ratio(r.fcl_us.median, r.ours_us.median);
    const double bul_p99 = Ratio(r.bullet_us.p99, r.ours_us.p99);
    std::snprintf(buf, sizeof(buf),
                  "target %-22s %-18s  median<=Bullet (x%.2f) %s;  median 5x FCL (x%.2f) %s;  "
                  "p99 10x Bullet (x%.2f) %s;  p99<=5x median (x%.2f) %s\n",
                  r.scene.c_str(), r.clip.substr(0, 18).c_str(), bul_med, verdict(bul_med >= 1),
                  fcl_med, verdict(fcl_med >= 5), bul_p99, verdict(bul_p99 >= 10), self,
                  verdict(self <= 5));
    out << buf;
  }
  std::snprintf(buf, sizeof(buf), "targets met: %d of %d\n", met, total);
  out << buf;
  return out.str();
}

// FCL's continuous query beside ours on the same pairs (--fcl-ccd).
std::string FclCcdTable(const std::vector<Row>& rows) {
  std::ostringstream out;
  char buf[256];
  std::snprintf(buf, sizeof(buf),
                "\nFCL continuousCollide (linear motion, naive solver, %d steps) per link, "
                "same pairs:\n%-22s %-18s %5s %9s %9s %9s %9s %9s %6s\n",
                FclPeer::kFclCcdSteps, "scene", "clip", "pairs", "ours_med", "fccd_med", "ours_p99",
                "fccd_p99", "fccd/ours", "fmiss");
  out << buf;
  for (const Row& r : rows) {
    std::snprintf(buf, sizeof(buf), "%-22s %-18s %5d %9.1f %9.1f %9.1f %9.1f %9.2f %6d\n",
                  r.scene.c_str(), r.clip.substr(0, 18).c_str(), r.pairs, r.ours_us.median,
                  r.fcl_ccd_us.median, r.ours_us.p99, r.fcl_ccd_us.p99,
                  Ratio(r.fcl_ccd_us.median, r.ours_us.median), r.fcl_ccd_misses);
    out << buf;
  }
  return out.str();
}

std::string FormatTable(const std::vector<Row>& rows, bool markdown) {
  std::ostringstream out;
  char buf[512];
  const char* sep = markdown ? " | " : "  ";
  if (markdown) {
    out << "| scene | triangles | clip | pairs | contact | undecided | median us | p99 us | max us"
           " | BVH build s | bytes/tri | FCL median us | FCL p99 us | ratio FCL/ours (median)"
           " | FCL missed contacts | FCL build s | GPU median us | GPU p99 us | GPU max us"
           " | ratio CPU/GPU (median) | GPU answers differing | Bullet median us | Bullet p99 us"
           " | ratio Bullet/ours (median) | ratio Bullet/ours (p99) | ours p99/median"
           " | Bullet missed contacts | Bullet build s |\n";
    out << "|---|---:|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|"
           "---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|\n";
  } else {
    std::snprintf(buf, sizeof(buf),
                  "%-22s %9s %-18s %5s %7s %5s %9s %9s %9s %8s %9s %9s %9s %7s %6s %8s %9s %9s "
                  "%9s %7s %6s %9s %9s %8s %8s %8s %6s %8s\n",
                  "scene", "tris", "clip", "pairs", "contact", "undec", "median_us", "p99_us",
                  "max_us", "build_s", "B/tri", "fcl_med", "fcl_p99", "ratio", "missed", "fcl_bld",
                  "gpu_med", "gpu_p99", "gpu_max", "cpu/gpu", "differ", "bul_med", "bul_p99",
                  "bul/ours", "b/o_p99", "p99/med", "bmiss", "bul_bld");
    out << buf;
  }
  for (const Row& r : rows) {
    if (markdown) {
      std::snprintf(buf, sizeof(buf),
                    "| %s | %zu | %s | %d | %d | %d | %.1f | %.1f | %.1f | %.3f | %.1f | %.1f | "
                    "%.1f | %.2f | %d | %.3f | %.1f | %.1f | %.1f | %.2f | %d | %.1f | %.1f | %.2f"
                    " | %.2f | %.2f | %d | %.3f |\n",
                    r.scene.c_str(), r.triangles, r.clip.c_str(), r.pairs, r.contacts, r.undecided,
                    r.ours_us.median, r.ours_us.p99, r.ours_us.max, r.build_s, r.bytes_per_tri,
                    r.fcl_us.median, r.fcl_us.p99,
                    r.ours_us.median > 0 ? r.fcl_us.median / r.ours_us.median : 0.0, r.fcl_misses,
                    r.fcl_build_s, r.gpu_us.median, r.gpu_us.p99, r.gpu_us.max,
                    r.gpu_us.median > 0 ? r.ours_us.median / r.gpu_us.median : 0.0,
                    r.gpu_mismatches, r.bullet_us.median, r.bullet_us.p99,
                    Ratio(r.bullet_us.median, r.ours_us.median),
                    Ratio(r.bullet_us.p99, r.ours_us.p99), Ratio(r.ours_us.p99, r.ours_us.median),
                    r.bullet_misses, r.bullet_build_s);
    } else {
      std::snprintf(buf, sizeof(buf),
                    "%-22s %9zu %-18s %5d %7d %5d %9.1f %9.1f %9.1f %8.3f %9.1f %9.1f %9.1f %7.2f "
                    "%6d %8.3f %9.1f %9.1f %9.1f %7.2f %6d %9.1f %9.1f %8.2f %8.2f %8.2f %6d "
                    "%8.3f\n",
                    r.scene.c_str(), r.triangles, r.clip.substr(0, 18).c_str(), r.pairs, r.contacts,
                    r.undecided, r.ours_us.median, r.ours_us.p99, r.ours_us.max, r.build_s,
                    r.bytes_per_tri, r.fcl_us.median, r.fcl_us.p99,
                    r.ours_us.median > 0 ? r.fcl_us.median / r.ours_us.median : 0.0, r.fcl_misses,
                    r.fcl_build_s, r.gpu_us.median, r.gpu_us.p99, r.gpu_us.max,
                    r.gpu_us.median > 0 ? r.ours_us.median / r.gpu_us.median : 0.0,
                    r.gpu_mismatches, r.bullet_us.median, r.bullet_us.p99,
                    Ratio(r.bullet_us.median, r.ours_us.median),
                    Ratio(r.bullet_us.p99, r.ours_us.p99), Ratio(r.ours_us.p99, r.ours_us.median),
                    r.bullet_misses, r.bullet_build_s);
    }
    out << buf;
  }
  (void)sep;
  return out.str();
}

}  // namespace

namespace {

// A clip of `scene`, resampled to `rate_hz` by frame skipping and stood on
// the scene's floor.
MocapClip LoadClip(const std::string& dir, const std::string& clip_name, const SceneSpec& scene,
                   double rate_hz) {
  MocapImportOptions mo;
  mo.up_axis = scene.up;
  MocapClip clip = ImportBvhFile(DataFile(dir + "/mocap/" + clip_name), mo);
  const int step = std::max(1, static_cast<int>(std::lround(1.0 / (clip.frame_time_s * rate_hz))));
  std::vector<Pose> poses;
  for (size_t f = 0; f < clip.poses.size(); f += step) poses.push_back(clip.poses[f]);
  clip.poses = poses;
  bench::PlaceClipOnFloor(&clip, scene.up, scene.floor, scene.centre);
  return clip;
}

QueryOptions BenchQueryOptions(const BenchCommandOptions& options) {
  QueryOptions q;
  q.eps_s = options.eps_s;
  q.delta_m = options.delta_m;
  q.motion = *ParseMotionModel(options.motion);
  q.per_link = options.per_link;
  return q;
}

}  // namespace

int RunBenchCommand(const BenchCommandOptions& options) {
  try {
    g_thread_clock = options.clock == "thread";
    const std::string dir = options.data_dir.empty() ? SWEPTCCD_DATA_DIR : options.data_dir;
    // Placements chosen by looking at the scenes: the floor heights are the
    // large flat areas; the walk is centred on the furnished part.
    const std::vector<SceneSpec> scenes = {
        {"morse_apartment", {{"morse_apartment.ply"}}, 'z', 0.0, {1.0, 1.0}},
        {"grey_white_room", {{"bitterli_grey_white_room.ply"}}, 'y', 0.0, {2.3, -1.5}},
        {"breakfast_room", {{"bitterli_breakfast_room.ply"}}, 'y', -1.42, {-0.67, -1.9}},
        {"breakfast+dragon_1.1M",
         {{"bitterli_breakfast_room.ply"},
          {"stanford_dragon_vrip.ply", 10.0, Eigen::Vector3d(-0.67, -1.42 - 0.527, -1.9)}},
         'y',
         -1.42,
         {-0.67, -1.9}},
        {"breakfast+dragons_10M", DragonRing(), 'y', -1.42, {-0.67, -1.9}, true},
    };
    // The GPU backend beside the CPU one, same pairs, same run.
    std::unique_ptr<gpu::Backend> gpu_backend;
    if (options.gpu != "off" && options.write_scene.empty()) {
      gpu::BackendOptions bo;
      bo.backend = gpu::BackendKind::kGpu;
      bo.device_index = options.gpu_device;
      bo.require_hardware = options.gpu == "hardware";
      gpu_backend = std::make_unique<gpu::Backend>(bo);
      std::fprintf(stderr, "backend %s\n", gpu_backend->reason().c_str());
      if (!gpu_backend->gpu()) gpu_backend.reset();
    }
    std::vector<Row> rows;
    std::vector<bench::SweepRow> sweep_rows;
    for (const std::string& name : options.scenes) {
      if (std::none_of(scenes.begin(), scenes.end(),
                       [&](const SceneSpec& s) { return s.name == name; })) {
        throw InputError("sweptccd bench: no scene '" + EscapeForDisplay(name) + "'");
      }
    }
    if (!options.write_scene.empty() && options.scenes.size() != 1) {
      throw InputError("sweptccd bench: --write-scene needs exactly one --scene");
    }
    // The sweep's table is printed scene by scene as each ends (flushed), so
    // a run cut short (gpu_bundle.sh's timeouts) keeps the scenes done.
    if (options.sweep && options.write_scene.empty()) {
      std::printf(
          "SweptCCD bench --sweep: %g Hz, eps %g s, delta %g m, motion %s%s; batches of pairs, "
          "each answered by the CPU backend on 1 thread, the CPU backend on %d threads and the "
          "GPU backend on %d threads (%s), in turn, batch by batch (wall clock); pairs/s = the "
          "batches' pairs over their summed wall time; the pairs cycle to fill at least 3 "
          "batches; differ: pairs whose answer differs between the methods (must be 0); "
          "dispatches: the GPU's, shared by the workers' requests; gpu descent: the batch's "
          "free intervals cleared on the GPU first (capsules = intervals tested there, "
          "requests = batches), then the CPU on the same threads\n\n",
          options.rate_hz, options.eps_s, options.delta_m, options.motion.c_str(),
          options.per_link ? ", per-link" : "", options.threads, options.threads,
          gpu_backend ? gpu_backend->context()->info().Summary().c_str() : "not run");
    }
    for (const SceneSpec& scene : scenes) {
      const bool named = std::find(options.scenes.begin(), options.scenes.end(), scene.name) !=
                         options.scenes.end();
      if (options.scenes.empty() ? scene.opt_in : !named) continue;
      const auto l0 = Clock::now();
      std::vector<TriangleMesh> meshes;
      {
        std::map<std::string, TriangleMesh> cache;
        for (const MeshPlacement& m : scene.meshes)
          meshes.push_back(PlacedMesh(dir, m, options.mesh, &cache));
      }
      const double load_s = Seconds(l0, Clock::now());
      if (!options.write_scene.empty()) {  // The placed meshes as one file, for the daemon.
        TriangleMesh all;
        for (const TriangleMesh& m : meshes) {
          const auto base = static_cast<uint32_t>(all.vertices.size());
          all.vertices.insert(all.vertices.end(), m.vertices.begin(), m.vertices.end());
          for (uint32_t i : m.indices) all.indices.push_back(base + i);
        }
        WriteBinaryPly(all, options.write_scene);
        std::printf("%s: %zu triangles written to %s\n", scene.name.c_str(), all.num_triangles(),
                    EscapeForDisplay(options.write_scene).c_str());
        return 0;
      }
      const long rss0 = ResidentKiB();
      const auto t0 = Clock::now();
      Environment env;
      for (size_t k = 0; k < meshes.size(); ++k) env.AddMesh(meshes[k], scene.meshes[k].file);
      const double build_s = Seconds(t0, Clock::now());
      const long rss1 = ResidentKiB();
      std::fprintf(stderr,
                   "%s: %zu triangles, meshes read and placed in %.2f s, BVH built in %.2f s, "
                   "%.0f MiB resident (%.1f bytes/triangle for the environment)\n",
                   scene.name.c_str(), env.num_triangles(), load_s, build_s, rss1 / 1024.0,
                   1024.0 * (rss1 - rss0) / env.num_triangles());
      if (options.sweep) {  // Batches instead of the per-pair table (bench_sweep.h).
        std::vector<MocapClip> clips;
        std::vector<bench::SweepClip> sweep_clips;
        for (const std::string& clip_name : options.clips) {
          clips.push_back(LoadClip(dir, clip_name, scene, options.rate_hz));
        }
        for (const MocapClip& clip : clips) {
          sweep_clips.push_back(
              {&clip.skeleton, &clip.poses,
               std::min<int>(options.max_pairs, static_cast<int>(clip.poses.size()) - 1)});
        }
        bench::SweepOptions so;
        so.batch_sizes = options.sweep_sizes;
        so.threads = options.threads;
        so.query = BenchQueryOptions(options);
        const std::vector<bench::SweepRow> rows =
            bench::RunSweep(scene.name, env, sweep_clips, so, gpu_backend.get());
        std::string part = bench::FormatSweep(rows, true);
        if (!sweep_rows.empty()) {  // The header once, then rows only.
          for (int line = 0; line < 2; ++line) part.erase(0, part.find('\n') + 1);
        }
        std::fputs(part.c_str(), stdout);
        std::fflush(stdout);
        sweep_rows.insert(sweep_rows.end(), rows.begin(), rows.end());
        std::fprintf(stderr, "%s: sweep done\n", scene.name.c_str());
        continue;
      }
      std::unique_ptr<FclPeer> fcl;
      std::unique_ptr<BulletPeer> bullet;
      if (options.peers) {
        fcl = std::make_unique<FclPeer>(meshes);
        bullet = std::make_unique<BulletPeer>(meshes);
      }
      Row all_row;
      std::vector<double> all_ours, all_theirs, all_gpu, all_bullet, all_fcl_ccd;
      const bool fcl_ccd = fcl && options.fcl_ccd;
      for (const std::string& clip_name : options.clips) {
        MocapClip clip = LoadClip(dir, clip_name, scene, options.rate_hz);
        const CcdEngine engine(clip.skeleton, env);
        CcdEngine gpu_engine(clip.skeleton, env);
        if (gpu_backend) gpu_backend->Attach(&gpu_engine);
        const bool with_gpu = gpu_engine.culler() != nullptr;
        const QueryOptions q = BenchQueryOptions(options);
        Row row;
        row.scene = scene.name;
        row.clip = clip_name;
        row.triangles = env.num_triangles();
        row.build_s = build_s;
        row.bytes_per_tri = static_cast<double>(env.memory_bytes()) / env.num_triangles();
        row.rss_per_tri = 1024.0 * (rss1 - rss0) / env.num_triangles();
        std::vector<double> ours, theirs, gpu_times, bullet_times, fcl_ccd_times;
        if (with_gpu) row.gpu_mismatches = 0;
        const int n = std::min<int>(options.max_pairs, static_cast<int>(clip.poses.size()) - 1);
        // Warm-up, untimed and alike for every method: the same first pairs
        // through ours, the GPU backend, FCL and Bullet (caches, lazy set-up).
        // Every pair is then timed; none is dropped from a percentile.
        for (int k = 0; k < std::min(n, options.warmup_pairs); ++k) {
          const Pose& p0 = clip.poses[k];
          const Pose& p1 = clip.poses[k + 1];
          (void)engine.Query(p0, p1, q);
          if (with_gpu) (void)gpu_engine.Query(p0, p1, q);
          if (fcl) (void)fcl->Collide(clip.skeleton, p1);
          if (bullet) (void)bullet->Sweep(clip.skeleton, p0, p1);
          if (fcl_ccd) (void)fcl->Sweep(clip.skeleton, p0, p1);
        }
        for (int k = 0; k < n; ++k) {
          const Pose& p0 = clip.poses[k];
          const Pose& p1 = clip.poses[k + 1];
          const double a = NowS();
          const QueryResult r = engine.Query(p0, p1, q);
          const double b = NowS();
          ours.push_back(1e6 * (b - a));
          ++row.pairs;
          row.contacts += r.contact;
          row.undecided += r.undecided;
          if (with_gpu) {
            const double c = NowS();
            const QueryResult g = gpu_engine.Query(p0, p1, q);
            gpu_times.push_back(1e6 * (NowS() - c));
            row.gpu_mismatches += g.contact != r.contact || g.s_lo != r.s_lo || g.s_hi != r.s_hi;
          }
          if (fcl) {
            const double c = NowS();
            const bool hit = fcl->Collide(clip.skeleton, p1);
            theirs.push_back(1e6 * (NowS() - c));
            if (r.contact && !hit) ++row.fcl_misses;
          }
          if (bullet) {
            const double c = NowS();
            const bool hit = bullet->Sweep(clip.skeleton, p0, p1);
            bullet_times.push_back(1e6 * (NowS() - c));
            if (r.contact && !hit) ++row.bullet_misses;
          }
          if (fcl_ccd) {
            const double c = NowS();
            const bool hit = fcl->Sweep(clip.skeleton, p0, p1);
            fcl_ccd_times.push_back(1e6 * (NowS() - c));
            if (r.contact && !hit) ++row.fcl_ccd_misses;
          }
        }
        all_ours.insert(all_ours.end(), ours.begin(), ours.end());
        all_theirs.insert(all_theirs.end(), theirs.begin(), theirs.end());
        all_gpu.insert(all_gpu.end(), gpu_times.begin(), gpu_times.end());
        all_bullet.insert(all_bullet.end(), bullet_times.begin(), bullet_times.end());
        all_fcl_ccd.insert(all_fcl_ccd.end(), fcl_ccd_times.begin(), fcl_ccd_times.end());
        row.fcl_ccd_us = Summarise(fcl_ccd_times);
        all_row.fcl_ccd_misses += row.fcl_ccd_misses;
        row.bullet_us = Summarise(bullet_times);
        row.bullet_build_s = bullet ? bullet->build_s() : 0;
        all_row.bullet_misses += row.bullet_misses;
        if (with_gpu)
          all_row.gpu_mismatches = std::max(0, all_row.gpu_mismatches) + row.gpu_mismatches;
        row.gpu_us = Summarise(gpu_times);
        all_row.pairs += row.pairs;
        all_row.contacts += row.contacts;
        all_row.undecided += row.undecided;
        all_row.fcl_misses += row.fcl_misses;
        row.ours_us = Summarise(ours);
        row.fcl_us = Summarise(theirs);
        row.fcl_build_s = fcl ? fcl->build_s() : 0;
        rows.push_back(row);
        std::fprintf(stderr, "%s / %s: %d pairs, median %.1f us\n", scene.name.c_str(),
                     clip_name.c_str(), row.pairs, row.ours_us.median);
        all_row.scene = row.scene;
        all_row.triangles = row.triangles;
        all_row.build_s = row.build_s;
        all_row.bytes_per_tri = row.bytes_per_tri;
        all_row.fcl_build_s = row.fcl_build_s;
        all_row.bullet_build_s = row.bullet_build_s;
      }
      all_row.clip = "ALL CLIPS";
      all_row.ours_us = Summarise(all_ours);
      all_row.fcl_us = Summarise(all_theirs);
      all_row.gpu_us = Summarise(all_gpu);
      all_row.bullet_us = Summarise(all_bullet);
      all_row.fcl_ccd_us = Summarise(all_fcl_ccd);
      rows.push_back(all_row);
    }
    if (options.sweep) {
      const std::string table = bench::FormatSweep(sweep_rows, true);
      if (!options.markdown_path.empty()) {
        std::ofstream md(options.markdown_path);
        md << table;
        if (!md) throw InputError(options.markdown_path + ": cannot write the Markdown table");
      }
      return 0;
    }
    std::printf(
        "SweptCCD bench: %g Hz, eps %g s, delta %g m, motion %s%s, %d warm-up pairs, "
        "single thread, %s\n",
        options.rate_hz, options.eps_s, options.delta_m, options.motion.c_str(),
        options.per_link ? ", per-link" : "", options.warmup_pairs,
        g_thread_clock ? "times: thread CPU time (CLOCK_THREAD_CPUTIME_ID)"
                       : "times: wall clock (steady_clock)");
    std::printf(
        "ours: CPU backend; gpu_*: GPU backend on the same pairs (%s), times include "
        "upload and read-back; differ: pairs whose GPU answer or bracket differs (must be "
        "0)\n",
        gpu_backend ? gpu_backend->context()->info().Summary().c_str() : "not run");
    std::printf(
        "ours: certified CCD per pair; FCL: discrete capsule-vs-OBBRSS collide at the "
        "second pose only (no sweep)\n");
    std::printf(
        "Bullet: btCollisionWorld::convexSweepTest of one btCapsuleShape per link from "
        "its pose at time 0 to time 1 against btBvhTriangleMeshShape (built once, untimed); "
        "linear/rigid sweep, not certified; bmiss: pairs we certify as contact and Bullet "
        "sees none\n\n");
    std::fputs(FormatTable(rows, false).c_str(), stdout);
    std::fputs("\n", stdout);
    std::fputs(TargetLines(rows, options.peers).c_str(), stdout);
    const std::string fcl_ccd_table = options.peers && options.fcl_ccd ? FclCcdTable(rows) : "";
    std::fputs(fcl_ccd_table.c_str(), stdout);
    if (!options.markdown_path.empty()) {
      std::ofstream md(options.markdown_path);
      md << FormatTable(rows, true) << "\n```\n"
         << TargetLines(rows, options.peers) << fcl_ccd_table << "```\n";
      if (!md) throw InputError(options.markdown_path + ": cannot write the Markdown table");
    }
    return 0;
  } catch (const InputError& e) {
    std::fprintf(stderr, "error: %s\n", DisplayError(e.what()).c_str());
    return 2;
  }
}

}  // namespace sweptccd
