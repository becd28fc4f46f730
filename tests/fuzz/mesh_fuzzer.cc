// Fuzzes LoadMeshFile (SPEC section 4) for one format, chosen at build time
// by SWEPTCCD_FUZZ_MESH_EXT ("obj", "ply" or "stl"); gzip-compressed inputs
// of that format take the same path (the loader detects the gzip magic). The
// contract: a mesh, or InputError. Anything else escaping, a crash, a hang
// (-timeout) or an allocation over -rss_limit_mb is a finding.

#include <cstddef>
#include <cstdint>

#include "core/errors.h"
#include "core/geometry/mesh.h"
#include "tests/fuzz/fuzz_input.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const std::string path = sweptccd::fuzz::WriteShmFile(data, size, SWEPTCCD_FUZZ_MESH_EXT);
  try {
    sweptccd::LoadMeshFile(path);
  } catch (const sweptccd::InputError&) {
  }
  return 0;
}
