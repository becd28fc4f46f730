// sweptccd: the command-line front end. Parses flags and dispatches to the
// subcommands; the work is in the *_command.cc files.

#include <spdlog/sinks/stdout_color_sinks.h>
#include <spdlog/spdlog.h>

#include <CLI/CLI.hpp>
#include <cstdio>

#include "core/errors.h"
#include "core/gpu/backend.h"
#include "msgs/signing.h"
#include "msgs/text.h"
#include "tools/bench_command.h"
#include "tools/import_bvh_command.h"
#include "tools/monitor_command.h"
#include "tools/query_command.h"
#include "tools/render_command.h"
#include "tools/simulate_tracker_command.h"
#include "tools/skeleton_command.h"
#include "tools/world_bench_command.h"
#include "tools/world_command.h"

int main(int argc, char** argv) {
  // Diagnostics go to standard error, never into the results.
  spdlog::set_default_logger(spdlog::stderr_color_mt("sweptccd"));
  spdlog::set_pattern("[%H:%M:%S.%e] [%^%l%$] %v");

  CLI::App app{"SweptCCD: certified continuous collision detection for tracked avatars"};
  app.require_subcommand(1);
  // --log-level (an option of sweptccd itself) also after the subcommand.
  app.fallthrough();
  std::string log_level = "warn";
  app.add_option("--log-level", log_level, "trace, debug, info, warn, error or off")
      ->check(CLI::IsMember({"trace", "debug", "info", "warn", "error", "off"}));

  sweptccd::QueryCommandOptions q;
  std::string motion = "articulated";
  CLI::App* query = app.add_subcommand("query", "Answer every pair of a pose stream (SPEC 7)");
  query->add_option("--skeleton", q.skeleton_path, "Skeleton JSON file")->required();
  query->add_option("--poses", q.poses_path, "Pose stream, JSON Lines")->required();
  query->add_option("--env", q.env_paths, "Mesh file (OBJ, PLY, STL, optionally .gz); repeat")
      ->required();
  query->add_option("--motion", motion, "articulated (default) or independent")
      ->check(CLI::IsMember({"articulated", "independent"}));
  query->add_option("--eps", q.query.eps_s, "Time tolerance, seconds (default 1e-4)");
  query->add_option("--delta", q.query.delta_m, "Distance tolerance, metres (default 1e-3)");
  sweptccd::AddBackendFlags(
      query, &q.backend, "cpu, gpu or auto (default auto: the faster on a calibration at start)");
  query->add_flag("--per-link", q.query.per_link, "A bracket for every touching link");
  query->add_flag("--device-descent", q.device_descent,
                  "With the GPU chosen: clear each chunk's free time intervals on the GPU in a "
                  "few dispatches, then answer on the CPU skipping them (docs/GPU.md)");
  query->add_option("--output", q.output_path, "Results file (default: standard output)");
  query->add_option("--filter", q.filter_path,
                    "Collision filter JSON: {\"ignore\": [{\"link\": L, \"object\": O}]}");
  query->add_option("--ignore", q.ignore_rules,
                    "Ignore contacts of LINK (name, index or *) with OBJECT (index, file or *); "
                    "repeat");
  query->add_option("--max-intervals", q.query.max_intervals,
                    "Work limit per pair (interval tests) before answering undecided");
  query
      ->add_option("--max-mesh-bytes", q.mesh.max_bytes,
                   "Largest mesh file, before and after gunzip, bytes (default 1 GiB)")
      ->check(CLI::PositiveNumber);
  sweptccd::AddMaxLinksFlag(query, &q.max_links);
  sweptccd::AddThreadsFlag(query, &q.threads);

  sweptccd::BenchCommandOptions b;
  CLI::App* bench = app.add_subcommand("bench", "Benchmark on real mocap and scenes");
  sweptccd::AddBenchOptions(bench, &b);

  sweptccd::ImportBvhCommandOptions ib;
  CLI::App* import_bvh =
      app.add_subcommand("import-bvh", "BVH motion capture to a skeleton and a pose stream");
  sweptccd::AddImportBvhOptions(import_bvh, &ib);

  sweptccd::SkeletonCommandOptions sk;
  CLI::App* skeleton = app.add_subcommand(
      "skeleton", "A SPEC skeleton from an OpenXR/WebXR/VRM joint set; joint frames to poses");
  sweptccd::AddSkeletonOptions(skeleton, &sk);

  sweptccd::RenderCommandOptions rn;
  CLI::App* render =
      app.add_subcommand("render", "PNG pictures of a contact and a timeline of a pose stream");
  sweptccd::AddRenderOptions(render, &rn);

  sweptccd::SimulateTrackerCommandOptions st;
  CLI::App* simulate = app.add_subcommand(
      "simulate-tracker", "Publish a pose stream or BVH clip as tracker poses over LCM");
  sweptccd::AddSimulateTrackerOptions(simulate, &st);

  sweptccd::MonitorCommandOptions mon;
  CLI::App* monitor = app.add_subcommand(
      "monitor", "Print the contact events, status and rejections of the daemon");
  sweptccd::AddMonitorOptions(monitor, &mon);

  std::string keygen_out;
  CLI::App* keygen = app.add_subcommand(
      "keygen", "Write a new random HMAC key (64 hex digits, mode 600) for signed messages");
  keygen->add_option("--out", keygen_out, "Key file to create (never overwritten)")->required();

  sweptccd::WorldCommandOptions wo;
  CLI::App* world =
      app.add_subcommand("world", "Answer every avatar pair of a shared world file (SPEC 8)");
  world->add_option("--world", wo.world_path, "World JSON file")->required();
  world->add_option("--eps", wo.query.eps_s, "Time tolerance, seconds (default 1e-4)");
  world->add_option("--delta", wo.query.delta_m, "Distance tolerance, metres (default 1e-3)");
  sweptccd::AddBackendFlags(world, &wo.backend,
                            "cpu, gpu or auto (static environment only; entities run on the CPU)");
  sweptccd::AddMaxLinksFlag(world, &wo.load.max_links);
  sweptccd::AddThreadsFlag(world, &wo.threads);
  world->add_flag("--per-link", wo.query.per_link, "A bracket for every touching link");
  world->add_flag("--device-descent", wo.device_descent,
                  "With the GPU chosen: clear the free time intervals of each chunk's "
                  "environment parts on the GPU in a few dispatches, then answer on the CPU "
                  "skipping them (docs/GPU.md)");
  world->add_option("--output", wo.output_path, "Results file (default: standard output)");
  world->add_flag("--bench", wo.bench,
                  "Print a table (counts, time per record) instead of the records");
  world->add_option("--max-intervals", wo.query.max_intervals,
                    "Work limit per query (default 2000000)");

  sweptccd::WorldBenchOptions wb;
  CLI::App* world_bench = app.add_subcommand(
      "world-bench", "Benchmark a shared world: avatars and objects in the breakfast room");
  sweptccd::AddWorldBenchOptions(world_bench, &wb);

  try {
    app.parse(argc, argv);
  } catch (const CLI::CallForHelp& e) {
    return app.exit(e);
  } catch (const CLI::CallForAllHelp& e) {
    return app.exit(e);
  } catch (const CLI::ParseError& e) {
    // One line, exit status 2, like every other refusal.
    std::fprintf(stderr, "error: sweptccd: %s\n", sweptccd::DisplayError(e.what()).c_str());
    return 2;
  }
  spdlog::set_level(spdlog::level::from_str(log_level));
  if (query->parsed()) {
    q.query.motion = *sweptccd::ParseMotionModel(motion);
    return sweptccd::RunQueryCommand(q);
  }
  if (world->parsed()) return sweptccd::RunWorldCommand(wo);
  if (world_bench->parsed()) return sweptccd::RunWorldBenchCommand(wb);
  if (bench->parsed()) return sweptccd::RunBenchCommand(b);
  if (import_bvh->parsed()) return sweptccd::RunImportBvhCommand(ib);
  if (skeleton->parsed()) return sweptccd::RunSkeletonCommand(sk);
  if (render->parsed()) return sweptccd::RunRenderCommand(rn);
  if (simulate->parsed()) return sweptccd::RunSimulateTrackerCommand(st);
  if (monitor->parsed()) return sweptccd::RunMonitorCommand(mon);
  if (keygen->parsed()) {
    try {
      sweptccd::WriteNewKeyFile(keygen_out);
      return 0;
    } catch (const sweptccd::InputError& e) {
      std::fprintf(stderr, "error: keygen: %s\n", sweptccd::DisplayError(e.what()).c_str());
      return 2;
    }
  }
  return 1;
}
