#pragma once
// The static scene the live view draws (docs/WEBSOCKET.md section 8): each
// environment object and each tracked object's mesh, welded and decimated by
// vertex clustering so the whole scene has at most a cap of triangles,
// encoded once at start (`/scene.json`, `/scene/N.bin`). For display only:
// queries always use the full meshes.

#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "core/scene/environment.h"

namespace sweptccd::ws {

struct SceneMesh {
  std::string kind;       // "environment" or "object".
  std::string name;       // Environment object name, or the object id.
  std::string object_id;  // Tracked objects only.
  size_t source_triangles = 0;
  uint32_t vertices = 0, triangles = 0;
  float min[3] = {0, 0, 0}, max[3] = {0, 0, 0};
  std::string bin;  // The /scene/N.bin bytes.
};

struct Scene {
  int max_triangles = 0;
  std::vector<SceneMesh> meshes;
  std::string json;  // The /scene.json text.
};

/// A tracked object's mesh for the scene.
struct SceneObject {
  std::string object_id;
  std::shared_ptr<const Environment> mesh;  // One object, its own frame.
};

/// Builds the scene: every mesh gets a share of `max_triangles` in
/// proportion to its triangles (at least 12), and is clustered on a grid
/// coarse enough to fit its share (a fine grid first: identical vertices
/// welded). Thread-safe (pure).
Scene BuildScene(const Environment& environment, const std::vector<SceneObject>& objects,
                 int max_triangles);

/// One mesh as its .bin (magic "SCM1", counts, float32 positions, uint32
/// indices, little-endian), at most `budget` triangles. Exposed for tests.
SceneMesh ClusterMesh(const TriangleBvh& bvh, size_t budget);

}  // namespace sweptccd::ws
