#pragma once
// Internal to the query engine (see docs/DESIGN.md, "core/query"): seeding,
// the published method's culling step. A BVH over the links' swept bounds for
// the whole pair is traversed together with each object's BVH; a link whose
// bound meets no triangle is free for the whole pair, the others start the
// descent with no list: the whole pair's capsule is the fattest of the
// descent, and its halves query the BVHs with their own.

#include <utility>
#include <vector>

#include "core/geometry/bvh.h"
#include "core/query/candidate_pool.h"
#include "core/query/swept_bounds.h"

namespace sweptccd::internal {

/// Which links the whole-pair capsules leave open. Single-threaded, one per
/// query.
class RootCandidates {
 public:
  /// The whole-pair capsules; nothing is open (FindOpen marks them).
  /// `buffers`: the arrays of an earlier RootCandidates (Release) to reuse,
  /// or null (the query's thread keeps them; see QueryBuffers).
  struct Buffers;
  /// `group_cleared` (null: none): by link, non-zero for the links whose
  /// group ball met nothing (QueryRun::ClearGroups; link_groups.h). They are
  /// never open, and neither their capsules nor their poses are asked for.
  /// `loose` (null: the whole-pair capsules): the two poses of the pair,
  /// whose SweptBounds::LooseOver capsules (each holding the link's
  /// whole-pair capsule) are tested instead; a link they leave closed is
  /// not open for the pair, and none of its poses is asked for.
  /// `growth` (null: computed): by link, PairMotion::PairGrowthUpper
  /// (SubtreeReach's copy), which the loose capsules read.
  struct LoosePoses {
    const Pose* pose0;
    const Pose* pose1;
    const std::vector<double>* growth = nullptr;
  };
  RootCandidates(const EnvironmentTarget& target, const SweptBounds& bounds, CandidatePool* pool,
                 Buffers* buffers = nullptr, const std::vector<char>* group_cleared = nullptr,
                 const LoosePoses* loose = nullptr);
  /// Gives the arrays back for the next query; this object is left unusable.
  void Release(Buffers* buffers);

  /// Marks open every link whose whole-pair capsule meets some primitive. A
  /// link leaves at its first primitive. The traversal pairs each object's
  /// BVH with a small tree over the links' boxes (FindDual), so the scene's
  /// upper levels are tested against the whole avatar's box once, not
  /// against every link's;
  /// a link is still tested against every node its own box meets, and
  /// searched (AnyWithin) from the node where it is alone.
  /// Without `touches`, which links are open does not depend on the tree's
  /// shape (only the work and the triangle-test count do); with it, that
  /// holds for the links up to the cutoff.
  /// Only links from `first` on are searched.
  ///
  /// With `touches`: it is asked, as each link is found open, whether that
  /// link touches at s = 0 (`context` is passed back). When one does, the
  /// links above it are dropped, undecided (neither searched nor open): a
  /// query without --per-link answers with the lowest touching link, so
  /// only the links below it still matter. cutoff() is then that link.
  using TouchCheck = bool (*)(void* context, LinkIndex link);
  void FindOpen(LinkIndex first = LinkIndex(0), TouchCheck touches = nullptr,
                void* context = nullptr);
  /// The lowest link the last FindOpen's check found touching (links above
  /// it undecided), or an invalid index.
  LinkIndex cutoff() const { return cutoff_; }
  bool Open(LinkIndex link) const { return links_[link].open; }
  /// As FindOpen for `link` alone, with its own BVH queries; returns Open.
  bool FindOpenOne(LinkIndex link);
  /// The link's root list: "requery" (not listed: the halves ask the BVHs)
  /// when the link is open.
  CandidateList ListOf(LinkIndex link) const {
    return links_[link].open ? CandidateList{0, 1, /*requery=*/true} : CandidateList{};
  }

 private:
  // FindOpen's tree over the links' boxes: a node holds link_order_[first,
  // first + count) and the union of their boxes; an inner node's children
  // are `left` and left + 1. `waiting` counts its links not decided yet
  // (found open, or dropped above the cutoff).
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

  // One link's whole-pair capsule and its box.
  struct LinkRoot {
    LinkCapsule capsule;
    Aabb box;
    bool open = false;
  };

  bool GroupCleared(LinkIndex link) const {
    return group_cleared_ != nullptr && (*group_cleared_)[link] != 0;
  }

  const EnvironmentTarget& target_;
  CandidatePool& pool_;
  const std::vector<char>* group_cleared_;
  // Loose capsules: each link's search at a leaf stops after kLooseBudget
  // triangle tests (none: a triangle the BVH's boxes cannot refuse), leaving
  // the link open (only not cleared: its whole-pair capsule is searched
  // next), so a link near a dense mesh costs little more than without them
  // (a budget of 8 cost the contact-heavy grey room walk 19 % more
  // instructions, 0 cost 3 % less; docs/BENCHMARKS-LOG.md).
  static constexpr int kLooseBudget = 0;
  // Without a touch check: a leaf's search budget (-1: exhaustive).
  const int no_check_budget_;
  std::vector<LinkRoot> links_;          // By link index.
  const std::vector<int>& depth_first_;  // The skeleton's.
  std::vector<LinkIndex> link_order_;    // FindOpen: the links of the tree, leaf order.
  std::vector<LinkNode> link_nodes_;
  // With a touch check, a link's search at a leaf first runs up to
  // kLeafBudget tests; past it the search waits in deferred_ (link, node)
  // until the traversal of the object ends, and then runs in full, in link
  // order, only for links below the cutoff. A closed link near a dense mesh
  // (hundreds of tests) is then never searched once a lower link touches.
  static constexpr int kLeafBudget = 16;
  void RunDeferred(ObjectIndex object);
  // Above the cutoff: not searched (the answer is a lower link).
  bool Dropped(LinkIndex link) const { return cutoff_.is_valid() && link > cutoff_; }
  // Marks the link open and, with a touch check, lowers the cutoff to it
  // when it touches at s = 0.
  void MarkOpen(LinkIndex link);
  std::vector<std::pair<LinkIndex, uint32_t>> deferred_;
  TouchCheck touches_ = nullptr;
  void* touches_context_ = nullptr;
  LinkIndex cutoff_;
};

struct RootCandidates::Buffers {
  std::vector<LinkRoot> links;
  std::vector<LinkIndex> link_order;
  std::vector<LinkNode> link_nodes;
  std::vector<std::pair<LinkIndex, uint32_t>> deferred;
};

}  // namespace sweptccd::internal
