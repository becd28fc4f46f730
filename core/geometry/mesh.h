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

/// Default cap on a mesh file's size, before and after gunzip: 1 GiB, far
/// above the largest real scene (16.5 MB) and far below a server's memory.
inline constexpr uint64_t kDefaultMaxMeshBytes = uint64_t{1} << 30;
/// Default cap on one line of a text mesh (OBJ, ASCII PLY, ASCII STL): 1 MiB.
inline constexpr uint64_t kDefaultMaxMeshLineBytes = uint64_t{1} << 20;

/// Limits applied while a mesh file is read, before any parser allocates.
struct MeshLoadOptions {
  /// Largest file size and largest decompressed size, bytes (> 0). Set from
  /// `--max-mesh-bytes` (query, render, bench) or `max_mesh_bytes` (daemon).
  uint64_t max_bytes = kDefaultMaxMeshBytes;
  /// Longest line of a text mesh, bytes (> 0).
  uint64_t max_line_bytes = kDefaultMaxMeshLineBytes;
};

/// Loads one OBJ, PLY (ASCII or binary) or STL (ASCII or binary) file, which
/// may be gzip-compressed (by magic bytes, `.gz` or not). Polygons are split as
/// a fan from their first vertex, in file order; degenerate triangles are kept;
/// points and lines are dropped. Before parsing, the file must fit
/// `options.max_bytes` (compressed and decompressed) and pass
/// PrecheckMeshData (core/geometry/mesh_precheck.h): header counts against the
/// file size, line lengths. Throws InputError("PATH: problem") when the file
/// cannot be read or parsed, breaks a limit, or holds no triangles.
/// Thread-safe (each call has its own importer).
TriangleMesh LoadMeshFile(const std::string& path, const MeshLoadOptions& options = {});

/// Reads a whole file, gunzipping it when it starts with the gzip magic bytes.
/// Reads at most `max_bytes` from the file and inflates at most `max_bytes`:
/// beyond either it throws InputError naming the path, the cap and
/// `--max-mesh-bytes`, having held no more than the cap in memory. Throws
/// InputError naming the path for unreadable or corrupt files.
std::string ReadFileMaybeGzip(const std::string& path, uint64_t max_bytes = kDefaultMaxMeshBytes);

}  // namespace sweptccd
