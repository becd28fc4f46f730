#include "tools/ply_writer.h"

#include <cstdint>
#include <cstring>
#include <fstream>

#include "core/errors.h"

namespace sweptccd {

namespace {

// Little-endian bytes of a float or a uint32, whatever the host's order.
void PutLe32(uint32_t v, char* out) {
  for (int b = 0; b < 4; ++b) out[b] = static_cast<char>((v >> (8 * b)) & 0xff);
}

uint32_t FloatBits(float f) {
  uint32_t u;
  std::memcpy(&u, &f, sizeof(u));
  return u;
}

}  // namespace

void WriteBinaryPly(const TriangleMesh& mesh, const std::string& path) {
  std::ofstream out(path, std::ios::binary | std::ios::trunc);
  if (!out) throw InputError("cannot write '" + path + "'");
  out << "ply\nformat binary_little_endian 1.0\ncomment written by sweptccd\n"
      << "element vertex " << mesh.vertices.size()
      << "\nproperty float x\nproperty float y\nproperty float z\n"
      << "element face " << mesh.num_triangles()
      << "\nproperty list uchar uint vertex_indices\nend_header\n";
  std::string buf;
  buf.reserve(1 << 20);
  char word[4];
  auto flush = [&](bool always) {
    if (always || buf.size() >= (1u << 20) - 16) {
      out.write(buf.data(), static_cast<std::streamsize>(buf.size()));
      buf.clear();
    }
  };
  for (const Eigen::Vector3f& v : mesh.vertices) {
    for (int k = 0; k < 3; ++k) {
      PutLe32(FloatBits(v[k]), word);
      buf.append(word, 4);
    }
    flush(false);
  }
  for (size_t t = 0; t < mesh.num_triangles(); ++t) {
    buf.push_back(3);
    for (int k = 0; k < 3; ++k) {
      PutLe32(mesh.indices[3 * t + k], word);
      buf.append(word, 4);
    }
    flush(false);
  }
  flush(true);
  if (!out) throw InputError("cannot write '" + path + "'");
}

}  // namespace sweptccd
