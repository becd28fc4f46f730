#include "core/scene/environment.h"

#include <algorithm>
#include <atomic>
#include <cmath>

#include "core/geometry/rounding_slack.h"

namespace sweptccd {

uint64_t Environment::NextContentId() {
  static std::atomic<uint64_t> next{1};
  return next++;
}

Environment Environment::LoadFiles(const std::vector<std::string>& paths,
                                   const MeshLoadOptions& options) {
  Environment env;
  for (const std::string& path : paths) env.AddMesh(LoadMeshFile(path, options), path);
  return env;
}

void Environment::AddMesh(const TriangleMesh& mesh, const std::string& name) {
  EnvironmentObject obj;
  obj.name = name;
  obj.bvh = TriangleBvh(mesh);
  // Floats read from text (assimp's fast_atoreal_move<float> can be off by
  // about one ulp more than rounding): rounding_slack.h.
  coordinate_tolerance_ =
      std::max(coordinate_tolerance_, RoundingSlack(obj.bvh.max_abs_coordinate()));
  objects_.push_back(std::move(obj));
  content_id_ = NextContentId();
}

size_t Environment::num_triangles() const {
  size_t n = 0;
  for (const auto& o : objects_) n += o.bvh.num_triangles();
  return n;
}

size_t Environment::memory_bytes() const {
  size_t n = 0;
  for (const auto& o : objects_) n += o.bvh.memory_bytes() + sizeof(o) + o.name.capacity();
  return n;
}

int Environment::FindObject(const std::string& name) const {
  for (int i = 0; i < num_objects(); ++i) {
    if (objects_[i].name == name) return i;
  }
  return -1;
}

}  // namespace sweptccd
