#pragma once
// Internal to the entity engine (docs/DESIGN.md, section 5a): one answer of
// A's pair against one other entity, as named phases (the counterpart of
// core/query's QueryRun). The descent is chronological over (A's link, tau
// interval) items, as core/query's: an item is free when the swept bounds
// (segment at the interval's midpoint grown by PairMotion's certified
// growth) cannot meet; a narrow item (width <= eps) closes when a sample
// time is within delta (certificate.h).

#include <cstdint>
#include <vector>

#include "core/avatar/motion_memo.h"
#include "core/avatar/skeleton.h"
#include "core/geometry/bvh.h"
#include "core/thread_spare.h"
#include "core/world/entity_query.h"
#include "core/world/other_target.h"
#include "core/world/window_split.h"

namespace sweptccd::world {

/// An item of the descent; its candidates are arena[off, off + len) of the
/// answer's candidate arena (both halves of a split share one list).
struct EntityItem {
  double tau0, tau1;
  LinkIndex link;
  int piece;
  size_t off, len;
};

/// An answer's arrays, kept per thread between answers (ThreadSpare) so
/// that an entry allocates almost nothing (an avatar record asks for 15-31
/// of them). Only capacity carries over: every array is cleared or
/// overwritten before use.
struct EntityScratch {
  std::vector<std::vector<int>> roots, cands;  // Lists: at most the links of an entity each.
  std::vector<Aabb> boxes_e, piece_boxes, unions, near_e, near_unions;
  std::vector<EntityItem> queue;
  std::vector<int> arena, work;
};

/// Runs one answer. Single-use and single-threaded; holds references to
/// everything it is given.
class EntityRun {
 public:
  /// A's pair [utime0, utime1] with the memo of its motion, against
  /// `target` over `pieces` (chronological, contiguous; empty: no window);
  /// `link_boxes_a`: A's LinkSweepBoxes(skeleton_a, memo_a->motion(), 0),
  /// or null (made here when the target has link boxes); `near_boxes_a`:
  /// A's NearLinkBoxes over that motion with margin NearMargin(options.
  /// delta_m) (near_link_boxes.h), or null (made here when the target has
  /// near boxes).
  EntityRun(const Skeleton& skeleton_a, MotionMemo* memo_a, int64_t utime0, int64_t utime1,
            const std::vector<Piece>& pieces, const OtherTarget& target,
            const EntityQueryOptions& options, const std::vector<Aabb>* link_boxes_a,
            const std::vector<Aabb>* near_boxes_a = nullptr);
  /// Frees what a rare large answer left in the thread's arrays.
  ~EntityRun();
  EntityRun(const EntityRun&) = delete;
  EntityRun& operator=(const EntityRun&) = delete;

  OtherAnswer Run();

 private:
  // The phases, in order.
  void FindRoots();
  bool LinkBoxesClearAll();
  bool GatherNearBoxes(size_t num_e);
  void NearBoxesPruneRoots();
  bool EntityBoxesMeet();
  void CloseTouchingAtStart();
  void SeedRoots();
  void Descend();
  void CloseOutOfWork(const EntityItem& item);
  void Assemble();

  enum class Step { kNext, kStop };
  // One item of the descent: cleared, closed, or split into the queue.
  Step Visit(const EntityItem& item);
  // A narrow item: closes it when a sample is within delta (G3).
  bool TryClose(const EntityItem& item);
  void Close(const OtherBracket& b);
  // An undecided bracket with its witness (SPEC 8: at least one for a
  // contact): E's nearest unfiltered candidate to the link at the
  // bracket's start, at any distance.
  void CloseUndecided(OtherBracket b);
  bool Searching() const { return options_.per_link || brackets_.empty(); }
  double SOf(double tau) const;
  const std::vector<int>& CandidatesOf(int link, size_t piece);
  void Push(const EntityItem& item);
  size_t Store(const std::vector<int>& list);
  void CompactArena();

  const Skeleton& skeleton_a_;
  MotionMemo& memo_a_;
  const std::vector<Piece>& pieces_;
  const OtherTarget& target_;
  const EntityQueryOptions& options_;
  const std::vector<Aabb>* link_boxes_a_;
  const std::vector<Aabb>* near_boxes_a_;
  std::vector<Aabb> own_near_;  // A's near boxes when not given.
  const int num_links_;
  const size_t num_pieces_;
  const double dur_;
  double tau_from_ = 0, tau_to_ = 0;
  double tol_ = 0, eps_us_ = 0, accept_ = 0;
  ThreadSpare<EntityScratch> scratch_;
  bool use_cands_ = false;  // False: the target has no link boxes.
  std::vector<bool> done_;
  std::vector<OtherBracket> brackets_;  // In chronological order.
  size_t compacted_ = 0;
  OtherAnswer answer_;
};

/// Answers A's pair (poses under `motion_a`) against `target` over
/// `pieces` (chronological, contiguous). Deterministic.
OtherAnswer AnswerOther(const Skeleton& skeleton_a, const PairMotion& motion_a, int64_t utime0,
                        int64_t utime1, const std::vector<Piece>& pieces, const OtherTarget& target,
                        const EntityQueryOptions& options);
/// The same with A's memo, which callers answering one pair against many
/// entities keep across them (the same bits: the memo answers as the motion),
/// and optionally A's LinkSweepBoxes(skeleton_a, memo_a->motion(), 0), which
/// they compute once for all entities (else computed here), and A's
/// NearLinkBoxes (EntityRun's near_boxes_a).
OtherAnswer AnswerOther(const Skeleton& skeleton_a, MotionMemo* memo_a, int64_t utime0,
                        int64_t utime1, const std::vector<Piece>& pieces, const OtherTarget& target,
                        const EntityQueryOptions& options,
                        const std::vector<Aabb>* link_boxes_a = nullptr,
                        const std::vector<Aabb>* near_boxes_a = nullptr);

}  // namespace sweptccd::world
