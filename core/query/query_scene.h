#pragma once
// What `sweptccd query` loads once before answering pairs, after the
// skeleton: the environment (SPEC 4) and the collision filter (SPEC 5), in
// that order. Shared by the command (tools/query_command.cc) and the Python
// engine (python/src/sweptccd_module.cc) so both refuse the same inputs with
// the same one-line messages.

#include <memory>
#include <string>
#include <vector>

#include "core/avatar/skeleton.h"
#include "core/geometry/mesh.h"
#include "core/scene/collision_filter.h"
#include "core/scene/environment.h"

namespace sweptccd {

struct QuerySceneSpec {
  std::vector<std::string> env_paths;     // At least one.
  std::string filter_path;                // Empty: none.
  std::vector<std::string> ignore_rules;  // LINK:OBJECT, after the filter file.
  MeshLoadOptions mesh;
};

struct QueryScene {
  Environment env;
  CollisionFilter filter;
};

/// The environment and the filter for `skeleton`. Throws InputError ("PATH:
/// problem", or `who` + ": give at least one --env" when env_paths is empty).
std::unique_ptr<QueryScene> LoadQueryScene(const QuerySceneSpec& spec, const Skeleton& skeleton,
                                           const std::string& who);

}  // namespace sweptccd
