#include "service/ws/scene.h"

#include <Eigen/Geometry>
#include <algorithm>
#include <array>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <nlohmann/json.hpp>
#include <unordered_map>
#include <unordered_set>

namespace sweptccd::ws {

namespace {

void PutU32(std::string* out, uint32_t v) {
  const unsigned char b[4] = {static_cast<unsigned char>(v), static_cast<unsigned char>(v >> 8),
                              static_cast<unsigned char>(v >> 16),
                              static_cast<unsigned char>(v >> 24)};
  out->append(reinterpret_cast<const char*>(b), 4);
}

void PutF32(std::string* out, float f) {
  uint32_t v;
  std::memcpy(&v, &f, 4);
  PutU32(out, v);
}

struct TriangleKeyHash {
  size_t operator()(const std::array<uint32_t, 3>& t) const {
    uint64_t h = (uint64_t{t[0]} << 32 | t[1]) * 0x9e3779b97f4a7c15ull;
    h ^= (h >> 29) ^ (uint64_t{t[2]} * 0xbf58476d1ce4e5b9ull);
    return static_cast<size_t>(h ^ (h >> 32));
  }
};

// The surface area of a hierarchy's triangles, square metres.
double SurfaceArea(const TriangleBvh& bvh) {
  double area = 0;
  for (uint32_t slot = 0; slot < bvh.num_triangles(); ++slot) {
    Eigen::Vector3d a, b, d;
    bvh.Triangle(slot, &a, &b, &d);
    area += 0.5 * (b - a).cross(d - a).norm();
  }
  return area;
}

struct Clustered {
  std::vector<std::array<float, 3>> vertices;
  std::vector<std::array<uint32_t, 3>> triangles;
};

// Vertex clustering on a grid of `cell` metres from `origin`: each cell's
// first vertex stands for all; triangles with two corners in one cell, and
// repeats, are dropped.
Clustered Cluster(const TriangleBvh& bvh, const Eigen::Vector3d& origin, double cell) {
  Clustered c;
  std::unordered_map<uint64_t, uint32_t> cells;
  std::unordered_set<std::array<uint32_t, 3>, TriangleKeyHash> seen;
  auto vertex = [&](const Eigen::Vector3d& p) {
    const Eigen::Vector3d q = (p - origin) / cell;
    const uint64_t x = static_cast<uint64_t>(std::max(0.0, std::floor(q.x()))) & 0x1fffff;
    const uint64_t y = static_cast<uint64_t>(std::max(0.0, std::floor(q.y()))) & 0x1fffff;
    const uint64_t z = static_cast<uint64_t>(std::max(0.0, std::floor(q.z()))) & 0x1fffff;
    const uint64_t key = x << 42 | y << 21 | z;
    const auto [it, inserted] = cells.try_emplace(key, static_cast<uint32_t>(c.vertices.size()));
    if (inserted) {
      c.vertices.push_back(
          {static_cast<float>(p.x()), static_cast<float>(p.y()), static_cast<float>(p.z())});
    }
    return it->second;
  };
  for (uint32_t slot = 0; slot < bvh.num_triangles(); ++slot) {
    Eigen::Vector3d a, b, d;
    bvh.Triangle(slot, &a, &b, &d);
    const std::array<uint32_t, 3> t = {vertex(a), vertex(b), vertex(d)};
    if (t[0] == t[1] || t[1] == t[2] || t[0] == t[2]) continue;
    std::array<uint32_t, 3> key = t;
    std::rotate(key.begin(), std::min_element(key.begin(), key.end()), key.end());
    if (!seen.insert(key).second) continue;
    c.triangles.push_back(t);
  }
  return c;
}

}  // namespace

SceneMesh ClusterMesh(const TriangleBvh& bvh, size_t budget) {
  SceneMesh m;
  m.source_triangles = bvh.num_triangles();
  const Aabb box = bvh.bounds();
  const Eigen::Vector3d lo = box.lo, hi = box.hi;
  const double extent = std::max({hi.x() - lo.x(), hi.y() - lo.y(), hi.z() - lo.z(), 1e-6});
  // 2^-20 of the extent welds identical vertices; coarser until it fits.
  double cell = extent / (1 << 20);
  Clustered c = Cluster(bvh, lo, cell);
  if (c.triangles.size() > budget) {
    // A surface of area A on a grid of cell h keeps about 2 A / h^2
    // triangles (two per cell it crosses): start where about four times the
    // budget would remain, then coarsen in small steps. Growing from the
    // welding grid instead took 25-45 s on the 1.1 M-triangle dragon room.
    cell = std::max(cell, 0.5 * std::sqrt(2 * SurfaceArea(bvh) /
                                          static_cast<double>(std::max<size_t>(budget, 1))));
    c = Cluster(bvh, lo, cell);
    while (c.triangles.size() > budget && cell < extent) {
      cell *= 1.25;
      c = Cluster(bvh, lo, cell);
    }
  }
  if (c.triangles.size() > budget) c.triangles.resize(budget);
  m.vertices = static_cast<uint32_t>(c.vertices.size());
  m.triangles = static_cast<uint32_t>(c.triangles.size());
  for (int k = 0; k < 3; ++k) {
    m.min[k] = static_cast<float>(lo[k]);
    m.max[k] = static_cast<float>(hi[k]);
  }
  m.bin.reserve(16 + 12 * c.vertices.size() + 12 * c.triangles.size());
  m.bin.append("SCM1", 4);
  PutU32(&m.bin, m.vertices);
  PutU32(&m.bin, m.triangles);
  PutU32(&m.bin, 0);
  for (const auto& v : c.vertices) {
    for (float f : v) PutF32(&m.bin, f);
  }
  for (const auto& t : c.triangles) {
    for (uint32_t i : t) PutU32(&m.bin, i);
  }
  return m;
}

Scene BuildScene(const Environment& environment, const std::vector<SceneObject>& objects,
                 int max_triangles) {
  Scene scene;
  scene.max_triangles = max_triangles;
  std::vector<const TriangleBvh*> bvhs;
  for (int i = 0; i < environment.num_objects(); ++i) bvhs.push_back(&environment.object(i).bvh);
  for (const SceneObject& o : objects) bvhs.push_back(&o.mesh->object(0).bvh);
  size_t total = 0;
  for (const TriangleBvh* b : bvhs) total += b->num_triangles();
  for (size_t i = 0; i < bvhs.size(); ++i) {
    const size_t n = bvhs[i]->num_triangles();
    size_t budget = n;
    if (total > static_cast<size_t>(max_triangles)) {
      budget = std::max<size_t>(
          12, static_cast<size_t>(static_cast<double>(max_triangles) * static_cast<double>(n) /
                                  static_cast<double>(total)));
    }
    SceneMesh m = ClusterMesh(*bvhs[i], budget);
    const int env_count = environment.num_objects();
    if (static_cast<int>(i) < env_count) {
      m.kind = "environment";
      // The file name only: a browser has no business with server paths.
      m.name =
          std::filesystem::path(environment.object(static_cast<int>(i)).name).filename().string();
    } else {
      m.kind = "object";
      m.object_id = objects[i - static_cast<size_t>(env_count)].object_id;
      m.name = m.object_id;
    }
    scene.meshes.push_back(std::move(m));
  }
  nlohmann::ordered_json j;
  j["max_triangles"] = max_triangles;
  nlohmann::ordered_json list = nlohmann::ordered_json::array();
  for (size_t i = 0; i < scene.meshes.size(); ++i) {
    const SceneMesh& m = scene.meshes[i];
    nlohmann::ordered_json e;
    e["index"] = i;
    e["kind"] = m.kind;
    e["name"] = m.name;
    if (m.kind == "object") e["object_id"] = m.object_id;
    e["triangles"] = m.triangles;
    e["source_triangles"] = m.source_triangles;
    e["vertices"] = m.vertices;
    e["url"] = "/scene/" + std::to_string(i) + ".bin";
    e["min"] = {m.min[0], m.min[1], m.min[2]};
    e["max"] = {m.max[0], m.max[1], m.max[2]};
    list.push_back(std::move(e));
  }
  j["meshes"] = std::move(list);
  scene.json = j.dump();
  return scene;
}

}  // namespace sweptccd::ws
