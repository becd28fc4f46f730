#include "core/query/query_scene.h"

#include <spdlog/spdlog.h>

#include <chrono>

#include "core/errors.h"

namespace sweptccd {

std::unique_ptr<QueryScene> LoadQueryScene(const QuerySceneSpec& spec, const Skeleton& skeleton,
                                           const std::string& who) {
  if (spec.env_paths.empty()) throw InputError(who + ": give at least one --env");
  auto scene = std::make_unique<QueryScene>();
  const auto load_start = std::chrono::steady_clock::now();
  scene->env = Environment::LoadFiles(spec.env_paths, spec.mesh);
  spdlog::info(
      "environment: {} objects, {} triangles, {:.1f} MiB, loaded in {:.3f} s",
      scene->env.num_objects(), scene->env.num_triangles(), scene->env.memory_bytes() / 1048576.0,
      std::chrono::duration<double>(std::chrono::steady_clock::now() - load_start).count());
  scene->filter = CollisionFilter(skeleton.num_links(), scene->env.num_objects());
  if (!spec.filter_path.empty()) {
    scene->filter = CollisionFilter::FromFile(spec.filter_path, skeleton, scene->env);
  }
  for (const std::string& rule : spec.ignore_rules) {
    scene->filter.AddRule(rule, skeleton, scene->env);
  }
  return scene;
}

}  // namespace sweptccd
