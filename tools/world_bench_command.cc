#include "tools/world_bench_command.h"

#include <CLI/CLI.hpp>
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <memory>
#include <nlohmann/json.hpp>
#include <set>
#include <tuple>
#include <utility>
#include <vector>

#include "core/avatar/motion.h"
#include "core/avatar/pose.h"
#include "core/avatar/skeleton.h"
#include "core/errors.h"
#include "core/worker_pool.h"
#include "core/world/world_query.h"
#include "mocap/mocap_import.h"
#include "msgs/text.h"
#include "tools/bench_common.h"
#include "tools/world_bench_hands.h"
#include "tools/world_bench_scene.h"

namespace sweptccd {

void AddWorldBenchOptions(CLI::App* app, WorldBenchOptions* o) {
  app->add_option("--out", o->out_dir, "Folder for the world file and what it names")->required();
  app->add_option("--data", o->data_dir,
                  "Folder with env/ and mocap/ (default: the project's data/, " SWEPTCCD_DATA_DIR
                  ")");
  app->add_option("--avatars", o->avatars, "Avatars (default 16)");
  app->add_option("--objects", o->objects,
                  "Tracked objects: the last thrown, the others held "
                  "(default 4)");
  app->add_option("--seconds", o->seconds, "Clip length per avatar (default 3)");
  app->add_option("--spacing", o->spacing, "Metres between grid neighbours (default 0.8)");
  app->add_option("--warmup", o->warmup, "Records per avatar answered untimed first (default 10)");
  app->add_flag("--generate-only", o->generate_only, "Write the world, do not time it");
  app->add_option("--threads", o->threads,
                  "Workers answering the records (default 1: the per-record times of one "
                  "thread; the tallies are the same for any number)")
      ->check(CLI::Range(1, 1024));
  app->add_option("--scenario", o->scenario,
                  "grid (default: held and thrown boxes among the avatars) or hands (each avatar "
                  "reaches for, grasps and carries its own box; 81-link full-body avatars beside "
                  "16-link ones, same run)")
      ->check(CLI::IsMember({"grid", "hands"}));
  app->add_option("--seed", o->seed, "Seed of the hands scenario's grasps (default 31)");
}

namespace {

using ojson = nlohmann::ordered_json;
using world_bench::BoxObj;
using world_bench::kCentre;
using world_bench::kFloor;
using world_bench::kRoom;
using world_bench::kThrownRate;
using world_bench::kUtime0;
using world_bench::ObjectPoseLine;
using world_bench::WriteText;

struct GeneratedWorld {
  std::string path;
  std::vector<int> holder;  // Per object: the avatar holding it, -1 when thrown.
};

// Writes the world: avatars k = 0.. in a grid of `cols` columns, held
// objects (pose = the holder's hand pose x a fixed offset, at the holder's
// samples), the thrown one on a ballistic arc with spin over the diagonal.
GeneratedWorld Generate(const WorldBenchOptions& o, const std::string& data) {
  namespace fs = std::filesystem;
  const fs::path out(o.out_dir);
  fs::create_directories(out);
  const int cols = static_cast<int>(std::ceil(std::sqrt(static_cast<double>(o.avatars))));
  const int rows = (o.avatars + cols - 1) / cols;
  const int num_held = std::max(0, o.objects - 1);
  GeneratedWorld g;
  ojson world;
  world["avatars"] = ojson::array();
  world["objects"] = ojson::array();
  std::vector<Skeleton> skeletons;
  std::vector<std::vector<Pose>> streams;
  for (int k = 0; k < o.avatars; ++k) {
    MocapClip clip = world_bench::GridAvatarClip(data, k, cols, rows, o.spacing, o.seconds);
    const std::string id = "avatar" + std::to_string(k);
    std::string lines;
    for (const Pose& pose : clip.poses) lines += PoseToJsonLine(pose) + '\n';
    WriteText(out / (id + ".json"), SkeletonToJson(clip.skeleton) + '\n');
    WriteText(out / (id + ".jsonl"), lines);
    ojson a = {{"id", id}, {"skeleton", id + ".json"}, {"poses", id + ".jsonl"}};
    a["ignore"] = ojson::array();
    skeletons.push_back(clip.skeleton);
    streams.push_back(std::move(clip.poses));
    world["avatars"].push_back(a);
  }
  // Held objects: avatar (5 j + 2) mod n holds object j in its right hand
  // (left for odd j), at the far end of the hand link; the holder's hand
  // and forearm never count as touching it (the grip is not a contact).
  const std::vector<std::string>& names = MocapLinkNames();
  const auto link_index = [&](const std::string& name) {
    return static_cast<int>(std::find(names.begin(), names.end(), name) - names.begin());
  };
  for (int j = 0; j < num_held; ++j) {
    const int h = (5 * j + 2) % o.avatars;
    const std::string side = j % 2 ? "_l" : "_r";
    const int hand = link_index("hand" + side);
    const Eigen::Vector3d grip = skeletons[h].link(hand).b_L;
    std::string lines;
    for (const Pose& pose : streams[h]) {
      const LinkPose& X = pose.links[hand];
      lines += ObjectPoseLine(pose.utime, X.p + X.q * grip, X.q);
    }
    const std::string id = "held" + std::to_string(j);
    WriteText(out / (id + ".obj"), BoxObj(Eigen::Vector3d(0.04, 0.04, 0.06)));
    WriteText(out / (id + ".jsonl"), lines);
    world["objects"].push_back({{"id", id}, {"mesh", id + ".obj"}, {"poses", id + ".jsonl"}});
    for (const char* link : {"hand", "forearm"}) {
      world["avatars"][h]["ignore"].push_back({{"link", link + side}, {"entity", id}});
    }
    g.holder.push_back(h);
  }
  if (o.objects > num_held) {
    // Thrown from beyond one corner of the group to beyond the opposite one,
    // 1.1 m then 0.8 m above the floor, in 0.7 s from 30% of the clip,
    // spinning at 12 rad/s.
    const double reach = 0.5 * (cols - 1) * o.spacing + 0.4;
    const Eigen::Vector3d p0(kCentre.x() - reach, kFloor + 1.1, kCentre.y() - reach);
    const Eigen::Vector3d p1(kCentre.x() + reach, kFloor + 0.8, kCentre.y() + reach);
    const double flight_s = std::min(0.7, 0.6 * o.seconds), g_y = -9.81;
    const Eigen::Vector3d v = (p1 - p0) / flight_s - 0.5 * flight_s * Eigen::Vector3d(0, g_y, 0);
    const Eigen::Vector3d axis = Eigen::Vector3d(0.3, 1.0, 0.2).normalized();
    const int64_t start = kUtime0 + std::llround(0.3 * o.seconds * 1e6);
    std::string lines;
    for (int k = 0; k / kThrownRate <= flight_s; ++k) {
      const double t = k / kThrownRate;
      const Eigen::Vector3d p = p0 + t * v + 0.5 * t * t * Eigen::Vector3d(0, g_y, 0);
      const Eigen::Quaterniond q(Eigen::AngleAxisd(12.0 * t, axis));
      lines += ObjectPoseLine(start + std::llround(t * 1e6), p, q);
    }
    const std::string id = "thrown";
    WriteText(out / (id + ".obj"), BoxObj(Eigen::Vector3d(0.06, 0.06, 0.06)));
    WriteText(out / (id + ".jsonl"), lines);
    world["objects"].push_back({{"id", id}, {"mesh", id + ".obj"}, {"poses", id + ".jsonl"}});
    g.holder.push_back(-1);
  }
  world["env"] = {fs::absolute(bench::DataFile(data + "/env/" + kRoom)).string()};
  g.path = (out / "world.json").string();
  WriteText(g.path, world.dump(1) + '\n');
  return g;
}

// What the whole answers found (counted outside the timed part).
struct Tally {
  int64_t entries = 0, culled = 0, avatar_contacts = 0, held_contacts = 0, thrown_contacts = 0;
  int64_t records_with_contact = 0, env_contacts = 0;
  std::set<std::pair<int, int>> avatar_pairs;  // (min, max) with a shared contact.
};

void PrintLine(const char* name, size_t n, const bench::Stats& s) {
  std::printf("| %s | %zu | %.1f | %.1f | %.1f |\n", name, n, s.median, s.p99, s.max);
}

void PrintTarget(const char* what, double value, double target) {
  std::printf("%s: %.2f (target <= %g): %s\n", what, value, target,
              value <= target ? "met" : "missed");
}

// One timed record's outcome, kept by its position in the order so that the
// tallies are summed in that order whatever the number of workers.
struct RecordOutcome {
  double env_us = 0, whole_us = 0;
  bool env_contact = false, any = false, link_work = false;
  int64_t entries = 0, culled = 0, held = 0, thrown = 0;
  std::vector<int> avatar_contacts;  // The other avatars touched.
};

void Bench(const WorldBenchOptions& o, const GeneratedWorld& g) {
  const world::LoadedWorld w = world::LoadWorldFile(g.path);
  const int n_avatars = static_cast<int>(w.world.avatars.size());
  const int n_objects = static_cast<int>(w.world.objects.size());
  // One answerer per worker (an answerer keeps per-record state and is not
  // thread-safe), and its buffers: the other entities of avatar a's record,
  // (b, -1) avatars, (-1, o) objects.
  WorkerPool pool(o.threads);
  struct Worker {
    std::unique_ptr<world::WorldAnswerer> answerer;
    std::vector<world::OtherAnswer> answers;
    std::vector<char> answered;
  };
  std::vector<Worker> workers(pool.size());
  for (Worker& k : workers) {
    k.answerer = std::make_unique<world::WorldAnswerer>(w, QueryOptions());
    k.answers.resize(n_avatars + n_objects);
    k.answered.resize(n_avatars + n_objects);
  }
  const auto answer_all = [&](Worker& k, int a, size_t r) {
    const world::AvatarIndex ia(a);
    QueryResult env = k.answerer->AnswerEnvironment(ia, r);
    const double t_env = bench::ThreadCpuSeconds();
    for (int e = 0; e < n_avatars + n_objects; ++e) {
      if (e == a) {
        k.answered[e] = false;
        continue;
      }
      std::optional<world::WorldAnswerer::Entry> x =
          e < n_avatars ? k.answerer->AnswerAvatar(ia, r, world::AvatarIndex(e))
                        : k.answerer->AnswerObject(ia, r, world::TrackedObjectIndex(e - n_avatars));
      k.answered[e] = x.has_value();
      if (x) k.answers[e] = std::move(x->answer);
    }
    return std::make_pair(env.contact, t_env);
  };
  // Warm-up, untimed, on every worker's answerer alike.
  for (Worker& k : workers) {
    for (int a = 0; a < n_avatars; ++a) {
      int done = 0;
      for (size_t r = 0; r < w.world.avatars[a].records.size() && done < o.warmup; ++r) {
        if (!w.world.avatars[a].records[r].valid) continue;
        answer_all(k, a, r);
        ++done;
      }
    }
  }
  // Records in the order a live room completes them: by the utime of the
  // pair's second sample (then avatar), as the daemon receives them.
  std::vector<std::tuple<int64_t, int, size_t>> order;
  for (int a = 0; a < n_avatars; ++a) {
    for (size_t r = 0; r < w.world.avatars[a].records.size(); ++r) {
      const PairOutcome& rec = w.world.avatars[a].records[r];
      if (rec.valid) order.emplace_back(rec.pose1.utime, a, r);
    }
  }
  std::sort(order.begin(), order.end());
  std::vector<RecordOutcome> outcomes(order.size());
  // Runs of consecutive records go to one worker, which times each record
  // in its own thread's CPU time.
  constexpr size_t kRun = 8;
  const auto wall0 = std::chrono::steady_clock::now();
  pool.Run((order.size() + kRun - 1) / kRun, [&](size_t run, int worker) {
    Worker& k = workers[worker];
    for (size_t i = run * kRun; i < std::min(order.size(), (run + 1) * kRun); ++i) {
      const int a = std::get<1>(order[i]);
      const size_t r = std::get<2>(order[i]);
      RecordOutcome& out = outcomes[i];
      const double t0 = bench::ThreadCpuSeconds();
      const auto [env_contact, t_env] = answer_all(k, a, r);
      const double t1 = bench::ThreadCpuSeconds();
      out.env_us = 1e6 * (t_env - t0);
      out.whole_us = 1e6 * (t1 - t0);
      out.env_contact = env_contact;
      for (int e = 0; e < n_avatars + n_objects; ++e) {
        if (!k.answered[e]) continue;
        ++out.entries;
        out.culled += k.answers[e].culled_by_box;
        out.link_work = out.link_work || !k.answers[e].culled_by_box;
        if (!k.answers[e].contact) continue;
        out.any = true;
        if (e < n_avatars) {
          out.avatar_contacts.push_back(e);
        } else {
          ++(g.holder[e - n_avatars] >= 0 ? out.held : out.thrown);
        }
      }
    }
  });
  const double wall_s =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - wall0).count();
  std::vector<double> env_us, whole_us;
  // The whole answer's times by record kind: every other entity cleared by
  // the broad phase; link work but no shared contact; a shared contact.
  std::vector<double> by_kind[3], env_by_kind[3];
  Tally tally;
  for (size_t i = 0; i < order.size(); ++i) {
    const RecordOutcome& out = outcomes[i];
    const int a = std::get<1>(order[i]);
    env_us.push_back(out.env_us);
    whole_us.push_back(out.whole_us);
    tally.env_contacts += out.env_contact;
    tally.entries += out.entries;
    tally.culled += out.culled;
    tally.held_contacts += out.held;
    tally.thrown_contacts += out.thrown;
    for (int e : out.avatar_contacts) {
      ++tally.avatar_contacts;
      tally.avatar_pairs.insert({std::min(a, e), std::max(a, e)});
    }
    tally.records_with_contact += out.any;
    const int kind = out.any ? 2 : out.link_work ? 1 : 0;
    by_kind[kind].push_back(out.whole_us);
    env_by_kind[kind].push_back(out.env_us);
  }
  const bench::Stats env = bench::Summarise(env_us), whole = bench::Summarise(whole_us);
  const int64_t pairs = static_cast<int64_t>(n_avatars) * (n_avatars - 1) / 2;
  std::printf(
      "world %s: %d avatars (90/72/60 Hz), %d objects (%d held, %d thrown), %d static "
      "triangles\n",
      g.path.c_str(), n_avatars, n_objects,
      static_cast<int>(
          std::count_if(g.holder.begin(), g.holder.end(), [](int h) { return h >= 0; })),
      static_cast<int>(std::count(g.holder.begin(), g.holder.end(), -1)),
      static_cast<int>(w.env.num_triangles()));
  std::printf(
      "times: thread CPU time (CLOCK_THREAD_CPUTIME_ID) of the worker that answered the "
      "record, %d worker%s, CPU backend; the first %d valid records of each avatar answered "
      "once untimed first by every worker; every valid record timed, none dropped, in the "
      "order a live room completes them (by the pair's second utime); the records in %.3f s "
      "wall, %.0f records/s\n\n",
      pool.size(), pool.size() == 1 ? "" : "s", o.warmup, wall_s,
      wall_s > 0 ? whole_us.size() / wall_s : 0.0);
  std::printf("| answer | records | median us | p99 us | max us |\n|---|---|---|---|---|\n");
  PrintLine("env-only", env_us.size(), env);
  PrintLine("whole", whole_us.size(), whole);
  PrintLine("whole: all others cleared by the broad phase", by_kind[0].size(),
            bench::Summarise(by_kind[0]));
  PrintLine("whole: link work, no shared contact", by_kind[1].size(), bench::Summarise(by_kind[1]));
  PrintLine("whole: a shared contact", by_kind[2].size(), bench::Summarise(by_kind[2]));
  // The shared part of a record: its whole time less its env-only time.
  std::vector<double> shared_us[3];
  for (int k = 0; k < 3; ++k) {
    for (size_t i = 0; i < by_kind[k].size(); ++i) {
      shared_us[k].push_back(by_kind[k][i] - env_by_kind[k][i]);
    }
  }
  PrintLine("shared: cleared", shared_us[0].size(), bench::Summarise(shared_us[0]));
  PrintLine("shared: link work", shared_us[1].size(), bench::Summarise(shared_us[1]));
  PrintLine("shared: contact", shared_us[2].size(), bench::Summarise(shared_us[2]));
  PrintLine("env-only: all others cleared by the broad phase", env_by_kind[0].size(),
            bench::Summarise(env_by_kind[0]));
  PrintLine("env-only: link work, no shared contact", env_by_kind[1].size(),
            bench::Summarise(env_by_kind[1]));
  PrintLine("env-only: a shared contact", env_by_kind[2].size(), bench::Summarise(env_by_kind[2]));
  std::printf("\n");
  PrintTarget("whole median / env-only median", env.median > 0 ? whole.median / env.median : 0, 2);
  PrintTarget("whole p99 / whole median", whole.median > 0 ? whole.p99 / whole.median : 0, 5);
  std::printf("avatar pairs with a shared contact: %zu of %lld (%.1f%%)\n",
              tally.avatar_pairs.size(), static_cast<long long>(pairs),
              pairs ? 100.0 * tally.avatar_pairs.size() / pairs : 0.0);
  std::printf("records with a shared contact: %lld of %zu (%.1f%%)\n",
              static_cast<long long>(tally.records_with_contact), whole_us.size(),
              whole_us.empty() ? 0.0 : 100.0 * tally.records_with_contact / whole_us.size());
  std::printf("records with an environment contact: %lld\n",
              static_cast<long long>(tally.env_contacts));
  std::printf("entity entries: %lld (cleared by the broad phase %lld, link work %lld)\n",
              static_cast<long long>(tally.entries), static_cast<long long>(tally.culled),
              static_cast<long long>(tally.entries - tally.culled));
  std::printf("entity contacts: avatar %lld, held object %lld, thrown object %lld\n",
              static_cast<long long>(tally.avatar_contacts),
              static_cast<long long>(tally.held_contacts),
              static_cast<long long>(tally.thrown_contacts));
}

}  // namespace

int RunWorldBenchCommand(const WorldBenchOptions& o) {
  try {
    if (o.avatars < 2 || o.objects < 0 || !(o.seconds > 0.1) || !(o.spacing > 0) || o.warmup < 0) {
      throw InputError(
          "world-bench: needs --avatars >= 2, --objects >= 0, --seconds > 0.1, "
          "--spacing > 0 and --warmup >= 0");
    }
    const std::string data = o.data_dir.empty() ? SWEPTCCD_DATA_DIR : o.data_dir;
    if (o.scenario == "hands") {
      if (o.threads != 1) throw InputError("world-bench: --scenario hands runs on one thread");
      RunHandsScenario(o, data);
      return 0;
    }
    const GeneratedWorld g = Generate(o, data);
    std::fprintf(stderr, "world-bench: wrote %s\n", g.path.c_str());
    if (!o.generate_only) Bench(o, g);
    return 0;
  } catch (const InputError& e) {
    std::fprintf(stderr, "error: %s\n", DisplayError(e.what()).c_str());
    return 2;
  } catch (const std::filesystem::filesystem_error& e) {
    std::fprintf(stderr, "error: world-bench: %s\n", DisplayError(e.what()).c_str());
    return 2;
  }
}

}  // namespace sweptccd
