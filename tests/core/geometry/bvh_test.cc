// TriangleBvh (core/bvh.h) and the culling of CcdEngine against brute force:
//   - the hierarchy's structure: every triangle in exactly one leaf, leaves of
//     1..kMaxLeafSize triangles, every node box contains the triangles below
//     it, the depth fits the fixed traversal stack;
//   - QueryCapsule never misses a triangle within the radius of the segment
//     (exact SegmentTriangleDistance over all triangles), on seeded random
//     soups (degenerate, huge, tiny, coincident centroids, flat, deep) and on
//     real meshes;
//   - CcdEngine::Separation equals the minimum over all triangles;
//   - the query's link culling (QueryStats.links_culled) never culls a link
//     that touches at a sampled s, on a 16-link avatar from real mocap.

#include "core/geometry/bvh.h"

#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <limits>
#include <random>
#include <string>
#include <vector>

#include "core/query/ccd_query.h"
#include "core/scene/collision_filter.h"
#include "core/geometry/distance.h"
#include "core/scene/environment.h"
#include "core/geometry/mesh.h"
#include "mocap/mocap_import.h"
#include "core/avatar/motion.h"
#include "core/avatar/pose.h"
#include "core/avatar/skeleton.h"
#include "tests/common/brute_force.h"
#include "tests/common/test_scale.h"

