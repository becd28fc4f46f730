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
  RootCandidates(const EnvironmentTarget& target, const SweptBounds& bounds, int num_links,
                 CandidatePool* pool);

  /// Marks open every link not in `skip` (cleared by the culler already)
  /// whose whole-pair capsule meets some primitive: the same traversal as
  /// Collect, but a link leaves it at its first primitive (a link near the
  /// scene costs little; a culled one as much as in Collect).
  void FindOpen(const std::vector<bool>& skip);
  bool Open(LinkIndex link) const { return open_[link]; }
  /// Collects into the pool, for every open link not in `skip` (closed
  /// already), the primitives its whole-pair capsule meets.
  void Collect(const std::vector<bool>& skip);

  /// The link's list (requery when it had too many to list). Empty: the link
  /// is free for the whole pair.
  CandidateList ListOf(LinkIndex link) const {
    return CandidateList{begin_[link], count_[link], static_cast<bool>(overflow_[link])};
  }
  bool Empty(LinkIndex link) const {
    return !open_[link] || (count_[link] == 0 && !overflow_[link]);
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

  const EnvironmentTarget& target_;
  CandidatePool& pool_;
  std::vector<LinkCapsule> capsule_;
  std::vector<Aabb> box_;
  std::vector<uint32_t> begin_, count_;
  std::vector<bool> overflow_;
  std::vector<LinkIndex> scratch_;
  std::vector<bool> open_;
  bool finding_ = false;  // FindOpen: CollectOne only marks the link open.
};

}  // namespace sweptccd::internal
