#include "core/query/root_candidates.h"

#include <algorithm>
#include <limits>

namespace sweptccd::internal {

RootCandidates::RootCandidates(const EnvironmentTarget& target, const SweptBounds& bounds,
                               CandidatePool* pool, Buffers* buffers)
    : target_(target), pool_(*pool), depth_first_(target.skeleton().depth_first_order()) {
  if (buffers != nullptr) {
    links_ = std::move(buffers->links);
    scratch_ = std::move(buffers->scratch);
    link_order_ = std::move(buffers->link_order);
    link_nodes_ = std::move(buffers->link_nodes);
    scratch_.clear();
    link_order_.clear();
    link_nodes_.clear();
  }
  const int n = target.skeleton().num_links();
  links_.resize(n);
  for (LinkIndex l(0); l < n; ++l) {
    LinkRoot& root = links_[l];  // Every field: the array may hold an earlier query's.
    root.capsule = bounds.Over(l, 0, 1);
    root.box = Aabb::OfCapsule(root.capsule.a, root.capsule.b, root.capsule.radius);
    root.begin = root.count = 0;
    root.overflow = root.open = false;
  }
  scratch_.reserve(static_cast<size_t>(4 * n + 16));
  link_order_.reserve(static_cast<size_t>(n));
  link_nodes_.reserve(static_cast<size_t>(2 * n));  // A binary tree over n leaves.
}

void RootCandidates::Release(Buffers* buffers) {
  buffers->links = std::move(links_);
  buffers->scratch = std::move(scratch_);
  buffers->link_order = std::move(link_order_);
  buffers->link_nodes = std::move(link_nodes_);
}

void RootCandidates::FindOpen(const std::vector<bool>& skip) {
  for (ObjectIndex o(0); o < target_.num_objects(); ++o) {
    link_order_.clear();
    for (int i : depth_first_) {
      const LinkIndex l(i);
      if (!target_.Ignores(l, o) && !skip[l] && !links_[l].open) link_order_.push_back(l);
    }
    if (link_order_.empty()) continue;
    link_nodes_.assign(1, LinkNode());
    BuildLinkTree(0, 0, static_cast<uint32_t>(link_order_.size()), 0);
    FindDual(0, o, 0);
  }
}

void RootCandidates::BuildLinkTree(uint32_t index, uint32_t first, uint32_t last,
                                   uint32_t parent) {
  LinkNode node;
  node.first = first;
  node.count = last - first;
  node.parent = parent;
  node.waiting = node.count;
  node.box = Aabb::Empty();
  for (uint32_t i = first; i < last; ++i) node.box.Grow(links_[link_order_[i]].box);
  if (node.count == 1) {
    link_nodes_[index] = node;
    return;
  }
  const uint32_t half = first + node.count / 2;
  node.left = static_cast<uint32_t>(link_nodes_.size());  // Children side by side.
  link_nodes_[index] = node;
  link_nodes_.resize(node.left + 2);
  BuildLinkTree(node.left, first, half, index);
  BuildLinkTree(node.left + 1, half, last, index);
}

void RootCandidates::FindDual(uint32_t link_node, ObjectIndex object, uint32_t env_node) {
  const LinkNode& node = link_nodes_[link_node];
  if (node.waiting == 0) return;  // Every link below was found open already.
  const TriangleBvh& bvh = target_.bvh(object);
  const Aabb env_box = bvh.NodeBox(env_node);
  if (!node.box.Overlaps(env_box)) return;
  if (node.count == 1) {
    const LinkIndex l = link_order_[node.first];
    if (pool_.AnyWithin(links_[l].capsule, object, env_node)) {
      links_[l].open = true;
      for (uint32_t k = link_node;; k = link_nodes_[k].parent) {
        --link_nodes_[k].waiting;
        if (k == 0) break;
      }
    }
    return;
  }
  const TriangleBvh::Node& env = bvh.nodes()[env_node];
  const Eigen::Vector3d link_ext = node.box.hi - node.box.lo;
  const Eigen::Vector3d env_ext = env_box.hi - env_box.lo;
  if (env.count > 0 || link_ext.maxCoeff() >= env_ext.maxCoeff()) {
    const uint32_t left = node.left;
    FindDual(left, object, env_node);
    FindDual(left + 1, object, env_node);
  } else {
    FindDual(link_node, object, env.first);
    FindDual(link_node, object, env.first + 1);
  }
}

void RootCandidates::Collect(const std::vector<bool>& skip) {
  std::vector<bool> closed(skip);
  for (size_t l = 0; l < closed.size(); ++l) closed[l] = closed[l] || !links_[l].open;
  Traverse(closed);
  // An overflowing link's partial runs are useless; it queries the BVHs per
  // interval instead.
  for (size_t l = 0; l < links_.size(); ++l) {
    if (links_[l].overflow) links_[l].count = 0;
  }
}

void RootCandidates::Traverse(const std::vector<bool>& skip) {
  const int n = static_cast<int>(links_.size());
  for (ObjectIndex o(0); o < target_.num_objects(); ++o) {
    scratch_.clear();
    for (LinkIndex l(0); l < n; ++l) {
      if (!target_.Ignores(l, o) && !skip[l]) scratch_.push_back(l);
    }
    if (!scratch_.empty()) CollectDual(0, scratch_.size(), o, 0);
  }
}

void RootCandidates::CollectDual(size_t first, size_t last, ObjectIndex object,
                                 uint32_t env_node) {
  const TriangleBvh& bvh = target_.bvh(object);
  const Aabb env_box = bvh.NodeBox(env_node);
  Aabb box{Eigen::Vector3d::Constant(std::numeric_limits<double>::infinity()),
           Eigen::Vector3d::Constant(-std::numeric_limits<double>::infinity())};
  // The live links go on top of the scratch stack (indices: it may grow).
  const size_t live_first = scratch_.size();
  for (size_t i = first; i < last; ++i) {
    const LinkIndex l = scratch_[i];
    if (links_[l].box.Overlaps(env_box)) {
      scratch_.push_back(l);
      box.Grow(links_[l].box);
    }
  }
  const size_t live_last = scratch_.size();
  const size_t live = live_last - live_first;
  if (live == 0) return;
  if (live == 1) {
    const LinkIndex l = scratch_[live_first];
    scratch_.resize(live_first);
    CollectOne(l, object, env_node);
    return;
  }
  const TriangleBvh::Node& node = bvh.nodes()[env_node];
  const Eigen::Vector3d link_ext = box.hi - box.lo;
  const Eigen::Vector3d env_ext = env_box.hi - env_box.lo;
  const bool split_links = node.count > 0 || link_ext.maxCoeff() >= env_ext.maxCoeff();
  if (!split_links) {
    CollectDual(live_first, live_last, object, node.first);
    CollectDual(live_first, live_last, object, node.first + 1);
  } else {
    int axis = 0;
    link_ext.maxCoeff(&axis);
    SplitLinks(live_first, live_last, axis, object, env_node);
  }
  scratch_.resize(live_first);
}

void RootCandidates::SplitLinks(size_t first, size_t last, int axis, ObjectIndex object,
                                uint32_t env_node) {
  std::sort(scratch_.begin() + first, scratch_.begin() + last, [&](LinkIndex x, LinkIndex y) {
    const double cx = links_[x].box.lo[axis] + links_[x].box.hi[axis];
    const double cy = links_[y].box.lo[axis] + links_[y].box.hi[axis];
    return cx != cy ? cx < cy : x < y;
  });
  const size_t half = (last - first) / 2;
  CollectDual(first, first + half, object, env_node);
  CollectDual(first + half, last, object, env_node);
}

void RootCandidates::CollectOne(LinkIndex l, ObjectIndex object, uint32_t env_node) {
  if (links_[l].overflow) return;
  // Gather this link's candidates below env_node into its own run of the
  // pool. Runs of one link from different nodes are contiguous because the
  // traversal finishes a link leaf before moving on.
  std::vector<Candidate>& pool = pool_.entries();
  const size_t before = pool.size();
  if (!pool_.CollectFromBvh(links_[l].capsule, object, env_node)) {
    links_[l].overflow = true;
    return;
  }
  const uint32_t added = static_cast<uint32_t>(pool.size() - before);
  if (added == 0) return;
  const uint32_t cap = static_cast<uint32_t>(pool_.max_candidates());
  // Move the new run next to the link's earlier run, if any.
  if (links_[l].count == 0) {
    links_[l].begin = static_cast<uint32_t>(before);
  } else if (links_[l].begin + links_[l].count != before) {
    std::vector<Candidate> merged(pool.begin() + links_[l].begin, pool.begin() + links_[l].begin + links_[l].count);
    merged.insert(merged.end(), pool.begin() + before, pool.end());
    pool.resize(before);
    links_[l].begin = static_cast<uint32_t>(pool.size());
    pool.insert(pool.end(), merged.begin(), merged.end());
    links_[l].count = static_cast<uint32_t>(merged.size());
    if (links_[l].count > cap) links_[l].overflow = true;
    return;
  }
  links_[l].count += added;
  if (links_[l].count > cap) links_[l].overflow = true;
}

}  // namespace sweptccd::internal
