// One round trip of the GPU swept-volume test (issue 30): the time of
// GpuCuller::Cull for batches of 1, 16, 64, 256 and 4096 capsules, the old
// way (glBufferSubData up, glGetBufferSubData down) against persistent
// mapped buffers with a fence, in the same run, alternating call by call.
// Two placements: capsules far outside the scene (the traversal stops at the
// roots: what is left is the round trip itself) and capsules inside the
// scene's box (the real work added). Prints a table (median, p99, max, us);
// times are never asserted anywhere.
//
//   build/bin/sweptccd_gpu_roundtrip_bench [--env MESH] [--seconds S] [--gpu-device N]

#include <spdlog/spdlog.h>

#include <CLI/CLI.hpp>
#include <chrono>
#include <cstdio>
#include <memory>
#include <random>
#include <string>
#include <vector>

#include "core/geometry/mesh.h"
#include "core/gpu/gl_context.h"
#include "core/gpu/gpu_culler.h"
#include "core/percentile.h"
#include "core/scene/collision_filter.h"
#include "core/scene/environment.h"
#include "tools/bench_common.h"

namespace sweptccd {
namespace {

std::vector<LinkCapsule> Capsules(std::mt19937_64& rng, const Eigen::Vector3d& lo,
                                  const Eigen::Vector3d& hi, size_t n, int links) {
  std::uniform_real_distribution<double> u(0, 1);
  std::vector<LinkCapsule> caps;
  for (size_t i = 0; i < n; ++i) {
    LinkCapsule c;
    for (int k = 0; k < 3; ++k) c.a[k] = lo[k] + u(rng) * (hi[k] - lo[k]);
    c.b = c.a + Eigen::Vector3d(0.1 * u(rng), 0.1 * u(rng), 0.1 * u(rng));
    c.radius = 0.02 + 0.05 * u(rng);
    c.link = LinkIndex(static_cast<int>(i % static_cast<size_t>(links)));
    caps.push_back(c);
  }
  return caps;
}

int Main(int argc, char** argv) {
  CLI::App app("GPU round trip: read-back against persistent mapped buffers and a fence");
  std::string env_path =
      bench::DataFile(std::string(SWEPTCCD_DATA_DIR) + "/env/morse_apartment.ply");
  double seconds = 0.3;
  int device = -1;
  app.add_option("--env", env_path, "Scene mesh (default: the MORSE apartment)");
  app.add_option("--seconds", seconds, "Time per batch size, placement and way (default 0.3)")
      ->check(CLI::Range(0.01, 60.0));
  app.add_option("--gpu-device", device, "EGL device index");
  CLI11_PARSE(app, argc, argv);
  spdlog::set_level(spdlog::level::warn);

  const TriangleMesh mesh = LoadMeshFile(env_path);
  Environment env;
  env.AddMesh(mesh, env_path);
  Eigen::Vector3d lo = Eigen::Vector3d::Constant(1e300), hi = -lo;
  for (const Eigen::Vector3f& v : mesh.vertices) {
    lo = lo.cwiseMin(v.cast<double>());
    hi = hi.cwiseMax(v.cast<double>());
  }
  gpu::GlContextOptions co;
  co.device_index = device;
  auto context = std::make_shared<gpu::GlContext>(co);
  const int links = 16;
  const CollisionFilter filter(links, env.num_objects());
  const gpu::Transfer ways[2] = {gpu::Transfer::kReadBack, gpu::Transfer::kPersistent};
  std::unique_ptr<gpu::GpuCuller> cullers[2];
  std::shared_ptr<const gpu::GpuEnvironment> envs[2];
  for (int w = 0; w < 2; ++w) {
    envs[w] = std::make_shared<const gpu::GpuEnvironment>(context, env, ways[w]);
    cullers[w] = std::make_unique<gpu::GpuCuller>(envs[w], filter, links);
  }
  std::printf(
      "GPU round trip, one GpuCuller::Cull call (us): %s; scene %s (%zu triangles); "
      "%.2f s per batch size, placement and way, calls alternating between the ways\n",
      context->info().Summary().c_str(), env_path.c_str(), mesh.num_triangles(), seconds);
  std::printf("ways: read-back (glBufferSubData + glGetBufferSubData) | persistent (%s)\n\n",
              gpu::TransferName(envs[1]->transfer()));
  std::printf(
      "| placement | capsules | calls | read-back median | p99 | max | persistent median | "
      "p99 | max | differing answers |\n|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|\n");
  std::mt19937_64 rng(30);
  const Eigen::Vector3d far_lo = hi + Eigen::Vector3d::Constant(100.0);
  const Eigen::Vector3d far_hi = far_lo + (hi - lo);
  using Clock = std::chrono::steady_clock;
  int exit_code = 0;
  for (const bool inside : {false, true}) {
    for (size_t n : {1u, 16u, 64u, 256u, 4096u}) {
      const std::vector<LinkCapsule> caps =
          inside ? Capsules(rng, lo, hi, n, links) : Capsules(rng, far_lo, far_hi, n, links);
      std::vector<double> us[2];
      std::vector<uint8_t> answer[2];
      int64_t differing = 0;
      for (int w = 0; w < 2; ++w) (void)cullers[w]->Cull(caps, &answer[w]);  // Warm-up.
      const auto end = Clock::now() + std::chrono::duration<double>(2 * seconds);
      for (int call = 0; Clock::now() < end || call < 4; ++call) {
        const int w = call % 2;
        const auto a = Clock::now();
        if (!cullers[w]->Cull(caps, &answer[w])) {
          std::fprintf(stderr, "the GPU failed\n");
          return 1;
        }
        us[w].push_back(std::chrono::duration<double, std::micro>(Clock::now() - a).count());
        if (w == 1) differing += answer[0] != answer[1];
      }
      const Summary r = Summarise(us[0]), p = Summarise(us[1]);
      std::printf("| %s | %zu | %zu | %.1f | %.1f | %.1f | %.1f | %.1f | %.1f | %lld |\n",
                  inside ? "in the scene" : "outside (round trip only)", n, r.n + p.n, r.median,
                  r.p99, r.max, p.median, p.p99, p.max, static_cast<long long>(differing));
      std::fflush(stdout);
      if (differing != 0) exit_code = 1;
    }
  }
  return exit_code;
}

}  // namespace
}  // namespace sweptccd

int main(int argc, char** argv) {
  try {
    return sweptccd::Main(argc, argv);
  } catch (const std::exception& e) {
    std::fprintf(stderr, "error: %s\n", e.what());
    return 2;
  }
}
