#include "tools/world_bench_hands.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <memory>
#include <nlohmann/json.hpp>
#include <random>
#include <string>
#include <tuple>
#include <utility>
#include <vector>

#include "core/avatar/joint_frame.h"
#include "core/avatar/joint_set.h"
#include "core/avatar/pose.h"
#include "core/avatar/skeleton.h"
#include "core/errors.h"
#include "core/world/world_query.h"
#include "mocap/full_body_frames.h"
#include "tools/bench_common.h"
#include "tools/world_bench_command.h"
#include "tools/world_bench_scene.h"

namespace sweptccd {
namespace {

namespace fs = std::filesystem;
using Eigen::Vector3d;
using ojson = nlohmann::ordered_json;

// One avatar's grasp: which hand, when (seconds from its first sample), the
// box's half extents and where its centre sits in the hand frame (along
// fwd, lat, normal: in front of the knuckles, on the palm's side).
struct Grasp {
  bool left = false;
  double t_grasp_s = 0, t_release_s = 0;
  Vector3d half, grip;
};

// The grasping hand's curl: open while reaching, closing over the 0.25 s
// before the grasp, closed while carrying, opening over 0.25 s after the
// release.
double GraspCurl(double t_s, const Grasp& g) {
  if (t_s < g.t_release_s) return full_body::SmoothStep((t_s - (g.t_grasp_s - 0.25)) / 0.25);
  return 1 - full_body::SmoothStep((t_s - g.t_release_s) / 0.25);
}

Grasp DrawGrasp(std::mt19937_64& rng, int k, double seconds) {
  auto u = [&](double lo, double hi) {
    return std::uniform_real_distribution<double>(lo, hi)(rng);
  };
  Grasp g;
  g.left = k % 2 == 1;
  g.t_grasp_s = u(0.3, 0.45) * seconds;
  g.t_release_s = g.t_grasp_s + u(0.3, 0.4) * seconds;
  // A block 3.6-5.2 cm along the fingers, 6-9 cm across them, 3-4.4 cm
  // deep, its top 6-12 mm below the open fingers' line.
  g.half = Vector3d(u(0.018, 0.026), u(0.03, 0.045), u(0.015, 0.022));
  g.grip = Vector3d(u(0.09, 0.1), u(-0.005, 0.005), -(g.half.z() + u(0.006, 0.012)));
  return g;
}

struct Written {
  std::string world16, world81;
  int refused = 0;  // 81-link frames the adapter refused (written as invalid lines).
};

Written Generate(const WorldBenchOptions& o, const std::string& data) {
  const fs::path out(o.out_dir);
  fs::create_directories(out);
  const int cols = static_cast<int>(std::ceil(std::sqrt(static_cast<double>(o.avatars))));
  const int rows = (o.avatars + cols - 1) / cols;
  const JointSet& meta = FindJointSet("meta-full-body");
  std::mt19937_64 rng(o.seed);
  ojson w16, w81;
  for (ojson* w : {&w16, &w81}) {
    (*w)["avatars"] = ojson::array();
    (*w)["objects"] = ojson::array();
    (*w)["env"] = {fs::absolute(bench::DataFile(data + "/env/" + world_bench::kRoom)).string()};
  }
  Written written;
  for (int k = 0; k < o.avatars; ++k) {
    const MocapClip clip = world_bench::GridAvatarClip(data, k, cols, rows, o.spacing, o.seconds);
    const Grasp g = DrawGrasp(rng, k, o.seconds);
    const full_body::FrameBuilder fb(meta, clip.skeleton);
    const int64_t u0 = clip.poses.front().utime;
    const auto t_of = [&](const Pose& p) { return 1e-6 * static_cast<double>(p.utime - u0); };
    // The object: at the grasping hand's grip from the grasp to the
    // release, resting at the grasp's grip before and at the release's after.
    const int n = static_cast<int>(clip.poses.size());
    int kg = 0, kr = n - 1;
    while (kg < n - 1 && t_of(clip.poses[kg]) < g.t_grasp_s) ++kg;
    while (kr > kg && t_of(clip.poses[kr - 1]) >= g.t_release_s) --kr;
    std::string object_lines;
    for (int i = 0; i < n; ++i) {
      const full_body::HandFrame h = fb.Hand(clip.poses[std::clamp(i, kg, kr)], g.left);
      const Eigen::Quaterniond basis = h.Basis();
      object_lines +=
          world_bench::ObjectPoseLine(clip.poses[i].utime, h.wrist + basis * g.grip, basis);
    }
    // The 81-link avatar: its frames, the skeleton calibrated on the first.
    const auto frame = [&](const Pose& p) {
      const double t = t_of(p);
      const double cycle = full_body::CycleCurl(t + (g.left ? 0.0 : 1.5));
      return fb.Build(p, g.left ? GraspCurl(t, g) : cycle, g.left ? cycle : GraspCurl(t, g));
    };
    const JointSkeleton js = full_body::CalibratedFullBody(meta, frame(clip.poses[0]));
    std::string lines16, lines81;
    for (const Pose& p : clip.poses) {
      lines16 += PoseToJsonLine(p) + '\n';
      Pose full;
      const std::string why = js.Convert(frame(p), &full);
      if (why.empty()) {
        lines81 += PoseToJsonLine(full) + '\n';
      } else {
        // A pose line SPEC 2 reads as invalid, as `sweptccd skeleton --joints` writes.
        lines81 += ojson({{"invalid", why}, {"utime", p.utime}}).dump() + '\n';
        ++written.refused;
      }
    }
    const std::string id = "avatar" + std::to_string(k), obj = "object" + std::to_string(k);
    world_bench::WriteText(out / (id + "_16.json"), SkeletonToJson(clip.skeleton) + '\n');
    world_bench::WriteText(out / (id + "_16.jsonl"), lines16);
    world_bench::WriteText(out / (id + "_81.json"), SkeletonToJson(js.skeleton()) + '\n');
    world_bench::WriteText(out / (id + "_81.jsonl"), lines81);
    world_bench::WriteText(out / (obj + ".obj"), world_bench::BoxObj(g.half));
    world_bench::WriteText(out / (obj + ".jsonl"), object_lines);
    for (const char* links : {"16", "81"}) {
      ojson& w = links[0] == '1' ? w16 : w81;
      w["avatars"].push_back({{"id", id},
                              {"skeleton", id + "_" + links + ".json"},
                              {"poses", id + "_" + links + ".jsonl"}});
    }
    for (ojson* w : {&w16, &w81}) {
      (*w)["objects"].push_back({{"id", obj}, {"mesh", obj + ".obj"}, {"poses", obj + ".jsonl"}});
    }
  }
  written.world16 = (out / "world16.json").string();
  written.world81 = (out / "world81.json").string();
  world_bench::WriteText(written.world16, w16.dump(1) + '\n');
  world_bench::WriteText(written.world81, w81.dump(1) + '\n');
  return written;
}

// One world under the bench: its answerer, its records in the order a live
// room completes them, the times and what the answers found.
struct Side {
  explicit Side(const std::string& path)
      : loaded(world::LoadWorldFile(path)),
        answerer(std::make_unique<world::WorldAnswerer>(loaded, QueryOptions())) {
    for (int a = 0; a < num_avatars(); ++a) {
      for (size_t r = 0; r < loaded.world.avatars[a].records.size(); ++r) {
        const PairOutcome& rec = loaded.world.avatars[a].records[r];
        if (rec.valid) order.emplace_back(rec.pose1.utime, a, r);
      }
    }
    std::sort(order.begin(), order.end());
  }
  int num_avatars() const { return static_cast<int>(loaded.world.avatars.size()); }
  int num_objects() const { return static_cast<int>(loaded.world.objects.size()); }