namespace sweptccd {
namespace {

using Eigen::Vector3d;
using Eigen::Vector3f;

const std::string kData = SWEPTCCD_DATA_DIR;

// --- Random soups ----------------------------------------------------------

struct Soup {
  std::string name;
  TriangleMesh mesh;
};

Vector3f RandomUnit(std::mt19937_64& rng) {
  std::normal_distribution<double> g(0, 1);
  Vector3d v(g(rng), g(rng), g(rng));
  if (v.norm() < 1e-9) v = Vector3d::UnitX();
  return v.normalized().cast<float>();
}

double Uniform(std::mt19937_64& rng, double lo, double hi) {
  return std::uniform_real_distribution<double>(lo, hi)(rng);
}

double LogUniform(std::mt19937_64& rng, double lo, double hi) {
  return std::pow(10.0, Uniform(rng, std::log10(lo), std::log10(hi)));
}

void AddTriangle(TriangleMesh* mesh, const Vector3f& a, const Vector3f& b, const Vector3f& c) {
  const uint32_t base = static_cast<uint32_t>(mesh->vertices.size());
  mesh->vertices.push_back(a);
  mesh->vertices.push_back(b);
  mesh->vertices.push_back(c);
  mesh->indices.insert(mesh->indices.end(), {base, base + 1, base + 2});
}

// A mix of everything: ordinary, degenerate (collinear, two equal vertices,
// a point), huge, tiny, and triangles sharing bounding-box centres.
TriangleMesh MixedSoup(std::mt19937_64& rng, int n, double half_extent) {
  TriangleMesh mesh;
  std::vector<Vector3f> centres;
  for (int k = 0; k < 4; ++k) {
    centres.push_back(Vector3f(static_cast<float>(Uniform(rng, -half_extent, half_extent)),
                               static_cast<float>(Uniform(rng, -half_extent, half_extent)),
                               static_cast<float>(Uniform(rng, -half_extent, half_extent))));
  }
  // Reuse shared vertices sometimes (indexed meshes).
  for (int t = 0; t < n; ++t) {
    const Vector3f c(static_cast<float>(Uniform(rng, -half_extent, half_extent)),
                     static_cast<float>(Uniform(rng, -half_extent, half_extent)),
                     static_cast<float>(Uniform(rng, -half_extent, half_extent)));
    const int kind = static_cast<int>(rng() % 20);
    if (kind < 8) {  // Ordinary.
      const float size = static_cast<float>(LogUniform(rng, 1e-3, 3));
      AddTriangle(&mesh, c + size * RandomUnit(rng), c + size * RandomUnit(rng),
                  c + size * RandomUnit(rng));
    } else if (kind < 10) {  // Collinear.
      const Vector3f d = static_cast<float>(LogUniform(rng, 1e-3, 2)) * RandomUnit(rng);
      AddTriangle(&mesh, c, c + d, c + static_cast<float>(Uniform(rng, -1, 2)) * d);
    } else if (kind == 10) {  // A point.
      AddTriangle(&mesh, c, c, c);
    } else if (kind == 11) {  // Two equal vertices.
      const Vector3f d = static_cast<float>(LogUniform(rng, 1e-3, 2)) * RandomUnit(rng);
      AddTriangle(&mesh, c, c + d, c);
    } else if (kind == 12) {  // Huge.
      const float size = static_cast<float>(LogUniform(rng, 20, 300));
      AddTriangle(&mesh, c + size * RandomUnit(rng), c + size * RandomUnit(rng),
                  c + size * RandomUnit(rng));
    } else if (kind < 15) {  // Tiny.
      const float size = static_cast<float>(LogUniform(rng, 1e-7, 1e-4));
      AddTriangle(&mesh, c + size * RandomUnit(rng), c + size * RandomUnit(rng),
                  c + size * RandomUnit(rng));
    } else if (kind < 18) {  // Symmetric about a shared centre: same box centre.
      const Vector3f& cc = centres[rng() % centres.size()];
      const Vector3f u = static_cast<float>(LogUniform(rng, 1e-2, 1)) * RandomUnit(rng);
      const Vector3f w = static_cast<float>(Uniform(rng, -1, 1)) * u;
      AddTriangle(&mesh, cc + u, cc - u, cc + w);
    } else {  // A copy (or rotation) of an earlier triangle: identical centre.
      if (mesh.num_triangles() == 0) {
        AddTriangle(&mesh, c, c + Vector3f(1, 0, 0), c + Vector3f(0, 1, 0));
        continue;
      }
      const size_t src = rng() % mesh.num_triangles();
      const uint32_t i0 = mesh.indices[3 * src], i1 = mesh.indices[3 * src + 1],
                     i2 = mesh.indices[3 * src + 2];
      if (rng() % 2) {
        mesh.indices.insert(mesh.indices.end(), {i1, i2, i0});  // Shares vertices.
      } else {
        const Vector3f a = mesh.vertices[i0], b = mesh.vertices[i1], cv = mesh.vertices[i2];
        AddTriangle(&mesh, a, b, cv);
      }
    }
  }
  return mesh;
}

// Every triangle has exactly the same bounding box centre (and many are
// identical): the SAH finds no split and must fall back.
TriangleMesh CoincidentSoup(std::mt19937_64& rng, int n) {
  TriangleMesh mesh;
  const Vector3f c(0.5f, -0.25f, 2.0f);
  for (int t = 0; t < n; ++t) {
    if (t % 3 == 0) {
      AddTriangle(&mesh, c + Vector3f(-1, -1, 0), c + Vector3f(1, 1, 0), c + Vector3f(1, -1, 0));
    } else {
      // Power-of-two sizes keep c +- u exact in floats.
      const float k = std::ldexp(1.0f, -static_cast<int>(rng() % 10));
      const Vector3f u = k * Vector3f(1, 0.5f, 0.25f);
      const Vector3f w = k * Vector3f(0.5f, -0.5f, 0);
      AddTriangle(&mesh, c + u, c - u, c + w);
    }
  }
  return mesh;
}

// All triangles in the plane z = 1 (zero extent on one axis).
TriangleMesh FlatSoup(std::mt19937_64& rng, int n) {
  TriangleMesh mesh;
  for (int t = 0; t < n; ++t) {
    const Vector3f c(static_cast<float>(Uniform(rng, -3, 3)), static_cast<float>(Uniform(rng, -3, 3)),
                     1.0f);
    auto v = [&]() -> Vector3f {
      const float s = static_cast<float>(LogUniform(rng, 1e-3, 0.5));
      return c + Vector3f(static_cast<float>(Uniform(rng, -s, s)),
                          static_cast<float>(Uniform(rng, -s, s)), 0.0f);
    };
    AddTriangle(&mesh, v(), v(), v());
  }
  return mesh;
}

// Centres at geometrically shrinking distances (and a far cluster): binned
// SAH peels off a few triangles per level, so the tree gets deep and the
// build's depth limit (median split) takes over.
TriangleMesh DeepSoup(std::mt19937_64& rng, int n) {
  TriangleMesh mesh;
  for (int t = 0; t < n; ++t) {
    const float x = std::ldexp(1.0f, -(t % 120));  // 1, 1/2, ... 2^-119.
    const float s = x * 0.01f;
    const Vector3f c(x, static_cast<float>(t % 7) * 1e-3f, 0);
    if (t % 10 == 0) {
      AddTriangle(&mesh, c + Vector3f(1000, 0, 0), c + Vector3f(1000, 1, 0), c + Vector3f(1001, 0, 0));
    } else {
      AddTriangle(&mesh, c, c + s * RandomUnit(rng), c + s * RandomUnit(rng));
    }
  }
  return mesh;
}

// A geometric ladder: rung k is a thin triangle at x ~ -16^k, k in [-28, 32).
// At every level the farthest rung sits alone in the first of the 16 SAH bins
// and all the others in the last, so SAH peels one rung per level: without
// the build's depth limit the tree would be ~60 deep.
TriangleMesh LadderSoup(std::mt19937_64& rng, int n) {
  TriangleMesh mesh;
  for (int t = 0; t < n; ++t) {
    const int k = 31 - t % 60;
    const float u = std::ldexp(1.0f, 4 * k);
    // Thin in y and z (relative to the rung below x = 1), so x stays the axis to split.
    const float h = 1e-3f * std::min(u, 1.0f);
    const float y = static_cast<float>(Uniform(rng, 0, 1)) * h;
    AddTriangle(&mesh, {-1.0f * u, y, 0}, {-1.1f * u, y + h, 0}, {-1.05f * u, y, h});
  }
  return mesh;
}

std::vector<Soup> MakeSoups() {
  std::mt19937_64 rng(20240611);
  std::vector<Soup> soups;
  soups.push_back({"single", MixedSoup(rng, 1, 1)});
  soups.push_back({"three", MixedSoup(rng, 3, 1)});
  soups.push_back({"five", MixedSoup(rng, 5, 1)});
  soups.push_back({"mixed_small", MixedSoup(rng, 60, 2)});
  soups.push_back({"mixed", MixedSoup(rng, 2500, 5)});
  soups.push_back({"mixed_far", MixedSoup(rng, 800, 3000)});  // Large coordinates.
  soups.push_back({"coincident", CoincidentSoup(rng, 600)});
  soups.push_back({"flat", FlatSoup(rng, 1200)});
  soups.push_back({"deep", DeepSoup(rng, 3000)});
  soups.push_back({"ladder", LadderSoup(rng, 120)});
  soups.push_back({"ladder_wide", LadderSoup(rng, 1200)});
  return soups;
}

// --- Structure -----------------------------------------------------------

Vector3d MeshVertex(const TriangleMesh& mesh, size_t t, int v) {
  return mesh.vertices[mesh.indices[3 * t + v]].cast<double>();
}

bool BoxContains(const Aabb& box, const Vector3d& p) {
  return (box.lo.array() <= p.array()).all() && (p.array() <= box.hi.array()).all();
}

// Walks the tree: every slot in exactly one leaf, leaf sizes, child indices,
// every node box containing every triangle below it, depth. Returns the depth.
int CheckStructure(const TriangleBvh& bvh, const TriangleMesh& mesh) {
  const auto& nodes = bvh.nodes();
  const size_t n = mesh.num_triangles();
  EXPECT_EQ(bvh.num_triangles(), n);
  EXPECT_FALSE(nodes.empty());
  if (nodes.empty()) return 0;
  // Slots hold the mesh's triangles, each id once.
  std::vector<int> id_seen(n, 0);
  for (uint32_t slot = 0; slot < n; ++slot) {
    const uint32_t id = bvh.TriangleId(slot);
    EXPECT_LT(id, n);
    if (id >= n) return 0;
    ++id_seen[id];
    Vector3d a, b, c;
    bvh.Triangle(slot, &a, &b, &c);
    EXPECT_EQ(a, MeshVertex(mesh, id, 0)) << "slot " << slot;
    EXPECT_EQ(b, MeshVertex(mesh, id, 1)) << "slot " << slot;
    EXPECT_EQ(c, MeshVertex(mesh, id, 2)) << "slot " << slot;
  }
  for (size_t id = 0; id < n; ++id) EXPECT_EQ(id_seen[id], 1) << "triangle id " << id;

  std::vector<int> slot_seen(n, 0);
  std::vector<int> node_seen(nodes.size(), 0);
  int max_depth = 0;
  struct Item {
    uint32_t node;
    int depth;
    std::vector<uint32_t> ancestors;
  };
  // Iterative DFS; keep the ancestor chain to check containment in every
  // ancestor box, not only the parent's.
  std::vector<Item> stack{{0, 0, {}}};
  while (!stack.empty()) {
    Item item = std::move(stack.back());
    stack.pop_back();
    EXPECT_LT(item.node, nodes.size());
    if (item.node >= nodes.size()) continue;
    EXPECT_EQ(node_seen[item.node]++, 0) << "node " << item.node << " reached twice";
    max_depth = std::max(max_depth, item.depth);
    const TriangleBvh::Node& node = nodes[item.node];
    const Aabb box = bvh.NodeBox(item.node);
    EXPECT_TRUE((box.lo.array() <= box.hi.array()).all()) << "node " << item.node;
    item.ancestors.push_back(item.node);
    if (node.count == 0) {
      EXPECT_GT(node.first, item.node) << "children after their parent";
      EXPECT_LT(node.first + 1, nodes.size());
      if (node.first + 1 >= nodes.size() || node.first <= item.node) continue;
      // Child boxes inside this box.
      for (uint32_t child : {node.first, node.first + 1}) {
        const Aabb cb = bvh.NodeBox(child);
        EXPECT_TRUE(BoxContains(box, cb.lo) && BoxContains(box, cb.hi))
            << "child " << child << " sticks out of node " << item.node;
        stack.push_back({child, item.depth + 1, item.ancestors});
      }
      continue;
    }
    EXPECT_LE(node.count, static_cast<uint32_t>(TriangleBvh::kMaxLeafSize)) << "leaf " << item.node;
    EXPECT_LE(static_cast<size_t>(node.first) + node.count, n) << "leaf " << item.node;
    for (uint32_t slot = node.first; slot < node.first + node.count && slot < n; ++slot) {
      ++slot_seen[slot];
      Vector3d v[3];
      bvh.Triangle(slot, &v[0], &v[1], &v[2]);
      for (uint32_t anc : item.ancestors) {
        const Aabb ab = bvh.NodeBox(anc);
        for (const Vector3d& p : v) {
          EXPECT_TRUE(BoxContains(ab, p))
              << "slot " << slot << " vertex " << p.transpose() << " outside node " << anc;
        }
      }
    }
  }
  for (size_t slot = 0; slot < n; ++slot) EXPECT_EQ(slot_seen[slot], 1) << "slot " << slot;
  for (size_t k = 0; k < nodes.size(); ++k) EXPECT_EQ(node_seen[k], 1) << "node " << k << " unreachable";
  // The traversal stack holds 128 entries; each level adds at most one.
  EXPECT_LE(max_depth, 48 + static_cast<int>(std::ceil(std::log2(std::max<size_t>(n, 2)))) + 1);
  EXPECT_LT(max_depth, 126);
  double max_abs = 0;
  for (size_t t = 0; t < n; ++t) {
    for (int v = 0; v < 3; ++v) max_abs = std::max(max_abs, MeshVertex(mesh, t, v).cwiseAbs().maxCoeff());
  }
  EXPECT_EQ(bvh.max_abs_coordinate(), max_abs);
  return max_depth;
}

// --- Capsules --------------------------------------------------------------

struct Capsule {
  Vector3d p0, p1;
  double radius;
};

std::vector<uint32_t> SubtreeSlots(const TriangleBvh& bvh, uint32_t node) {
  std::vector<uint32_t> out, stack{node};
  while (!stack.empty()) {
    const TriangleBvh::Node& nd = bvh.nodes()[stack.back()];
    stack.pop_back();
    if (nd.count == 0) {
      stack.push_back(nd.first);
      stack.push_back(nd.first + 1);
    } else {
      for (uint32_t s = nd.first; s < nd.first + nd.count; ++s) out.push_back(s);
    }
  }
  return out;
}

// Returns the number of triangles within the radius (brute force); fails when
// QueryCapsule misses one or visits a slot twice.
size_t CheckCapsule(const TriangleBvh& bvh, const Capsule& cap, const std::string& what,
                    uint32_t start_node = 0) {
  std::vector<int> visited(bvh.num_triangles(), 0);
  bvh.QueryCapsule(
      cap.p0, cap.p1, cap.radius,
      [&](uint32_t slot) {
        EXPECT_LT(slot, visited.size()) << what;
        if (slot < visited.size()) ++visited[slot];
      },
      start_node);
  std::vector<uint32_t> slots;
  if (start_node == 0) {
    slots.resize(bvh.num_triangles());
    for (uint32_t s = 0; s < slots.size(); ++s) slots[s] = s;
  } else {
    slots = SubtreeSlots(bvh, start_node);
    std::vector<char> in(bvh.num_triangles(), 0);
    for (uint32_t s : slots) in[s] = 1;
    for (uint32_t s = 0; s < visited.size(); ++s) {
      EXPECT_FALSE(visited[s] && !in[s]) << what << ": slot " << s << " outside start node";
    }
  }
  size_t within = 0;
  int misses = 0;
  for (uint32_t slot : slots) {
    EXPECT_LE(visited[slot], 1) << what << ": slot " << slot << " visited twice";
    Vector3d a, b, c;
    bvh.Triangle(slot, &a, &b, &c);
    const double d = SegmentTriangleDistance(cap.p0, cap.p1, a, b, c).distance;
    if (d <= cap.radius) {
      ++within;
      if (!visited[slot] && ++misses <= 3) {
        ADD_FAILURE() << what << ": missed slot " << slot << " (triangle "
                      << bvh.TriangleId(slot) << ") at distance " << d << " <= radius "
                      << cap.radius << "; segment " << cap.p0.transpose() << " -> "
                      << cap.p1.transpose() << "; triangle " << a.transpose() << " | "
                      << b.transpose() << " | " << c.transpose();
      }
    }
  }
  return within;
}

Vector3d RandomPointIn(std::mt19937_64& rng, const Aabb& box) {
  return Vector3d(Uniform(rng, box.lo.x(), box.hi.x()), Uniform(rng, box.lo.y(), box.hi.y()),
                  Uniform(rng, box.lo.z(), box.hi.z()));
}

// Random capsules of every shape near a mesh whose box is `box` and typical
// size `scale`: random, spheres, axis-aligned, tiny/denormal directions, zero
// radius, exactly touching (radius = the distance to some triangle), huge.
Capsule RandomCapsule(std::mt19937_64& rng, const TriangleBvh& bvh, const Aabb& box, double scale) {
  Aabb grown = box;
  const Vector3d margin = Vector3d::Constant(0.2 * scale) + 0.1 * (box.hi - box.lo);
  grown.lo -= margin;
  grown.hi += margin;
  Capsule c;
  // Start near a random triangle half of the time, so capsules hit things.
  const uint32_t slot = static_cast<uint32_t>(rng() % bvh.num_triangles());
  Vector3d ta, tb, tc;
  bvh.Triangle(slot, &ta, &tb, &tc);
  c.p0 = rng() % 2 ? RandomPointIn(rng, grown)
                   : Vector3d(ta + Uniform(rng, -0.3, 0.3) * scale * RandomUnit(rng).cast<double>());
  const double len = LogUniform(rng, 1e-4 * scale, 2 * scale);
  c.p1 = c.p0 + len * RandomUnit(rng).cast<double>();
  c.radius = LogUniform(rng, 1e-5 * scale, 0.5 * scale);
  switch (rng() % 12) {
    case 0: c.p1 = c.p0; break;  // Sphere.
    case 1: {                    // Axis-aligned.
      const int k = static_cast<int>(rng() % 3);
      c.p1 = c.p0;
      c.p1[k] += len * (rng() % 2 ? 1 : -1);
      break;
    }
    case 2: {  // Two coordinates equal.
      const int k = static_cast<int>(rng() % 3);
      c.p1[k] = c.p0[k];
      break;
    }
    case 3: {  // Denormal / tiny direction: 1/d overflows.
      c.p1 = c.p0;
      c.p1[rng() % 3] += (rng() % 2 ? 1e-310 : 1e-200);
      break;
    }
    case 4: c.radius = 0; break;
    case 5:
    case 6: {  // Exactly touching a triangle (closed sets count).
      c.radius = SegmentTriangleDistance(c.p0, c.p1, ta, tb, tc).distance;
      break;
    }
    case 7: c.radius = LogUniform(rng, scale, 50 * scale); break;  // Huge.
    default: break;
  }
  return c;
}

// --- Tests -----------------------------------------------------------------

TEST(BvhTest, RandomSoupsStructureAndNoMissedTriangle) {
  std::mt19937_64 rng(77);
  for (const Soup& soup : MakeSoups()) {
    SCOPED_TRACE(soup.name);
    const TriangleBvh bvh(soup.mesh);
    const int depth = CheckStructure(bvh, soup.mesh);
    const Aabb box = bvh.bounds();
    const double scale = std::max(1e-3, std::min(2.0, (box.hi - box.lo).maxCoeff()));
    size_t within = 0;
    const int capsules = testing::ScaledCount(soup.mesh.num_triangles() > 1000 ? 250 : 400);
    for (int k = 0; k < capsules; ++k) {
      const Capsule cap = RandomCapsule(rng, bvh, box, scale);
      within += CheckCapsule(bvh, cap, soup.name + " capsule " + std::to_string(k));
    }
    // From inner nodes too (the query restarts below the root).
    for (int k = 0; k < 40 && bvh.nodes().size() > 1; ++k) {
      const uint32_t node = static_cast<uint32_t>(rng() % bvh.nodes().size());
      const Capsule cap = RandomCapsule(rng, bvh, box, scale);
      CheckCapsule(bvh, cap, soup.name + " from node " + std::to_string(node), node);
    }
    std::printf("%-12s %5zu triangles, %6zu nodes, depth %3d, %zu hits within radius\n",
                soup.name.c_str(), soup.mesh.num_triangles(), bvh.nodes().size(), depth, within);
    EXPECT_GT(within, 0u);
  }
}

TEST(BvhTest, LadderSoupUsesTheDepthLimit) {
  std::mt19937_64 rng(5);
  const TriangleMesh mesh = LadderSoup(rng, 60);
  const TriangleBvh bvh(mesh);
  const int depth = CheckStructure(bvh, mesh);
  // SAH alone would go ~60 deep; the median split past depth 48 bounds it.
  EXPECT_GE(depth, 48);
  EXPECT_LE(depth, 48 + 6);
  // Queries reach every rung, down to the bottom of the ladder.
  for (int k = -28; k < 32; ++k) {
    const double u = std::ldexp(1.0, 4 * k);
    Capsule cap{Vector3d(-1.05 * u, 0, -1), Vector3d(-1.05 * u, 0, 1), 2e-3 * std::min(u, 1.0)};
    EXPECT_GE(CheckCapsule(bvh, cap, "ladder rung " + std::to_string(k)), 1u);
  }
}

// A capsule whose distance to a triangle equals its radius (touching) in
// large coordinates, where float storage and the slab test round.
TEST(BvhTest, TouchingCapsulesAtLargeCoordinates) {
  std::mt19937_64 rng(99);
  for (double offset : {0.0, 1e3, 1e5, -3e6}) {
    TriangleMesh mesh;
    for (int t = 0; t < 400; ++t) {
      const Vector3f c = (Vector3d::Constant(offset) + Vector3d(Uniform(rng, -5, 5), Uniform(rng, -5, 5), Uniform(rng, -5, 5))).cast<float>();
      AddTriangle(&mesh, c, c + 0.3f * RandomUnit(rng), c + 0.3f * RandomUnit(rng));
    }
    const TriangleBvh bvh(mesh);
    CheckStructure(bvh, mesh);
    for (int k = 0; k < 300; ++k) {
      const uint32_t slot = static_cast<uint32_t>(rng() % bvh.num_triangles());
      Vector3d a, b, c;
      bvh.Triangle(slot, &a, &b, &c);
      Capsule cap;
      cap.p0 = a + Vector3d(Uniform(rng, -1, 1), Uniform(rng, -1, 1), Uniform(rng, -1, 1));
      cap.p1 = k % 3 == 0 ? cap.p0 : Vector3d(cap.p0 + Vector3d(Uniform(rng, -1, 1), 0, Uniform(rng, -1, 1)));
      cap.radius = SegmentTriangleDistance(cap.p0, cap.p1, a, b, c).distance;
      CheckCapsule(bvh, cap, "offset " + std::to_string(offset) + " capsule " + std::to_string(k));
    }
  }
}

struct RealMesh {
  const char* file;
  int capsules;
};

class RealMeshBvhTest : public ::testing::TestWithParam<RealMesh> {};

TEST_P(RealMeshBvhTest, StructureAndNoMissedTriangle) {
  const std::string path = kData + "/env/" + GetParam().file;
  const TriangleMesh mesh = LoadMeshFile(path);  // Throws (fails) when missing.
  const TriangleBvh bvh(mesh);
  const int depth = CheckStructure(bvh, mesh);
  const Aabb box = bvh.bounds();
  const double size = (box.hi - box.lo).maxCoeff();
  // Avatar-sized capsules for rooms, proportionally sized ones for small scans.
  const double scale = size > 3 ? 0.3 : 0.1 * size;
  std::mt19937_64 rng(4242);
  size_t within = 0;
  for (int k = 0; k < testing::ScaledCount(GetParam().capsules); ++k) {
    const Capsule cap = RandomCapsule(rng, bvh, box, scale);
    within += CheckCapsule(bvh, cap, std::string(GetParam().file) + " capsule " + std::to_string(k));
  }
  std::printf("%s: %zu triangles, %zu nodes, depth %d, %zu hits within radius\n", GetParam().file,
              mesh.num_triangles(), bvh.nodes().size(), depth, within);
  EXPECT_GT(within, 0u);
}

INSTANTIATE_TEST_SUITE_P(RealData, RealMeshBvhTest,
                         ::testing::Values(RealMesh{"stanford_bunny.obj.gz", 200},
                                           RealMesh{"stanford_dragon_vrip_res4.ply.gz", 400},
                                           RealMesh{"morse_apartment.ply.gz", 400}),
                         [](const ::testing::TestParamInfo<RealMesh>& info) {
                           std::string name = info.param.file;
                           for (char& ch : name) {
                             if (!std::isalnum(static_cast<unsigned char>(ch))) ch = '_';
                           }
                           return name;
                         });

// --- CcdEngine::Separation -------------------------------------------------

Skeleton ChainSkeleton(int n) {
  std::vector<Link> links(n);
  for (int i = 0; i < n; ++i) {
    links[i].name = "link" + std::to_string(i);
    links[i].parent = i - 1;
    links[i].a_L = Vector3d(0, 0, 0);
    links[i].b_L = i % 3 == 2 ? Vector3d(0, 0, 0) : Vector3d(0, 0.3, 0);  // Some spheres.
    links[i].radius = 0.03 + 0.02 * i;
  }
  return Skeleton::FromLinks("chain", links, "chain");
}

Pose RandomPose(std::mt19937_64& rng, int n, const Aabb& box, int64_t utime) {
  Pose pose;
  pose.utime = utime;
  for (int i = 0; i < n; ++i) {
    LinkPose lp;
    lp.p = RandomPointIn(rng, box);
    lp.q = Eigen::Quaterniond(Uniform(rng, -1, 1), Uniform(rng, -1, 1), Uniform(rng, -1, 1),
                              Uniform(rng, -1, 1));
    lp.q.normalize();
    pose.links.push_back(lp);
  }
  return pose;
}

using testing::BruteForceNearest;
using testing::BruteNearest;

// Finds the triangle `id` of object `o` (slots are in BVH order).
void TriangleById(const TriangleBvh& bvh, uint32_t id, Vector3d* a, Vector3d* b, Vector3d* c) {
  for (uint32_t slot = 0; slot < bvh.num_triangles(); ++slot) {
    if (bvh.TriangleId(slot) == id) {
      bvh.Triangle(slot, a, b, c);
      return;
    }
  }
  ADD_FAILURE() << "no triangle with id " << id;
}

TEST(BvhTest, SeparationMatchesBruteForceOverAllTriangles) {
  std::mt19937_64 rng(31337);
  Environment env;
  env.AddMesh(MixedSoup(rng, 700, 1.5), "soup");
  TriangleMesh dragon = LoadMeshFile(kData + "/env/stanford_dragon_vrip_res4.ply.gz");
  for (Vector3f& v : dragon.vertices) v = v * 6.0f + Vector3f(0.5f, -0.6f, 0.2f);
  env.AddMesh(dragon, "dragon");
  env.AddMesh(FlatSoup(rng, 200), "flat");
  const Skeleton skel = ChainSkeleton(5);
  Aabb box{Vector3d(-2, -2, -1), Vector3d(2, 2, 2)};

  for (int variant = 0; variant < 2; ++variant) {
    CollisionFilter filter(skel.num_links(), env.num_objects());
    if (variant == 1) {
      filter.Ignore(LinkIndex(0), kAllObjects);  // Link 0 ignores everything.
      filter.Ignore(LinkIndex(1), ObjectIndex(1));  // Link 1 ignores the dragon.
      filter.Ignore(kAllLinks, ObjectIndex(2));     // Nobody sees the flat soup.
    }
    const CcdEngine engine(skel, env, filter);
    int found = 0, not_found = 0;
    for (int trial = 0; trial < testing::ScaledCount(60); ++trial) {
      const Pose p0 = RandomPose(rng, skel.num_links(), box, 0);
      const Pose p1 = RandomPose(rng, skel.num_links(), box, 33333);
      const MotionModel model = trial % 2 ? MotionModel::kIndependent : MotionModel::kArticulated;
      const PairMotion motion(skel, p0, p1, model);
      for (int k = 0; k < 6; ++k) {
        const LinkIndex link(static_cast<int>(rng() % skel.num_links()));
        const double s = k == 0 ? 0.0 : k == 1 ? 1.0 : Uniform(rng, 0, 1);
        const double search = std::vector<double>{0.0, 1e-3, 0.05, 0.4, 10.0, -1.0}[rng() % 6];
        Vector3d a, b;
        motion.SegmentAt(link, s, &a, &b);
        const double radius = skel.link(link).radius;
        const BruteNearest brute = BruteForceNearest(env, filter, link, a, b);
        const bool expect_found = brute.any && brute.distance <= radius + std::max(0.0, search);
        ContactRecord rec;
        const bool got = engine.Separation(motion, link, s, search, &rec);
        SCOPED_TRACE("variant " + std::to_string(variant) + " trial " + std::to_string(trial) +
                     " link " + std::to_string(link) + " s " + std::to_string(s) + " search " +
                     std::to_string(search) + " brute " + std::to_string(brute.distance - radius));
        ASSERT_EQ(got, expect_found);
        if (!got) {
          ++not_found;
          continue;
        }
        ++found;
        EXPECT_EQ(rec.separation, brute.distance - radius);
        EXPECT_EQ(rec.link, link);
        EXPECT_EQ(rec.s, s);
        ASSERT_GE(rec.object, 0);
        ASSERT_LT(rec.object, env.num_objects());
        EXPECT_FALSE(filter.Ignores(link, rec.object));
        Vector3d ta, tb, tc;
        TriangleById(env.object(rec.object).bvh, rec.triangle, &ta, &tb, &tc);
        EXPECT_EQ(SegmentTriangleDistance(a, b, ta, tb, tc).distance, brute.distance)
            << "the reported triangle is not a nearest one";
        // Witness points: on the segment, on the triangle, as far apart as the distance.
        Vector3d on_seg;
        ClosestPointOnSegment(rec.point_link, a, b, &on_seg);
        EXPECT_LT((on_seg - rec.point_link).norm(), 1e-9);
        EXPECT_LT((ClosestPointOnTriangle(rec.point_env, ta, tb, tc) - rec.point_env).norm(), 1e-9);
        EXPECT_NEAR((rec.point_link - rec.point_env).norm(), brute.distance, 1e-9);
        EXPECT_NEAR(rec.normal.norm(), 1.0, 1e-12);
        if (brute.distance > 1e-9) {
          EXPECT_GT(rec.normal.dot(rec.point_link - rec.point_env), 0.999 * brute.distance);
        }
      }
    }
    std::printf("Separation variant %d: %d found, %d beyond the search radius\n", variant, found,
                not_found);
    // A scaled run (tests/common/test_scale.h): the minimums scaled alike.
    EXPECT_GT(found, testing::ScaledMinimum(50));
    EXPECT_GT(not_found, testing::ScaledMinimum(20));
  }
}

// --- Link culling in the query ---------------------------------------------

// Brute force: the earliest sampled s at which `link` touches (distance <=
// radius to some unfiltered triangle), or -1.
double EarliestTouchingSample(const Environment& env, const CollisionFilter& filter,
                              const Skeleton& skel, const PairMotion& motion, LinkIndex link,
                              int samples) {
  for (int k = 0; k <= samples; ++k) {
    const double s = static_cast<double>(k) / samples;
    Vector3d a, b;
    motion.SegmentAt(link, s, &a, &b);
    const BruteNearest n = BruteForceNearest(env, filter, link, a, b);
    if (n.any && n.distance <= skel.link(link).radius) return s;
  }
  return -1;
}

TEST(BvhTest, QueryNeverCullsATouchingLink) {
  MocapImportOptions options;
  options.frame_step = 4;  // 30 Hz.
  MocapClip clip = ImportBvhFile(kData + "/mocap/cmu_02_01_walk.bvh.gz", options);
  ASSERT_EQ(clip.skeleton.num_links(), 16);
  ASSERT_GT(clip.poses.size(), 40u);
  const Skeleton& skel = clip.skeleton;

  // The box swept by the avatar.
  Aabb swept{Vector3d::Constant(1e30), Vector3d::Constant(-1e30)};
  for (const Pose& pose : clip.poses) {
    for (const LinkPose& lp : pose.links) {
      swept.lo = swept.lo.cwiseMin(lp.p);
      swept.hi = swept.hi.cwiseMax(lp.p);
    }
  }
  // Small random triangles through the swept volume (they clip hands, knees,
  // heads...) and a floor patch slightly above the lowest foot point.
  std::mt19937_64 rng(808);
  TriangleMesh clutter;
  for (int t = 0; t < 260; ++t) {
    const Vector3d c = RandomPointIn(rng, swept);
    const float size = static_cast<float>(LogUniform(rng, 0.01, 0.25));
    const Vector3f cf = c.cast<float>();
    if (t % 13 == 0) {
      AddTriangle(&clutter, cf, cf, cf);  // Degenerate: a point.
    } else {
      AddTriangle(&clutter, cf + size * RandomUnit(rng), cf + size * RandomUnit(rng),
                  cf + size * RandomUnit(rng));
    }
  }
  TriangleMesh floor;
  const float y = static_cast<float>(swept.lo.y()) - 0.06f;
  const float x0 = static_cast<float>(swept.lo.x()) - 1, x1 = static_cast<float>(swept.hi.x()) + 1;
  const float z0 = static_cast<float>(swept.lo.z()) - 1, z1 = static_cast<float>(swept.hi.z()) + 1;
  AddTriangle(&floor, {x0, y, z0}, {x1, y, z0}, {x1, y, z1});
  AddTriangle(&floor, {x0, y, z0}, {x1, y, z1}, {x0, y, z1});
  Environment env;
  env.AddMesh(clutter, "clutter");
  env.AddMesh(floor, "floor");

  int total_culled = 0, total_touching = 0, pairs = 0, contact_pairs = 0;
  for (int variant = 0; variant < 2; ++variant) {
    CollisionFilter filter(skel.num_links(), env.num_objects());
    if (variant == 1) {
      filter.Ignore(LinkIndex(skel.FindLink("foot_l")), ObjectIndex(1));
      filter.Ignore(LinkIndex(skel.FindLink("foot_r")), ObjectIndex(1));
      filter.Ignore(LinkIndex(skel.FindLink("head")), kAllObjects);
    }
    const CcdEngine engine(skel, env, filter);
    QueryOptions per_link;
    per_link.per_link = true;
    QueryOptions first;
    const size_t stride = static_cast<size_t>(testing::ScaledStride());  // 1 in the full run.
    for (size_t k = 1; k + 1 < clip.poses.size() && k < 36; k += stride) {
      const Pose& p0 = clip.poses[k];
      const Pose& p1 = clip.poses[k + 1];
      const PairMotion motion(skel, p0, p1, MotionModel::kArticulated);
      std::vector<double> touch(skel.num_links(), -1);
      int touching = 0;
      double earliest = 2;
      for (int l = 0; l < skel.num_links(); ++l) {
        touch[l] = EarliestTouchingSample(env, filter, skel, motion, LinkIndex(l), 32);
        if (touch[l] >= 0) {
          ++touching;
          earliest = std::min(earliest, touch[l]);
        }
      }
      const QueryResult r = engine.Query(p0, p1, per_link);
      SCOPED_TRACE("variant " + std::to_string(variant) + " pair " + std::to_string(k));
      int ignored_all = 0;
      for (LinkIndex l(0); l < skel.num_links(); ++l) ignored_all += filter.IgnoresAll(l);
      EXPECT_EQ(r.stats.links_culled + r.stats.links_tested + ignored_all, skel.num_links());
      EXPECT_GE(r.stats.links_tested, touching) << "a touching link was culled";
      for (int l = 0; l < skel.num_links(); ++l) {
        if (touch[l] < 0) continue;
        const auto it = std::find_if(r.links.begin(), r.links.end(),
                                     [&](const LinkBracket& b) { return b.link == l; });
        if (it == r.links.end()) {
          ADD_FAILURE() << "link " << l << " (" << skel.link(l).name << ") touches at s = "
                        << touch[l] << " but has no bracket (culled or missed)";
          continue;
        }
        EXPECT_LE(it->s_lo, touch[l]) << "link " << l << ": G1 broken";
      }
      const QueryResult f = engine.Query(p0, p1, first);
      if (touching > 0) {
        EXPECT_TRUE(f.contact);
        if (f.contact) {
          EXPECT_LE(f.s_lo, earliest);
        }
      }
      total_culled += r.stats.links_culled;
      total_touching += touching;
      contact_pairs += f.contact;
      ++pairs;
    }
  }
  std::printf("culling: %d pairs, %d contact, %d touching links, %d culled links\n", pairs,
              contact_pairs, total_touching, total_culled);
  // The scene exercises both sides: links that touch and links that are culled.
  EXPECT_GT(total_touching, testing::ScaledMinimum(10));
  EXPECT_GT(total_culled, testing::ScaledMinimum(50));
}

}  // namespace
}  // namespace sweptccd
