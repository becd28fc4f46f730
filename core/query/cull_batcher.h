#pragma once
// Internal to the query engine (see docs/DESIGN.md, "core/query"): batching
// swept-volume tests for a CapsuleCuller (the GPU). One round trip answers an
// interval and the first levels of its time-slicing subtree, plus as many
// other pending intervals as fit, so the descent mostly finds its answers
// waiting. The capsules sent are the descent's own (SweptBounds), and the
// answers keep them, so the CPU never computes one twice.

#include <cstdint>
#include <unordered_map>
#include <vector>

#include "core/query/capsule_culler.h"
#include "core/query/ccd_query.h"
#include "core/query/swept_bounds.h"
#include "core/query/time_slicer.h"

namespace sweptccd::internal {

/// The culler's verdict on one interval, with the capsule it was asked about.
struct CullAnswer {
  bool cleared;
  LinkCapsule capsule;
};

/// Single-threaded, one per query. With a null culler, or once the culler
/// failed, it is inactive and answers nothing.
class CullBatcher {
 public:
  /// Levels of the time-slicing tree below an interval that one round trip
  /// answers ahead of the descent (15 intervals per interval asked about),
  /// and the most capsules sent in one round trip.
  static constexpr int kLevels = 3;
  static constexpr size_t kMaxBatch = 4096;

  CullBatcher(const CapsuleCuller* culler, const SweptBounds& bounds, QueryStats* stats)
      : culler_(culler), bounds_(bounds), stats_(*stats) {}

  bool active() const { return culler_ != nullptr; }

  /// Queues the capsule of [s0, s1] and of its descendants `levels` deep,
  /// computed exactly as the descent computes them.
  void AppendSubtree(LinkIndex link, double s0, double s1, const SegmentEnds& ends, int levels);
  /// Sends the queued capsules in one round trip and records the answers.
  /// Returns false (and goes inactive) when the culler failed.
  bool Flush();
  /// The answer for the interval; nullptr when it was not asked.
  const CullAnswer* Find(LinkIndex link, double s0, double s1) const;
  /// The answer for `interval`, asking (with the subtree, and the pending
  /// intervals of links not `done`, while the batch has room) when it was not
  /// asked yet. nullptr when inactive or the culler failed.
  const CullAnswer* AnswerFor(const Interval& interval, const std::vector<Interval>& pending,
                              const std::vector<bool>& done);

 private:
  struct Key {
    LinkIndex link;
    double s0, s1;
    bool operator==(const Key& o) const { return link == o.link && s0 == o.s0 && s1 == o.s1; }
  };
  struct KeyHash {
    size_t operator()(const Key& k) const {
      return std::hash<double>()(k.s0) * 1000003u ^ std::hash<double>()(k.s1) * 31u ^
             static_cast<size_t>(k.link.value());
    }
  };

  const CapsuleCuller* culler_;
  const SweptBounds& bounds_;
  QueryStats& stats_;
  std::vector<LinkCapsule> batch_;
  std::vector<Key> keys_;
  std::vector<uint8_t> may_touch_;
  std::unordered_map<Key, CullAnswer, KeyHash> answers_;
};

}  // namespace sweptccd::internal
