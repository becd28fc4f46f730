#pragma once
// A triangle mesh written as binary little-endian PLY (x y z floats, faces of
// three uint32 indices), the format LoadMeshFile reads back exactly. Used by
// `sweptccd bench --write-scene` to hand a composite bench scene to the daemon
// (which takes mesh files, not placements).

#include <string>

#include "core/geometry/mesh.h"

namespace sweptccd {

/// Writes `mesh` to `path` (replacing it). Throws InputError when the file
/// cannot be written.
void WriteBinaryPly(const TriangleMesh& mesh, const std::string& path);

}  // namespace sweptccd
