#include "core/geometry/mesh.h"

#include <assimp/Importer.hpp>
#include <assimp/postprocess.h>
#include <assimp/scene.h>
#include <zlib.h>

#include <algorithm>
#include <cctype>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <sstream>
#include <vector>

#include "core/bounded_file.h"
#include "core/errors.h"
#include "core/geometry/mesh_precheck.h"

namespace sweptccd {

namespace {

const char kRaiseMeshCap[] =
    "raise it with --max-mesh-bytes (daemon: max_mesh_bytes) if the file is real";

std::string CapMessage(const std::string& path, const char* what, uint64_t max_bytes) {
  return path + ": " + what + " more than the cap of " + std::to_string(max_bytes) + " bytes; " +
         kRaiseMeshCap;
}

// Inflates gzip data (windowBits 15 + 32 detects the gzip header), stopping
// as soon as the output would pass max_bytes.
std::string Gunzip(std::string& raw, const std::string& path, uint64_t max_bytes) {
  z_stream zs;
  std::memset(&zs, 0, sizeof(zs));
  if (inflateInit2(&zs, 15 + 32) != Z_OK) throw InputError(path + ": zlib initialisation failed");
  zs.next_in = reinterpret_cast<Bytef*>(raw.data());
  zs.avail_in = static_cast<uInt>(raw.size());
  std::string out;
  char chunk[1 << 16];
  int ret = Z_OK;
  while (ret != Z_STREAM_END) {
    zs.next_out = reinterpret_cast<Bytef*>(chunk);
    zs.avail_out = sizeof(chunk);
    ret = inflate(&zs, Z_NO_FLUSH);
    if (ret != Z_OK && ret != Z_STREAM_END) {
      const std::string why = zs.msg ? std::string(zs.msg) : "zlib error " + std::to_string(ret);
      inflateEnd(&zs);
      throw InputError(path + ": corrupt or truncated gzip data (" + why + ")");
    }
    const uint64_t got = sizeof(chunk) - zs.avail_out;
    if (out.size() + got > max_bytes) {
      inflateEnd(&zs);
      throw InputError(CapMessage(path, "the gzip data inflates to", max_bytes));
    }
    out.append(chunk, got);
    if (ret != Z_STREAM_END && zs.avail_in == 0 && zs.avail_out != 0) {
      inflateEnd(&zs);
      throw InputError(path + ": truncated gzip data");
    }
  }
  inflateEnd(&zs);
  return out;
}

}  // namespace

std::string ReadFileMaybeGzip(const std::string& path, uint64_t max_bytes) {
  // The file itself is held under the same cap (and below 4 GiB: zlib's
  // avail_in is 32 bits).
  std::string raw = ReadFileBounded(path, std::min<uint64_t>(max_bytes, 0xffffffffu), "file",
                                    kRaiseMeshCap);
  if (raw.size() < 2 || static_cast<unsigned char>(raw[0]) != 0x1f ||
      static_cast<unsigned char>(raw[1]) != 0x8b) {
    return raw;
  }
  return Gunzip(raw, path, max_bytes);
}

namespace {

std::string Lower(std::string s) {
  std::transform(s.begin(), s.end(), s.begin(),
                 [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  return s;
}

// The format hint for assimp from the file name (without a .gz suffix).
std::string FormatHint(const std::string& path) {
  std::string name = Lower(path);
  if (name.size() > 3 && name.compare(name.size() - 3, 3, ".gz") == 0) {
    name.resize(name.size() - 3);
  }
  const size_t dot = name.rfind('.');
  const std::string ext = dot == std::string::npos ? "" : name.substr(dot + 1);
  if (ext == "obj" || ext == "ply" || ext == "stl") return ext;
  return "";
}

void AppendNode(const aiScene* scene, const aiNode* node, const aiMatrix4x4& parent,
                TriangleMesh* mesh) {
  const aiMatrix4x4 X = parent * node->mTransformation;
  for (unsigned m = 0; m < node->mNumMeshes; ++m) {
    const aiMesh* am = scene->mMeshes[node->mMeshes[m]];
    const uint32_t base = static_cast<uint32_t>(mesh->vertices.size());
    for (unsigned v = 0; v < am->mNumVertices; ++v) {
      const aiVector3D p = X * am->mVertices[v];
      mesh->vertices.emplace_back(p.x, p.y, p.z);
    }
    for (unsigned f = 0; f < am->mNumFaces; ++f) {
      const aiFace& face = am->mFaces[f];
      // Fan from the first vertex, in file order (SPEC section 4).
      for (unsigned k = 2; k < face.mNumIndices; ++k) {
        mesh->indices.push_back(base + face.mIndices[0]);
        mesh->indices.push_back(base + face.mIndices[k - 1]);
        mesh->indices.push_back(base + face.mIndices[k]);
      }
    }
  }
  for (unsigned c = 0; c < node->mNumChildren; ++c) AppendNode(scene, node->mChildren[c], X, mesh);
}

}  // namespace

TriangleMesh LoadMeshFile(const std::string& path, const MeshLoadOptions& options) {
  const std::string hint = FormatHint(path);
  if (hint.empty()) {
    throw InputError(path + ": unknown mesh format (expected .obj, .ply or .stl, optionally .gz)");
  }
  if (options.max_bytes == 0 || options.max_line_bytes == 0) {
    throw InputError(path + ": the mesh size caps must be > 0 bytes");
  }
  const std::string data = ReadFileMaybeGzip(path, options.max_bytes);
  if (data.empty()) throw InputError(path + ": the file is empty");
  // assimp must never see a file that fails these checks.
  PrecheckMeshData(data, hint, path, options.max_line_bytes);
  Assimp::Importer importer;
  // No post-processing: polygons stay polygons (we fan-split them ourselves in
  // file order) and degenerate triangles are kept.
  const aiScene* scene = importer.ReadFileFromMemory(data.data(), data.size(), 0, hint.c_str());
  if (scene == nullptr) {
    std::string why = importer.GetErrorString();
    if (why.empty()) why = "unknown parse error";
    throw InputError(path + ": cannot parse the " + hint + " mesh: " + why);
  }
  TriangleMesh mesh;
  if (scene->mRootNode != nullptr) {
    AppendNode(scene, scene->mRootNode, aiMatrix4x4(), &mesh);
  }
  if (mesh.num_triangles() == 0) throw InputError(path + ": the mesh holds no triangles");
  for (const Eigen::Vector3f& v : mesh.vertices) {
    if (!v.allFinite()) throw InputError(path + ": a vertex holds a non-finite coordinate");
  }
  for (uint32_t idx : mesh.indices) {
    if (idx >= mesh.vertices.size()) throw InputError(path + ": a face index is out of range");
  }
  return mesh;
}

}  // namespace sweptccd
