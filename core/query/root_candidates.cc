#include "core/query/root_candidates.h"

#include <algorithm>

namespace sweptccd::internal {

RootCandidates::RootCandidates(const EnvironmentTarget& target, const SweptBounds& bounds,
                               CandidatePool* pool, Buffers* buffers,
                               const std::vector<char>* group_cleared, const LoosePoses* loose)
    : target_(target),
      pool_(*pool),
      group_cleared_(group_cleared),
      no_check_budget_(loose != nullptr ? kLooseBudget : -1),
      depth_first_(target.skeleton().depth_first_order()) {
  if (buffers != nullptr) {
    links_ = std::move(buffers->links);
    link_order_ = std::move(buffers->link_order);
    link_nodes_ = std::move(buffers->link_nodes);
    deferred_ = std::move(buffers->deferred);
    link_order_.clear();
    link_nodes_.clear();
    deferred_.clear();
  }
  const int n = target.skeleton().num_links();
  links_.resize(n);
  for (LinkIndex l(0); l < n; ++l) {
    LinkRoot& root = links_[l];  // The array may hold an earlier query's.
    if (GroupCleared(l)) {
      // Never open, and nothing reads its capsule or box (FindOpen and
      // FindOpenOne skip it): left as the array holds them. Its poses are
      // not composed.
      root.open = false;
      continue;
    }
    if (loose == nullptr) {
      root.capsule = bounds.Over(l, 0, 1);
    } else {
      root.capsule = loose->growth != nullptr
                         ? bounds.LooseOver(l, *loose->pose0, *loose->pose1, (*loose->growth)[l])
                         : bounds.LooseOver(l, *loose->pose0, *loose->pose1);
    }
    root.box = Aabb::OfCapsule(root.capsule.a, root.capsule.b, root.capsule.radius);
    root.open = false;
  }
  link_order_.reserve(static_cast<size_t>(n));
  link_nodes_.reserve(static_cast<size_t>(2 * n));  // A binary tree over n leaves.
}

void RootCandidates::Release(Buffers* buffers) {
  buffers->links = std::move(links_);
  buffers->link_order = std::move(link_order_);
  buffers->link_nodes = std::move(link_nodes_);
  buffers->deferred = std::move(deferred_);
}

void RootCandidates::FindOpen(LinkIndex first, TouchCheck touches, void* context) {
  touches_ = touches;
  touches_context_ = context;
  cutoff_ = LinkIndex();
  for (ObjectIndex o(0); o < target_.num_objects(); ++o) {
    link_order_.clear();
    for (int i : depth_first_) {
      const LinkIndex l(i);
      if (Dropped(l)) continue;
      if (l >= first && !GroupCleared(l) && !links_[l].open && !target_.Ignores(l, o)) {
        link_order_.push_back(l);
      }
    }
    if (link_order_.empty()) continue;
    link_nodes_.assign(1, LinkNode());
    BuildLinkTree(0, 0, static_cast<uint32_t>(link_order_.size()), 0);
    deferred_.clear();
    FindDual(0, o, 0);
    RunDeferred(o);
  }
}

void RootCandidates::RunDeferred(ObjectIndex object) {
  // Link order (then the traversal's), so the cutoff falls as early as it can.
  std::stable_sort(deferred_.begin(), deferred_.end(),
                   [](const auto& x, const auto& y) { return x.first < y.first; });
  for (const auto& [l, env_node] : deferred_) {
    if (Dropped(l) || links_[l].open) continue;
    if (pool_.AnyWithin(links_[l].capsule, object, env_node)) MarkOpen(l);
  }
  deferred_.clear();
}

void RootCandidates::MarkOpen(LinkIndex link) {
  links_[link].open = true;
  if (touches_ != nullptr && (!cutoff_.is_valid() || link < cutoff_) &&
      touches_(touches_context_, link)) {
    cutoff_ = link;
  }
}

bool RootCandidates::FindOpenOne(LinkIndex link) {
  LinkRoot& root = links_[link];
  if (GroupCleared(link)) return false;
  for (ObjectIndex o(0); o < target_.num_objects() && !root.open; ++o) {
    root.open = pool_.AnyWithin(root.capsule, o, 0);
  }
  return root.open;
}

void RootCandidates::BuildLinkTree(uint32_t index, uint32_t first, uint32_t last, uint32_t parent) {
  LinkNode node;
  node.first = first;
  node.count = last - first;
  node.parent = parent;
  node.waiting = node.count;
  if (node.count == 1) {
    node.box = Aabb::Empty();  // Grown, as before (a NaN coordinate is left out).
    node.box.Grow(links_[link_order_[first]].box);
    link_nodes_[index] = node;
    return;
  }
  const uint32_t half = first + node.count / 2;
  node.left = static_cast<uint32_t>(link_nodes_.size());  // Children side by side.
  link_nodes_.emplace_back();  // Within the reserved 2n: no reallocation.
  link_nodes_.emplace_back();
  BuildLinkTree(node.left, first, half, index);
  BuildLinkTree(node.left + 1, half, last, index);
  // The union of its links' boxes, from its children's (min and max are
  // exact: the same bits as growing it link by link).
  node.box = link_nodes_[node.left].box;
  node.box.Grow(link_nodes_[node.left + 1].box);
  link_nodes_[index] = node;
}

void RootCandidates::FindDual(uint32_t link_node, ObjectIndex object, uint32_t env_node) {
  const LinkNode& node = link_nodes_[link_node];
  if (node.waiting == 0) return;  // Every link below was found open (or dropped) already.
  const TriangleBvh& bvh = target_.bvh(object);
  const Aabb env_box = bvh.NodeBox(env_node);
  if (!node.box.Overlaps(env_box)) return;
  if (node.count == 1) {
    const LinkIndex l = link_order_[node.first];
    if (!Dropped(l)) {
      if (touches_ == nullptr) {
        // Exhaustive, or with loose capsules bounded (kLooseBudget: past it
        // the link is left open).
        if (pool_.AnyWithinBudget(links_[l].capsule, object, env_node, no_check_budget_) ==
            CandidatePool::Search::kNone) {
          return;
        }
      } else {
        switch (pool_.AnyWithinBudget(links_[l].capsule, object, env_node, kLeafBudget)) {
          case CandidatePool::Search::kNone:
            return;
          case CandidatePool::Search::kUndecided:
            deferred_.emplace_back(l, env_node);
            return;
          case CandidatePool::Search::kFound:
            break;
        }
      }
      MarkOpen(l);
    }
    for (uint32_t k = link_node;; k = link_nodes_[k].parent) {  // Decided.
      --link_nodes_[k].waiting;
      if (k == 0) break;
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

}  // namespace sweptccd::internal
