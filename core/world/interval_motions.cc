#include "core/world/interval_motions.h"

#include <algorithm>
#include <iterator>
#include <utility>

#include "core/errors.h"
#include "core/world/link_sweep_boxes.h"
#include "core/world/near_link_boxes.h"

namespace sweptccd::world {

IntervalMotions::Held::Held(const AvatarWindow& e, int k, int k1)
    : motion(e.skeleton, e.samples[static_cast<size_t>(k)], e.samples[static_cast<size_t>(k1)],
             e.motion),
      memo(motion, /*max_times=*/64) {}

IntervalMotions::IntervalMotions(const AvatarWindow& entity, size_t max_kept,
                                 std::vector<std::vector<Aabb>> link_boxes,
                                 std::vector<std::vector<Aabb>> near_boxes, double near_margin)
    : entity_(entity),
      max_kept_(std::max<size_t>(max_kept, 1)),
      given_link_boxes_(std::move(link_boxes)),
      given_near_boxes_(std::move(near_boxes)),
      given_near_margin_(near_margin) {}

const std::vector<Aabb>& IntervalMotions::NearLinkBoxesOf(int k, double margin) {
  if (!given_near_boxes_.empty() && margin == given_near_margin_) {
    SWEPTCCD_CHECK(k >= 0 && static_cast<size_t>(k) < given_near_boxes_.size());
    return given_near_boxes_[static_cast<size_t>(k)];
  }
  MemoOf(k);
  Held& held = *held_.at(k);
  if (held.near_boxes.empty() || held.near_margin != margin) {
    // A memo of its own (the interval's memo keeps the descent's times).
    if (near_memo_) {
      near_memo_->Rebind(held.motion);
    } else {
      near_memo_.emplace(held.motion);
    }
    held.near_boxes = NearLinkBoxes(entity_.skeleton, &*near_memo_, margin);
    held.near_margin = margin;
  }
  return held.near_boxes;
}

MotionMemo& IntervalMotions::MemoOf(int k) {
  auto it = held_.find(k);
  if (it != held_.end()) return it->second->memo;
  const int k1 = std::min<int>(k + 1, static_cast<int>(entity_.samples.size()) - 1);
  std::unique_ptr<Held> held;
  if (held_.size() >= max_kept_) {
    // Full: the interval farthest from k goes, its memo's memory reused.
    auto far = std::prev(held_.end());
    if (k - held_.begin()->first >= far->first - k) far = held_.begin();
    held = std::move(far->second);
    held_.erase(far);
    // The new motion in the old one's arrays (the same bits, no allocation).
    PairMotion::Storage storage;
    held->motion.Release(&storage);
    held->motion = PairMotion(entity_.skeleton, entity_.samples[static_cast<size_t>(k)],
                              entity_.samples[static_cast<size_t>(k1)], entity_.motion, &storage);
    held->memo.Rebind(held->motion);
    held->link_boxes.clear();
    held->near_boxes.clear();
  } else {
    held = std::make_unique<Held>(entity_, k, k1);
  }
  return held_.emplace(k, std::move(held)).first->second->memo;
}

const std::vector<Aabb>& IntervalMotions::LinkBoxesOf(int k) {
  if (!given_link_boxes_.empty()) {
    SWEPTCCD_CHECK(k >= 0 && static_cast<size_t>(k) < given_link_boxes_.size());
    return given_link_boxes_[static_cast<size_t>(k)];
  }
  MemoOf(k);
  Held& held = *held_.at(k);
  if (held.link_boxes.empty() && entity_.skeleton.num_links() > 0) {
    held.link_boxes = LinkSweepBoxes(entity_.skeleton, held.motion, 0.0);
  }
  return held.link_boxes;
}

}  // namespace sweptccd::world
