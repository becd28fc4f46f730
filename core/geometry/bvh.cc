#include "core/geometry/bvh.h"

#include <algorithm>
#include <cmath>
#include <limits>

#include "core/errors.h"

namespace sweptccd {

namespace {

constexpr int kBins = 16;
// Beyond this depth the build splits at the median (see below).
constexpr uint32_t kMaxSahDepth = 48;

struct Box {
  float lo[3] = {std::numeric_limits<float>::infinity(), std::numeric_limits<float>::infinity(),
                 std::numeric_limits<float>::infinity()};
  float hi[3] = {-std::numeric_limits<float>::infinity(), -std::numeric_limits<float>::infinity(),
                 -std::numeric_limits<float>::infinity()};
  void Grow(const Box& o) {
    for (int k = 0; k < 3; ++k) {
      lo[k] = std::min(lo[k], o.lo[k]);
      hi[k] = std::max(hi[k], o.hi[k]);
    }
  }
  void Grow(const float* p) {
    for (int k = 0; k < 3; ++k) {
      lo[k] = std::min(lo[k], p[k]);
      hi[k] = std::max(hi[k], p[k]);
    }
  }
  float HalfArea() const {
    const float dx = hi[0] - lo[0], dy = hi[1] - lo[1], dz = hi[2] - lo[2];
    if (dx < 0) return 0;
    return dx * dy + dy * dz + dz * dx;
  }
};

}  // namespace

namespace {

// The triangles being split into a BVH: their boxes and box centroids, and
// the permutation the build sorts (a node owns order[begin, end)).
struct BuildInput {
  std::vector<Box> boxes;
  std::vector<float> centroids;  // 3 per triangle.
  std::vector<uint32_t> order;
};

// The best binned-SAH split of order[begin, end) over the three axes, whose
// centroids span `cbox`: axis -1 when every centroid coincides.
struct SahSplit {
  int axis = -1;
  int split = 0;  // Bins [0, split) go left.
};

SahSplit FindSahSplit(const BuildInput& in, uint32_t begin, uint32_t end, const Box& cbox) {
  const uint32_t count = end - begin;
  Box bin_box[kBins];
  uint32_t bin_count[kBins];
  float right_area[kBins];
  float best_cost = std::numeric_limits<float>::infinity();
  SahSplit best;
  for (int axis = 0; axis < 3; ++axis) {
    const float extent = cbox.hi[axis] - cbox.lo[axis];
    // Below ~1e-30 kBins / extent overflows to inf (and 0 * inf is NaN).
    if (!(extent > 1e-30f)) continue;
    const float scale = kBins / extent;
    for (int b = 0; b < kBins; ++b) {
      bin_box[b] = Box{};
      bin_count[b] = 0;
    }
    for (uint32_t i = begin; i < end; ++i) {
      const uint32_t t = in.order[i];
      int b = static_cast<int>((in.centroids[3 * t + axis] - cbox.lo[axis]) * scale);
      b = std::clamp(b, 0, kBins - 1);
      bin_box[b].Grow(in.boxes[t]);
      ++bin_count[b];
    }
    Box acc;
    uint32_t acc_count = 0;
    for (int b = kBins - 1; b > 0; --b) {
      acc.Grow(bin_box[b]);
      acc_count += bin_count[b];
      right_area[b] = acc.HalfArea() * static_cast<float>(acc_count);
    }
    acc = Box{};
    acc_count = 0;
    for (int b = 0; b < kBins - 1; ++b) {
      acc.Grow(bin_box[b]);
      acc_count += bin_count[b];
      const float cost = acc.HalfArea() * static_cast<float>(acc_count) + right_area[b + 1];
      if (acc_count > 0 && acc_count < count && cost < best_cost) {
        best_cost = cost;
        best.axis = axis;
        best.split = b + 1;
      }
    }
  }
  return best;
}

// Reorders order[begin, end) into two children and returns where the right
// one starts: a median split on the widest axis of `box` below the SAH depth
// limit (queries use a fixed stack; each such level halves the count), else
// the SAH split (halves when there is none or it leaves a side empty).
uint32_t SplitRange(BuildInput* in, uint32_t begin, uint32_t end, uint32_t depth, const Box& box,
                    const Box& cbox) {
  const uint32_t count = end - begin;
  std::vector<uint32_t>& order = in->order;
  const std::vector<float>& centroids = in->centroids;
  if (depth >= kMaxSahDepth) {
    int axis = 0;
    for (int k = 1; k < 3; ++k) {
      if (box.hi[k] - box.lo[k] > box.hi[axis] - box.lo[axis]) axis = k;
    }
    const uint32_t mid = begin + count / 2;
    std::nth_element(order.begin() + begin, order.begin() + mid, order.begin() + end,
                     [&](uint32_t x, uint32_t y) {
                       return centroids[3 * x + axis] < centroids[3 * y + axis];
                     });
    return mid;
  }
  const SahSplit sah = FindSahSplit(*in, begin, end, cbox);
  if (sah.axis < 0) return begin + count / 2;  // All centroids coincide.
  const float lo = cbox.lo[sah.axis];
  const float scale = kBins / (cbox.hi[sah.axis] - lo);
  auto it = std::partition(order.begin() + begin, order.begin() + end, [&](uint32_t t) {
    int b = static_cast<int>((centroids[3 * t + sah.axis] - lo) * scale);
    return std::clamp(b, 0, kBins - 1) < sah.split;
  });
  const uint32_t mid = static_cast<uint32_t>(it - order.begin());
  return (mid == begin || mid == end) ? begin + count / 2 : mid;
}

// The node tree over `in` (order is permuted so each leaf owns a range).
std::vector<TriangleBvh::Node> BuildNodes(BuildInput* in) {
  using Node = TriangleBvh::Node;
  std::vector<Node> nodes;
  const uint32_t n = static_cast<uint32_t>(in->order.size());
  nodes.reserve(2 * n / 2 + 16);
  nodes.push_back(Node{});
  struct Job {
    uint32_t node, begin, end, depth;
  };
  std::vector<Job> jobs;
  jobs.push_back({0, 0, n, 0});
  while (!jobs.empty()) {
    const Job job = jobs.back();
    jobs.pop_back();
    Box box, cbox;
    for (uint32_t i = job.begin; i < job.end; ++i) {
      box.Grow(in->boxes[in->order[i]]);
      cbox.Grow(&in->centroids[3 * in->order[i]]);
    }
    Node& node = nodes[job.node];
    for (int k = 0; k < 3; ++k) {
      node.lo[k] = box.lo[k];
      node.hi[k] = box.hi[k];
    }
    const uint32_t count = job.end - job.begin;
    if (count <= TriangleBvh::kMaxLeafSize) {
      node.first = job.begin;
      node.count = count;
      continue;
    }
    const uint32_t mid = SplitRange(in, job.begin, job.end, job.depth, box, cbox);
    const uint32_t left = static_cast<uint32_t>(nodes.size());
    nodes[job.node].first = left;
    nodes[job.node].count = 0;
    nodes.push_back(Node{});
    nodes.push_back(Node{});
    jobs.push_back({left + 1, mid, job.end, job.depth + 1});
    jobs.push_back({left, job.begin, mid, job.depth + 1});
  }
  nodes.shrink_to_fit();
  return nodes;
}

// The triangles in leaf order (9 floats each) and their ids.
void StoreTriangles(const TriangleMesh& mesh, const std::vector<uint32_t>& order,
                    std::vector<float>* tri, std::vector<uint32_t>* ids) {
  const size_t n = order.size();
  tri->resize(9 * n);
  ids->resize(n);
  for (size_t slot = 0; slot < n; ++slot) {
    const uint32_t t = order[slot];
    (*ids)[slot] = t;
    for (int v = 0; v < 3; ++v) {
      const Eigen::Vector3f& p = mesh.vertices[mesh.indices[3 * t + v]];
      for (int k = 0; k < 3; ++k) (*tri)[9 * slot + 3 * v + k] = p[k];
    }
  }
}

}  // namespace

TriangleBvh::TriangleBvh(const TriangleMesh& mesh) {
  const size_t n = mesh.num_triangles();
  SWEPTCCD_CHECK(n > 0 && n < std::numeric_limits<uint32_t>::max() / 2);
  BuildInput in;
  in.boxes.resize(n);
  in.centroids.resize(3 * n);
  for (size_t t = 0; t < n; ++t) {
    for (int v = 0; v < 3; ++v) {
      const Eigen::Vector3f& p = mesh.vertices[mesh.indices[3 * t + v]];
      in.boxes[t].Grow(p.data());
      max_abs_coordinate_ = std::max<double>(max_abs_coordinate_, p.cwiseAbs().maxCoeff());
    }
    for (int k = 0; k < 3; ++k) {
      in.centroids[3 * t + k] = 0.5f * (in.boxes[t].lo[k] + in.boxes[t].hi[k]);
    }
  }
  in.order.resize(n);
  for (size_t t = 0; t < n; ++t) in.order[t] = static_cast<uint32_t>(t);
  nodes_ = BuildNodes(&in);
  StoreTriangles(mesh, in.order, &tri_, &ids_);
}

Aabb TriangleBvh::NodeBox(uint32_t node) const {
  const Node& nd = nodes_[node];
  return Aabb{Eigen::Vector3d(nd.lo[0], nd.lo[1], nd.lo[2]),
              Eigen::Vector3d(nd.hi[0], nd.hi[1], nd.hi[2])};
}

size_t TriangleBvh::memory_bytes() const {
  return nodes_.capacity() * sizeof(Node) + tri_.capacity() * sizeof(float) +
         ids_.capacity() * sizeof(uint32_t);
}

}  // namespace sweptccd