  world::LoadedWorld loaded;
  std::unique_ptr<world::WorldAnswerer> answerer;
  std::vector<std::tuple<int64_t, int, size_t>> order;
  std::vector<double> env_us, own_us, whole_us;
  int64_t own_entries = 0, own_contacts = 0, own_initially = 0, own_undecided = 0;
  int64_t other_object_contacts = 0, avatar_contacts = 0, entries = 0, culled = 0;
  int64_t env_contacts = 0;

  // Answers avatar a's record r: the environment, a's own object (object a),
  // then every other entity; times each part, tallies when `count`.
  void Answer(int a, size_t r, bool count) {
    const world::AvatarIndex ia(a);
    const double t0 = bench::ThreadCpuSeconds();
    const QueryResult env = answerer->AnswerEnvironment(ia, r);
    const double t1 = bench::ThreadCpuSeconds();
    const auto own = answerer->AnswerObject(ia, r, world::TrackedObjectIndex(a));
    const double t2 = bench::ThreadCpuSeconds();
    std::vector<std::pair<int, world::OtherAnswer>> others;
    for (int e = 0; e < num_avatars() + num_objects(); ++e) {
      if (e == a || e == num_avatars() + a) continue;
      std::optional<world::WorldAnswerer::Entry> x =
          e < num_avatars()
              ? answerer->AnswerAvatar(ia, r, world::AvatarIndex(e))
              : answerer->AnswerObject(ia, r, world::TrackedObjectIndex(e - num_avatars()));
      if (x) others.emplace_back(e, std::move(x->answer));
    }
    const double t3 = bench::ThreadCpuSeconds();
    if (!count) return;
    env_us.push_back(1e6 * (t1 - t0));
    own_us.push_back(1e6 * (t2 - t1));
    whole_us.push_back(1e6 * (t3 - t0));
    env_contacts += env.contact;
    if (own) {
      ++own_entries;
      ++entries;
      culled += own->answer.culled_by_box;
      own_contacts += own->answer.contact;
      own_initially += own->answer.contact && own->answer.bracket.initially_colliding;
      own_undecided += own->answer.contact && own->answer.bracket.undecided;
    }
    for (const auto& [e, ans] : others) {
      ++entries;
      culled += ans.culled_by_box;
      if (!ans.contact) continue;
      ++(e < num_avatars() ? avatar_contacts : other_object_contacts);
    }
  }
};

void PrintRow(int links, const char* what, const std::vector<double>& us) {
  const bench::Stats s = bench::Summarise(us);
  std::printf("| %d | %s | %zu | %.1f | %.1f | %.1f |\n", links, what, us.size(), s.median, s.p99,
              s.max);
}

void Bench(const WorldBenchOptions& o, const Written& written) {
  Side side16(written.world16), side81(written.world81);
  Side* sides[2] = {&side16, &side81};
  // Warm-up, untimed: the first valid records of each avatar, both worlds.
  for (Side* s : sides) {
    for (int a = 0; a < s->num_avatars(); ++a) {
      int done = 0;
      for (size_t r = 0; r < s->loaded.world.avatars[a].records.size() && done < o.warmup; ++r) {
        if (!s->loaded.world.avatars[a].records[r].valid) continue;
        s->Answer(a, r, false);
        ++done;
      }
    }
  }
  // Every valid record of both worlds, the two alternating record by
  // record, each going first every other record.
  const size_t n = std::max(side16.order.size(), side81.order.size());
  for (size_t i = 0; i < n; ++i) {
    for (int turn = 0; turn < 2; ++turn) {
      Side& s = *sides[(turn + i) % 2];
      if (i >= s.order.size()) continue;
      s.Answer(std::get<1>(s.order[i]), std::get<2>(s.order[i]), true);
    }
  }
  std::printf(
      "hands scenario: %d avatars (90/72/60 Hz), each reaching for, grasping, carrying and "
      "releasing its own box; 16-link CMU avatars (%s) beside 81-link meta-full-body avatars "
      "(%s, fingers PROCEDURALLY ANIMATED, not captured; %d frames refused by the adapter), "
      "seed %llu\n",
      side16.num_avatars(), written.world16.c_str(), written.world81.c_str(), written.refused,
      static_cast<unsigned long long>(o.seed));
  std::printf(
      "times: thread CPU time (CLOCK_THREAD_CPUTIME_ID), 1 thread, CPU backend; the first %d "
      "valid records of each avatar answered once untimed first; every valid record timed, none "
      "dropped, in the order a live room completes them, the two worlds alternating record by "
      "record\n\n",
      o.warmup);
  std::printf(
      "| links | answer | records | median us | p99 us | max us |\n|---|---|---|---|---|---|\n");
  for (Side* s : sides) {
    const int links = s == &side16 ? 16 : 81;
    PrintRow(links, "env-only", s->env_us);
    PrintRow(links, "own object (reach, grasp, carry, release)", s->own_us);
    PrintRow(links, "whole record", s->whole_us);
  }
  std::printf("\n");
  for (Side* s : sides) {
    std::printf(
        "links %d: own-object entries %lld: contact %lld (initially colliding %lld, undecided "
        "%lld); other objects: contact %lld; avatars: contact %lld; entity entries %lld (cleared "
        "by the broad phase %lld); environment contacts %lld\n",
        s == &side16 ? 16 : 81, static_cast<long long>(s->own_entries),
        static_cast<long long>(s->own_contacts), static_cast<long long>(s->own_initially),
        static_cast<long long>(s->own_undecided), static_cast<long long>(s->other_object_contacts),
        static_cast<long long>(s->avatar_contacts), static_cast<long long>(s->entries),
        static_cast<long long>(s->culled), static_cast<long long>(s->env_contacts));
  }
}

}  // namespace

void RunHandsScenario(const WorldBenchOptions& o, const std::string& data_dir) {
  const Written written = Generate(o, data_dir);
  std::fprintf(stderr, "world-bench: wrote %s and %s\n", written.world16.c_str(),
               written.world81.c_str());
  if (!o.generate_only) Bench(o, written);
}

}  // namespace sweptccd
