// Fuzzes CollisionFilter::FromJson (SPEC section 5) against a fixed
// three-link skeleton and a two-object environment: a filter, or InputError.

#include <cstddef>
#include <cstdint>

#include "core/avatar/skeleton.h"
#include "core/errors.h"
#include "core/geometry/mesh.h"
#include "core/scene/collision_filter.h"
#include "core/scene/environment.h"
#include "tests/fuzz/fuzz_input.h"

namespace {

const char kSkeleton[] = R"({"name": "fuzz", "links": [
  {"name": "pelvis", "parent": null, "a": [0, 0, 0], "b": [0, 0, 0.2], "radius": 0.1},
  {"name": "foot_l", "parent": "pelvis", "a": [0, 0, 0], "b": [0, 0, -0.8], "radius": 0.05},
  {"name": "foot_r", "parent": "pelvis", "a": [0, 0, 0], "b": [0, 0, -0.8], "radius": 0.05}]})";

sweptccd::Environment MakeEnvironment() {
  sweptccd::TriangleMesh triangle;
  triangle.vertices = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}};
  triangle.indices = {0, 1, 2};
  sweptccd::Environment env;
  env.AddMesh(triangle, "floor.obj");
  env.AddMesh(triangle, "wall.ply");
  return env;
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  static const sweptccd::Skeleton skeleton = sweptccd::ParseSkeletonJson(kSkeleton, "fuzz");
  static const sweptccd::Environment env = MakeEnvironment();
  try {
    const sweptccd::CollisionFilter filter = sweptccd::CollisionFilter::FromJson(
        sweptccd::fuzz::AsText(data, size), "fuzz", skeleton, env);
    for (int link = 0; link < skeleton.num_links(); ++link) {
      for (int object = 0; object < env.num_objects(); ++object) filter.Ignores(link, object);
      filter.IgnoresAll(link);
    }
  } catch (const sweptccd::InputError&) {
  }
  return 0;
}
