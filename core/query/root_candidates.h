#pragma once
// Internal to the query engine (see docs/DESIGN.md, "core/query"): seeding,
// the published method's culling step. A BVH over the links' swept bounds for
// the whole pair is traversed together with each object's BVH; a link whose
// bound meets no triangle is free for the whole pair, the others start the
// descent with their candidates listed.

#include <vector>

#include "core/geometry/bvh.h"
#include "core/query/candidate_pool.h"
#include "core/query/swept_bounds.h"

namespace sweptccd::internal {

/// The whole-pair candidates of every link. Single-threaded, one per query.
class RootCandidates {
 public:
  /// The whole-pair capsules; nothing is open (Find marks them).
  /// `buffers`: the arrays of an earlier RootCandidates (Release) to reuse,
  /// or null (the query's thread keeps them; see QueryBuffers).
  struct Buffers;
  RootCandidates(const EnvironmentTarget& target, const SweptBounds& bounds, CandidatePool* pool,
                 Buffers* buffers = nullptr);
  /// Gives the arrays back for the next query; this object is left unusable.
  void Release(Buffers* buffers);

  /// Marks open every link not in `skip` (cleared by the culler already)
  /// whose whole-pair capsule meets some primitive. A link leaves at its
  /// first primitive. The traversal pairs each object's BVH with a small
  /// tree over the links' boxes (FindDual), so the scene's upper levels are
  /// tested against the whole avatar's box once, not against every link's;
  /// a link is still tested against every node its own box meets, and
  /// searched (AnyWithin) from the node where it is alone, as in Collect.
  /// Which links are open does not depend on the tree's shape (only the
  /// work and the triangle-test count do).
  void FindOpen(const std::vector<bool>& skip);
  bool Open(LinkIndex link) const { return links_[link].open; }
  /// Collects into the pool, for every open link not in `skip` (closed
  /// already), the primitives its whole-pair capsule meets.
  void Collect(const std::vector<bool>& skip);

  /// The link's list (requery when it had too many to list). Empty: the link
  /// is free for the whole pair.
  CandidateList ListOf(LinkIndex link) const {
    const LinkRoot& r = links_[link];
    return CandidateList{r.begin, r.count, r.overflow};
  }
  bool Empty(LinkIndex link) const {
    const LinkRoot& r = links_[link];
    return !r.open || (r.count == 0 && !r.overflow);
  }

 private:
  // The links scratch_[first, last) below env_node. The traversal keeps its
  // link sets on one scratch stack (no allocation per node): a call appends
  // its live links after `last` and pops them before returning.
  void Traverse(const std::vector<bool>& skip);
  void CollectDual(size_t first, size_t last, ObjectIndex object, uint32_t env_node);
  // One link below env_node: appends its candidates next to its earlier run.
  void CollectOne(LinkIndex link, ObjectIndex object, uint32_t env_node);
  // Splits scratch_[first, last) at the median of the box centres along `axis`.
  void SplitLinks(size_t first, size_t last, int axis, ObjectIndex object, uint32_t env_node);

  // FindOpen's tree over the links' boxes: a node holds link_order_[first,
  // first + count) and the union of their boxes; an inner node's children
  // are `left` and left + 1. `waiting` counts its links not found open yet.
  struct LinkNode {
    Aabb box;
    uint32_t first = 0, count = 0;
    uint32_t left = 0;  // Inner nodes only.
    uint32_t parent = 0;
    uint32_t waiting = 0;
  };
  // Fills link_nodes_[index] with link_order_[first, last) and builds its
  // subtree from the halves of that range. link_order_ follows the
  // skeleton's depth-first order, in which every subtree of the kinematic
  // tree is contiguous, so a limb's links share nodes: no sorting per query.
  void BuildLinkTree(uint32_t index, uint32_t first, uint32_t last, uint32_t parent);
  void FindDual(uint32_t link_node, ObjectIndex object, uint32_t env_node);

  // One link's whole-pair capsule, its box, its run of the pool.
  struct LinkRoot {
    LinkCapsule capsule;
    Aabb box;
    uint32_t begin = 0, count = 0;
    bool overflow = false;
    bool open = false;
  };

  const EnvironmentTarget& target_;
  CandidatePool& pool_;
  std::vector<LinkRoot> links_;  // By link index.
  std::vector<LinkIndex> scratch_;
  const std::vector<int>& depth_first_;  // The skeleton's.
  std::vector<LinkIndex> link_order_;  // FindOpen: the links of the tree, leaf order.
  std::vector<LinkNode> link_nodes_;
};

struct RootCandidates::Buffers {
  std::vector<LinkRoot> links;
  std::vector<LinkIndex> scratch, link_order;
  std::vector<LinkNode> link_nodes;
};

}  // namespace sweptccd::internal
