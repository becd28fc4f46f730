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

#include "core/errors.h"

namespace sweptccd {

std::string ReadFileMaybeGzip(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw InputError(path + ": cannot open the file");
  std::stringstream buffer;
  buffer << in.rdbuf();
  if (in.bad()) throw InputError(path + ": error while reading the file");
  std::string raw = buffer.str();
  if (raw.size() < 2 || static_cast<unsigned char>(raw[0]) != 0x1f ||
      static_cast<unsigned char>(raw[1]) != 0x8b) {
    return raw;
  }
  // gzip: inflate with zlib (windowBits 15 + 32 detects the gzip header).
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
      inflateEnd(&zs);
      throw InputError(path + ": corrupt or truncated gzip data (" +
                       (zs.msg ? std::string(zs.msg) : std::string("zlib error ") +
                                                           std::to_string(ret)) +
                       ")");
    }
    out.append(chunk, sizeof(chunk) - zs.avail_out);
    if (ret != Z_STREAM_END && zs.avail_in == 0 && zs.avail_out != 0) {
      inflateEnd(&zs);
      throw InputError(path + ": truncated gzip data");
    }
  }
  inflateEnd(&zs);
  return out;
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

// PLY is checked before assimp sees it: assimp 5.2 loops forever on a header
// without end_header, and reads past or misreads a truncated body
// (assimp/assimp#5310, #5341). The check parses the header and walks the body
// without interpreting it: binary bodies must hold every announced element,
// ASCII bodies at least one line per element.
void CheckPly(const std::string& data, const std::string& path) {
  if (data.compare(0, 3, "ply") != 0) return;  // Not a PLY: assimp will say so.
  constexpr size_t kMaxHeader = 1 << 20;
  size_t end = std::string::npos;
  for (size_t at = data.find("end_header"); at != std::string::npos && at < kMaxHeader;
       at = data.find("end_header", at + 1)) {
    if (at == 0 || data[at - 1] != '\n') continue;
    size_t after = at + 10;
    while (after < data.size() && data[after] == ' ') ++after;
    if (after < data.size() && data[after] == '\r') ++after;
    if (after < data.size() && data[after] == '\n') {
      end = after + 1;
      break;
    }
    if (after == data.size()) {
      end = after;
      break;
    }
  }
  if (end == std::string::npos) {
    throw InputError(path + ": the PLY header has no end_header line (truncated or corrupt)");
  }
  struct Property {
    int size = 0;        // Scalar size, or list item size.
    int count_size = 0;  // > 0 for a list.
  };
  struct Element {
    std::string name;
    uint64_t count = 0;
    std::vector<Property> properties;
  };
  auto type_size = [&](const std::string& t) {
    if (t == "char" || t == "uchar" || t == "int8" || t == "uint8") return 1;
    if (t == "short" || t == "ushort" || t == "int16" || t == "uint16") return 2;
    if (t == "int" || t == "uint" || t == "int32" || t == "uint32" || t == "float" ||
        t == "float32") {
      return 4;
    }
    if (t == "double" || t == "float64") return 8;
    throw InputError(path + ": the PLY header names an unknown property type '" + t + "'");
  };
  std::istringstream header(data.substr(0, end));
  std::string line, format;
  std::vector<Element> elements;
  while (std::getline(header, line)) {
    std::istringstream words(line);
    std::string key;
    words >> key;
    if (key == "format") {
      words >> format;
    } else if (key == "element") {
      Element e;
      long double count = -1;
      words >> e.name >> count;
      if (!words || count < 0 || count > 1e15) {
        throw InputError(path + ": bad PLY element line '" + line + "'");
      }
      e.count = static_cast<uint64_t>(count);
      elements.push_back(e);
    } else if (key == "property") {
      if (elements.empty()) throw InputError(path + ": PLY property before any element");
      std::string type;
      words >> type;
      Property prop;
      if (type == "list") {
        std::string count_type, item_type;
        words >> count_type >> item_type;
        prop.count_size = type_size(count_type);
        prop.size = type_size(item_type);
      } else {
        prop.size = type_size(type);
      }
      elements.back().properties.push_back(prop);
    }
  }
  const bool little = format == "binary_little_endian";
  if (little || format == "binary_big_endian") {
    const unsigned char* bytes = reinterpret_cast<const unsigned char*>(data.data());
    size_t pos = end;
    for (const Element& e : elements) {
      if (e.properties.empty()) continue;
      for (uint64_t k = 0; k < e.count; ++k) {
        for (const Property& prop : e.properties) {
          uint64_t items = 1;
          if (prop.count_size > 0) {
            if (pos + prop.count_size > data.size()) items = 0;
            else {
              items = 0;
              for (int b = 0; b < prop.count_size; ++b) {
                const int shift = 8 * (little ? b : prop.count_size - 1 - b);
                items |= static_cast<uint64_t>(bytes[pos + b]) << shift;
              }
              if (prop.count_size == 4 && (items >> 31)) {
                throw InputError(path + ": corrupt PLY list length in element '" + e.name + "' " +
                                 std::to_string(k));
              }
            }
            pos += prop.count_size;
          }
          pos += items * prop.size;
          if (pos > data.size()) {
            throw InputError(path + ": the binary PLY data is truncated: it ends inside element '" +
                             e.name + "' " + std::to_string(k) + " of " +
                             std::to_string(e.count));
          }
        }
      }
    }
  } else if (format == "ascii") {
    // Walk the tokens: one per scalar, a count and that many items per list.
    size_t pos = end;
    auto next_token = [&](std::string* token) {
      while (pos < data.size() && std::isspace(static_cast<unsigned char>(data[pos]))) ++pos;
      const size_t start = pos;
      while (pos < data.size() && !std::isspace(static_cast<unsigned char>(data[pos]))) ++pos;
      if (token != nullptr) token->assign(data, start, pos - start);
      return pos > start;
    };
    std::string token;
    for (const Element& e : elements) {
      if (e.properties.empty()) continue;
      for (uint64_t k = 0; k < e.count; ++k) {
        for (const Property& prop : e.properties) {
          uint64_t items = 1;
          if (prop.count_size > 0) {
            if (!next_token(&token)) items = ~uint64_t{0};
            else {
              char* stop = nullptr;
              const long long n = std::strtoll(token.c_str(), &stop, 10);
              if (stop == token.c_str() || *stop != '\0' || n < 0) {
                throw InputError(path + ": bad PLY list length '" + token + "' in element '" +
                                 e.name + "' " + std::to_string(k));
              }
              items = static_cast<uint64_t>(n);
            }
          }
          for (uint64_t i = 0; i < items; ++i) {
            if (!next_token(nullptr)) {
              throw InputError(path + ": the ASCII PLY data is truncated: it ends inside element '" +
                               e.name + "' " + std::to_string(k) + " of " +
                               std::to_string(e.count));
            }
          }
        }
      }
    }
  } else {
    throw InputError(path + ": the PLY header has no valid format line (got '" + format + "')");
  }
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

TriangleMesh LoadMeshFile(const std::string& path) {
  const std::string hint = FormatHint(path);
  if (hint.empty()) {
    throw InputError(path + ": unknown mesh format (expected .obj, .ply or .stl, optionally .gz)");
  }
  const std::string data = ReadFileMaybeGzip(path);
  if (data.empty()) throw InputError(path + ": the file is empty");
  if (hint == "ply") CheckPly(data, path);
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
