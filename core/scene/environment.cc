#include "core/scene/environment.h"

#include <algorithm>
#include <atomic>
#include <cmath>

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
  // A float keeps 24 bits: rounding a coordinate x moves it by at most
  // 2^-24 |x|, but assimp's text parser (fast_atoreal_move<float>) can be off
  // by about one float ulp more. 2^-22 |x| covers two ulps, with room for the rounding of
  // the double-precision distance computations (below 1e-8 of |x|).
  coordinate_tolerance_ =
      std::max(coordinate_tolerance_, std::ldexp(obj.bvh.max_abs_coordinate(), -22) + 1e-9);
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
