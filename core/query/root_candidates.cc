#include "core/query/root_candidates.h"

#include <algorithm>
#include <limits>

namespace sweptccd::internal {

RootCandidates::RootCandidates(const EnvironmentTarget& target, const SweptBounds& bounds,
                               int num_links, CandidatePool* pool)
    : target_(target), pool_(*pool) {
  const int n = num_links;
  capsule_.resize(n);
  box_.resize(n);
  begin_.assign(n, 0);
  count_.assign(n, 0);
  overflow_.assign(n, false);
  open_.assign(n, false);
  for (LinkIndex l(0); l < n; ++l) {
    capsule_[l] = bounds.Over(l, 0, 1);
    const LinkCapsule& c = capsule_[l];
    box_[l] = Aabb::OfCapsule(c.a, c.b, c.radius);
  }
  scratch_.reserve(static_cast<size_t>(4 * n + 16));
}

void RootCandidates::FindOpen(const std::vector<bool>& skip) {
  finding_ = true;
  Traverse(skip);
  finding_ = false;
}

void RootCandidates::Collect(const std::vector<bool>& skip) {
  std::vector<bool> closed(skip);
  for (size_t l = 0; l < closed.size(); ++l) closed[l] = closed[l] || !open_[l];
  Traverse(closed);
  // An overflowing link's partial runs are useless; it queries the BVHs per
  // interval instead.
  for (size_t l = 0; l < overflow_.size(); ++l) {
    if (overflow_[l]) count_[l] = 0;
  }
}

void RootCandidates::Traverse(const std::vector<bool>& skip) {
  const int n = static_cast<int>(capsule_.size());
  for (ObjectIndex o(0); o < target_.num_objects(); ++o) {
    scratch_.clear();
    for (LinkIndex l(0); l < n; ++l) {
      // Finding: a link open already needs no more of the traversal.
      if (!target_.Ignores(l, o) && !skip[l] && !(finding_ && open_[l])) scratch_.push_back(l);
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
    if (finding_ && open_[l]) continue;  // Found open under an earlier node.
    if (box_[l].Overlaps(env_box)) {
      scratch_.push_back(l);
      box.Grow(box_[l]);
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
    const double cx = box_[x].lo[axis] + box_[x].hi[axis];
    const double cy = box_[y].lo[axis] + box_[y].hi[axis];
    return cx != cy ? cx < cy : x < y;
  });
  const size_t half = (last - first) / 2;
  CollectDual(first, first + half, object, env_node);
  CollectDual(first + half, last, object, env_node);
}

void RootCandidates::CollectOne(LinkIndex l, ObjectIndex object, uint32_t env_node) {
  if (finding_) {
    if (!open_[l]) open_[l] = pool_.AnyWithin(capsule_[l], object, env_node);
    return;
  }
  if (overflow_[l]) return;
  // Gather this link's candidates below env_node into its own run of the
  // pool. Runs of one link from different nodes are contiguous because the
  // traversal finishes a link leaf before moving on.
  std::vector<Candidate>& pool = pool_.entries();
  const size_t before = pool.size();
  if (!pool_.CollectFromBvh(capsule_[l], object, env_node)) {
    overflow_[l] = true;
    return;
  }
  const uint32_t added = static_cast<uint32_t>(pool.size() - before);
  if (added == 0) return;
  const uint32_t cap = static_cast<uint32_t>(pool_.max_candidates());
  // Move the new run next to the link's earlier run, if any.
  if (count_[l] == 0) {
    begin_[l] = static_cast<uint32_t>(before);
  } else if (begin_[l] + count_[l] != before) {
    std::vector<Candidate> merged(pool.begin() + begin_[l], pool.begin() + begin_[l] + count_[l]);
    merged.insert(merged.end(), pool.begin() + before, pool.end());
    pool.resize(before);
    begin_[l] = static_cast<uint32_t>(pool.size());
    pool.insert(pool.end(), merged.begin(), merged.end());
    count_[l] = static_cast<uint32_t>(merged.size());
    if (count_[l] > cap) overflow_[l] = true;
    return;
  }
  count_[l] += added;
  if (count_[l] > cap) overflow_[l] = true;
}

}  // namespace sweptccd::internal
