#pragma once
// The static environment: objects (one per mesh file), each with its BVH.

#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "core/geometry/bvh.h"
#include "core/geometry/mesh.h"

namespace sweptccd {

struct EnvironmentObject {
  std::string name;  // Usually the file path.
  TriangleBvh bvh;
};

/// Immutable once built; const methods are thread-safe.
class Environment {
 public:
  Environment() = default;

  /// Loads each file as one object, in order, under `options`' size caps.
  /// Throws InputError naming the file.
  static Environment LoadFiles(const std::vector<std::string>& paths,
                               const MeshLoadOptions& options = {});

  /// Adds a mesh as the next object (builds its BVH).
  void AddMesh(const TriangleMesh& mesh, const std::string& name);

  int num_objects() const { return static_cast<int>(objects_.size()); }
  const EnvironmentObject& object(int i) const { return objects_[i]; }
  size_t num_triangles() const;
  size_t memory_bytes() const;
  /// Index of the object whose name is `name`, or -1.
  int FindObject(const std::string& name) const;

  /// Distance slack (metres) covering the single-precision storage of the
  /// vertices: contact tests treat a triangle as touching when it is within
  /// this much of the capsule, so no contact is missed even if the file held
  /// more digits than a float keeps.
  double coordinate_tolerance() const { return coordinate_tolerance_; }

  /// Identifies this content: unique in the process for every environment
  /// built and every AddMesh; copies share it. Caches of derived data (the
  /// GPU backend's uploads) key on it, never on the object's address, which
  /// a later environment may reuse.
  uint64_t content_id() const { return content_id_; }

 private:
  static uint64_t NextContentId();
  std::vector<EnvironmentObject> objects_;
  double coordinate_tolerance_ = 1e-9;
  uint64_t content_id_ = NextContentId();
};

}  // namespace sweptccd
