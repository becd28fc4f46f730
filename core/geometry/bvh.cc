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

TriangleBvh::TriangleBvh(const TriangleMesh& mesh) {
  const size_t n = mesh.num_triangles();
  SWEPTCCD_CHECK(n > 0 && n < std::numeric_limits<uint32_t>::max() / 2);
  std::vector<Box> boxes(n);
  std::vector<float> centroids(3 * n);
  for (size_t t = 0; t < n; ++t) {
    for (int v = 0; v < 3; ++v) {
      const Eigen::Vector3f& p = mesh.vertices[mesh.indices[3 * t + v]];
      boxes[t].Grow(p.data());
      max_abs_coordinate_ = std::max<double>(max_abs_coordinate_, p.cwiseAbs().maxCoeff());
    }
    for (int k = 0; k < 3; ++k) centroids[3 * t + k] = 0.5f * (boxes[t].lo[k] + boxes[t].hi[k]);
  }
  std::vector<uint32_t> order(n);
  for (size_t t = 0; t < n; ++t) order[t] = static_cast<uint32_t>(t);

  nodes_.reserve(2 * n / 2 + 16);
  nodes_.push_back(Node{});
  struct Job {
    uint32_t node, begin, end, depth;
  };
  std::vector<Job> jobs;
  jobs.push_back({0, 0, static_cast<uint32_t>(n), 0});
  Box bin_box[kBins];
  uint32_t bin_count[kBins];
  float right_area[kBins];
  while (!jobs.empty()) {
    const Job job = jobs.back();
    jobs.pop_back();
    Box box, cbox;
    for (uint32_t i = job.begin; i < job.end; ++i) {
      box.Grow(boxes[order[i]]);
      cbox.Grow(&centroids[3 * order[i]]);
    }
    Node& node = nodes_[job.node];
    for (int k = 0; k < 3; ++k) {
      node.lo[k] = box.lo[k];
      node.hi[k] = box.hi[k];
    }
    const uint32_t count = job.end - job.begin;
    if (count <= kMaxLeafSize) {
      node.first = job.begin;
      node.count = count;
      continue;
    }
    // Binned SAH over the three axes.
    float best_cost = std::numeric_limits<float>::infinity();
    int best_axis = -1, best_split = 0;
    for (int axis = 0; axis < 3; ++axis) {
      const float extent = cbox.hi[axis] - cbox.lo[axis];
      // Below ~1e-30 kBins / extent overflows to inf (and 0 * inf is NaN).
      if (!(extent > 1e-30f)) continue;
      const float scale = kBins / extent;
      for (int b = 0; b < kBins; ++b) {
        bin_box[b] = Box{};
        bin_count[b] = 0;
      }
      for (uint32_t i = job.begin; i < job.end; ++i) {
        const uint32_t t = order[i];
        int b = static_cast<int>((centroids[3 * t + axis] - cbox.lo[axis]) * scale);
        b = std::clamp(b, 0, kBins - 1);
        bin_box[b].Grow(boxes[t]);
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
          best_axis = axis;
          best_split = b + 1;
        }
      }
    }
    uint32_t mid;
    if (job.depth >= kMaxSahDepth) {
      // Bound the depth (queries use a fixed stack): median split on the
      // widest axis halves the count, so at most log2(n) more levels follow.
      int axis = 0;
      for (int k = 1; k < 3; ++k) {
        if (box.hi[k] - box.lo[k] > box.hi[axis] - box.lo[axis]) axis = k;
      }
      mid = job.begin + count / 2;
      std::nth_element(order.begin() + job.begin, order.begin() + mid, order.begin() + job.end,
                       [&](uint32_t x, uint32_t y) {
                         return centroids[3 * x + axis] < centroids[3 * y + axis];
                       });
    } else if (best_axis < 0) {
      // All centroids coincide: split the range in half.
      mid = job.begin + count / 2;
    } else {
      const float lo = cbox.lo[best_axis];
      const float scale = kBins / (cbox.hi[best_axis] - lo);
      auto it = std::partition(order.begin() + job.begin, order.begin() + job.end, [&](uint32_t t) {
        int b = static_cast<int>((centroids[3 * t + best_axis] - lo) * scale);
        return std::clamp(b, 0, kBins - 1) < best_split;
      });
      mid = static_cast<uint32_t>(it - order.begin());
      if (mid == job.begin || mid == job.end) mid = job.begin + count / 2;
    }
    const uint32_t left = static_cast<uint32_t>(nodes_.size());
    nodes_[job.node].first = left;
    nodes_[job.node].count = 0;
    nodes_.push_back(Node{});
    nodes_.push_back(Node{});
    jobs.push_back({left + 1, mid, job.end, job.depth + 1});
    jobs.push_back({left, job.begin, mid, job.depth + 1});
  }
  nodes_.shrink_to_fit();
  tri_.resize(9 * n);
  ids_.resize(n);
  for (size_t slot = 0; slot < n; ++slot) {
    const uint32_t t = order[slot];
    ids_[slot] = t;
    for (int v = 0; v < 3; ++v) {
      const Eigen::Vector3f& p = mesh.vertices[mesh.indices[3 * t + v]];
      for (int k = 0; k < 3; ++k) tri_[9 * slot + 3 * v + k] = p[k];
    }
  }
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
