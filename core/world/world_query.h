#pragma once
// Answers every record of every avatar of a loaded world (SPEC section 8,
// "What is answered"): the static-environment part through CcdEngine (on the
// chosen backend), the part per other entity through the entity query
// (entity_query.h, CPU), whose records it writes as JSON.

#include <functional>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "core/query/ccd_query.h"
#include "core/world/entity_query.h"
#include "core/world/interval_motions.h"
#include "core/world/world_file.h"

namespace sweptccd::world {

/// Holds references to `world` (it outlives this). Not thread-safe.
class WorldAnswerer {
 public:
  WorldAnswerer(const LoadedWorld& world, const QueryOptions& options);

  /// Calls f on each avatar's environment engine (to attach a backend).
  void ForEachEngine(const std::function<void(CcdEngine*)>& f);

  /// The static-environment answer of avatar a's valid record r (SPEC 8:
  /// `free` when the world has no environment), on the attached backend,
  /// skipping the intervals `clears` holds (the device descent, docs/GPU.md:
  /// the same answer; nullptr: none).
  QueryResult AnswerEnvironment(AvatarIndex a, size_t r, const PairClears* clears = nullptr) const;

  /// The JSON record (one line, no newline) of record `r` of avatar `a`;
  /// `clears` as for AnswerEnvironment.
  std::string RecordJson(AvatarIndex a, size_t r, const PairClears* clears = nullptr) const;

  /// One entry of a record's `others`: its window (utimes) and answer.
  struct Entry {
    int64_t t_from = 0, t_to = 0;
    OtherAnswer answer;
  };
  /// The entry of avatar a's valid record r against avatar b (against
  /// object o); nullopt when E does not overlap the pair. The broad phase
  /// first: A's AvatarMotionBox over the pair against E's box of each
  /// piece's sample interval (computed once per entity); apart, the answer
  /// is `free` without any link work.
  std::optional<Entry> AnswerAvatar(AvatarIndex a, size_t r, AvatarIndex b) const {
    return AnswerEntity(a, r, b, TrackedObjectIndex());
  }
  std::optional<Entry> AnswerObject(AvatarIndex a, size_t r, TrackedObjectIndex o) const {
    return AnswerEntity(a, r, AvatarIndex(), o);
  }

  /// A box holding every link of avatar a over its valid record r.
  Aabb PairBox(AvatarIndex a, size_t r) const;

 private:
  const LoadedWorld& w_;
  QueryOptions options_;
  EntityQueryOptions entity_options_;
  std::vector<std::unique_ptr<CcdEngine>> engines_;
  std::vector<std::vector<int64_t>> avatar_times_, object_times_;  // Used samples' utimes.
  // Per entity, a box holding it over each interval between used samples
  // (one box for an entity with one sample).
  std::vector<std::vector<Aabb>> avatar_boxes_, object_boxes_;
  // Per interval likewise, near boxes (near_link_boxes.h, margin
  // NearMargin(delta)): the union of an avatar's NearLinkBoxes, an object's
  // box grown by the margin (as their targets make them).
  std::vector<std::vector<Aabb>> avatar_near_unions_, object_near_boxes_;
  // Per avatar, the largest absolute coordinate of each used sample's links,
  // and of its skeleton's link ends: WindowScale of a window is the largest
  // of these over its samples and the skeleton's (a maximum is exact).
  std::vector<std::vector<double>> avatar_sample_scales_;
  std::vector<double> avatar_skeleton_scales_;
  double AvatarWindowScale(AvatarIndex b, const std::vector<Piece>& pieces) const;
  // The window of the entry being answered (its arrays kept between entries).
  mutable EntryWindow window_;
  // AnswerAvatar (b valid) or AnswerObject (o valid).
  std::optional<Entry> AnswerEntity(AvatarIndex a, size_t r, AvatarIndex b,
                                    TrackedObjectIndex o) const;
  // PairBox of the last record asked for (records are answered one by one).
  mutable AvatarIndex box_a_;
  mutable size_t box_r_ = 0;
  mutable Aabb box_;
  // The motion of the last record asked for: PairBox and every entity of
  // the record use it (a construction composes every link three times).
  const PairMotion& RecordMotion(AvatarIndex a, size_t r) const;
  mutable AvatarIndex motion_a_;
  mutable size_t motion_r_ = 0;
  // The record's motion: A's interval motion when the record is the pair of
  // A's used samples k, k + 1 (built once for A's record and for every
  // other avatar's window that meets it), else own_motion_.
  mutable const PairMotion* motion_ = nullptr;
  mutable std::optional<PairMotion> own_motion_;
  // k when *motion_ is A's interval motion k (then PairBox is avatar_boxes_[a][k]
  // and A's link boxes are its IntervalMotions' LinkBoxesOf(k)), else -1.
  mutable int motion_k_ = -1;
  // Over *motion_: every entity of the record asks for A's links at the
  // same times (the window's start, its halves).
  mutable std::optional<MotionMemo> memo_;
  // LinkSweepBoxes of A over *motion_ (extra 0), for every avatar entity of
  // the record; null until one needs them (then link_boxes_, or A's
  // IntervalMotions' boxes of interval motion_k_).
  mutable const std::vector<Aabb>* link_boxes_a_ = nullptr;
  mutable std::vector<Aabb> link_boxes_;
  // NearLinkBoxes of A over *motion_ when it is A's interval motion (its
  // IntervalMotions' NearLinkBoxesOf(motion_k_)), else null (not used).
  mutable const std::vector<Aabb>* near_link_boxes_a_ = nullptr;
  // Each avatar's motions over its sample intervals, kept across records.
  std::vector<std::unique_ptr<IntervalMotions>> interval_motions_;
};

}  // namespace sweptccd::world
