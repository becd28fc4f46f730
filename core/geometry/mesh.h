#pragma once
// Triangle meshes and the environment file formats of SPEC section 4.

#include <Eigen/Core>
#include <cstdint>
#include <string>
#include <vector>

namespace sweptccd {

/// An indexed triangle mesh, single precision (the formats store floats).
/// Triangle t is (vertices[indices[3t]], vertices[indices[3t+1]], vertices[indices[3t+2]]),
/// in file order after the fan split.
struct TriangleMesh {
  std::vector<Eigen::Vector3f> vertices;
  std::vector<uint32_t> indices;
  size_t num_triangles() const { return indices.size() / 3; }
};

/// Loads one OBJ, PLY (ASCII or binary) or STL (ASCII or binary) file, which
/// may be gzip-compressed (by magic bytes, `.gz` or not). Polygons are split as
/// a fan from their first vertex, in file order; degenerate triangles are kept;
/// points and lines are dropped. Throws InputError("PATH: problem") when the
/// file cannot be read or parsed, or holds no triangles.
TriangleMesh LoadMeshFile(const std::string& path);

/// Reads a whole file, gunzipping it when it starts with the gzip magic bytes.
/// Throws InputError naming the path.
std::string ReadFileMaybeGzip(const std::string& path);

}  // namespace sweptccd
