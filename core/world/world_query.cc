#include "core/world/world_query.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <nlohmann/json.hpp>

#include "core/errors.h"
#include "core/query/result_json.h"
#include "core/world/entity_broad_phase.h"
#include "core/world/interval_motions.h"
#include "core/world/link_sweep_boxes.h"
#include "core/world/near_link_boxes.h"
#include "core/world/window_split.h"

namespace sweptccd::world {
namespace {

using ojson = nlohmann::ordered_json;

ojson Vec(const Eigen::Vector3d& v) { return ojson::array({v.x(), v.y(), v.z()}); }

ojson ContactJson(const EntityContactRecord& c) {
  ojson j;
  j["link"] = c.link.value();
  if (c.other_link >= 0) j["other_link"] = c.other_link.value();
  if (c.triangle >= 0) j["triangle"] = c.triangle;
  j["s"] = c.s;
  j["point_link"] = Vec(c.point_link);
  j["point_other"] = Vec(c.point_other);
  j["normal"] = Vec(c.normal);
  j["separation"] = c.separation;
  return j;
}

void BracketFields(const EntityBracketRecord& p, ojson* j) {
  (*j)["initially_colliding"] = p.initially_colliding;
  (*j)["undecided"] = p.undecided;
  (*j)["s_lo"] = p.s_lo;
  (*j)["s_hi"] = p.s_hi;
  (*j)["t_lo"] = p.t_lo;
  (*j)["t_hi"] = p.t_hi;
}

// The entry's JSON object of SPEC 8 (`others`).
ojson EntityJson(const EntityRecord& r) {
  ojson e;
  e["entity"] = r.entity;
  e["kind"] = r.is_object ? "object" : "avatar";
  e["window"] = ojson::array({r.t_from, r.t_to});
  e["result"] = r.contact ? "contact" : "free";
  if (r.contact) {
    BracketFields(r.bracket, &e);
    ojson contacts = ojson::array();
    for (const EntityContactRecord& c : r.contacts) contacts.push_back(ContactJson(c));
    e["contacts"] = contacts;
  } else {
    e["initially_colliding"] = false;
    e["undecided"] = false;
  }
  if (r.per_link) {
    ojson links = ojson::array();
    for (const EntityBracketRecord& br : r.links) {
      ojson l;
      l["link"] = br.link.value();
      BracketFields(br, &l);
      if (br.has_witness) l["contact"] = ContactJson(br.witness);
      links.push_back(l);
    }
    e["links"] = links;
  }
  e["stats"] = {{"intervals", r.intervals}, {"culled_by_box", r.culled_by_box}};
  return e;
}

}  // namespace

WorldAnswerer::WorldAnswerer(const LoadedWorld& world, const QueryOptions& options)
    : w_(world), options_(options) {
  entity_options_.eps_s = options.eps_s;
  entity_options_.delta_m = options.delta_m;
  entity_options_.per_link = options.per_link;
  entity_options_.max_intervals = options.max_intervals;
  for (size_t a = 0; a < w_.world.avatars.size(); ++a) {
    engines_.push_back(
        std::make_unique<CcdEngine>(w_.world.avatars[a].skeleton, w_.env, w_.env_filters[a]));
    avatar_times_.emplace_back();
    for (const Pose& p : w_.world.avatars[a].used) avatar_times_.back().push_back(p.utime);
  }
  for (const ObjectEntity& o : w_.world.objects) {
    object_times_.emplace_back();
    for (const RigidSample& x : o.used) object_times_.back().push_back(x.utime);
  }
  const double near_margin = NearMargin(options.delta_m);
  std::optional<MotionMemo> memo;  // Rebound from interval to interval (its memory kept).
  for (const AvatarEntity& e : w_.world.avatars) {
    // Per sample interval, from one motion: the entity box and the link
    // boxes (both depend on the interval's samples only; the link boxes are
    // kept so that an entry cleared by them never builds E's motion), and
    // the links' near boxes (near_link_boxes.h).
    avatar_boxes_.emplace_back();
    avatar_near_unions_.emplace_back();
    std::vector<std::vector<Aabb>> link_boxes, near_boxes;
    for (size_t k = 0; k < std::max<size_t>(e.used.size(), 2) - 1 && !e.used.empty(); ++k) {
      const size_t k1 = std::min(k + 1, e.used.size() - 1);
      const PairMotion motion(e.skeleton, e.used[k], e.used[k1], e.motion);
      avatar_boxes_.back().push_back(AvatarMotionBox(e.skeleton, motion));
      link_boxes.push_back(LinkSweepBoxes(e.skeleton, motion, 0.0));
      if (memo) {
        memo->Rebind(motion);
      } else {
        memo.emplace(motion);
      }
      near_boxes.push_back(NearLinkBoxes(e.skeleton, &*memo, near_margin));
      avatar_near_unions_.back().push_back(UnionOf(near_boxes.back()));
    }
    interval_motions_.push_back(std::make_unique<IntervalMotions>(
        WindowOfAvatar(w_.world, AvatarIndex(static_cast<int>(interval_motions_.size()))), 4,
        std::move(link_boxes), std::move(near_boxes), near_margin));
    avatar_sample_scales_.emplace_back();
    for (const Pose& pose : e.used) avatar_sample_scales_.back().push_back(SampleScale(pose));
    avatar_skeleton_scales_.push_back(SkeletonScale(e.skeleton));
  }
  for (const ObjectEntity& e : w_.world.objects) {
    const TriangleBvh& bvh = e.mesh->object(0).bvh;
    const double rho = ObjectRadius(bvh);
    object_boxes_.emplace_back();
    object_near_boxes_.emplace_back();
    for (size_t k = 0; k < std::max<size_t>(e.used.size(), 2) - 1 && !e.used.empty(); ++k) {
      const size_t k1 = std::min(k + 1, e.used.size() - 1);
      object_boxes_.back().push_back(
          ObjectMotionBox(e.used[k], e.used[k1], rho, bvh.max_abs_coordinate()));
      // Its near box, as its target makes it (ObjectTarget::NearLinkBoxes).
      Aabb near = object_boxes_.back().back();
      near.lo.array() -= near_margin;
      near.hi.array() += near_margin;
      object_near_boxes_.back().push_back(near);
    }
  }
}

void WorldAnswerer::ForEachEngine(const std::function<void(CcdEngine*)>& f) {
  if (w_.env.num_objects() == 0) return;
  for (auto& e : engines_) f(e.get());
}

std::optional<WorldAnswerer::Entry> WorldAnswerer::AnswerEntity(AvatarIndex a, size_t r,
                                                                AvatarIndex b,
                                                                TrackedObjectIndex o) const {
  SWEPTCCD_CHECK(b.is_valid() != o.is_valid());
  const AvatarEntity& A = w_.world.avatars[a];
  const PairOutcome& rec = A.records[r];
  const int64_t u0 = rec.pose0.utime, u1 = rec.pose1.utime;
  const std::vector<int64_t>& times = b.is_valid() ? avatar_times_[b] : object_times_[o];
  std::optional<Entry> entry;      // Every return returns it (no copy).
  EntryWindow* window = &window_;  // Its capacity kept from entry to entry.
  if (!WindowInto(
          u0, u1, times.size(), [&](size_t k) { return times[k]; }, window))
    return entry;
  entry.emplace();
  entry->t_from = window->t_from;
  entry->t_to = window->t_to;
  // Broad phase: A's box over the pair against E's box of each piece's
  // sample interval.
  const std::vector<Aabb>& boxes = b.is_valid() ? avatar_boxes_[b] : object_boxes_[o];
  if (box_a_ != a || box_r_ != r) {
    box_ = PairBox(a, r);
    box_a_ = a;
    box_r_ = r;
  }
  if (!EntryNear(box_, window->pieces, [&](size_t k) -> const Aabb& { return boxes[k]; })) {
    entry->answer.culled_by_box = true;
    return entry;
  }
  RecordMotion(a, r);    // Sets memo_ to this record's.
  if (motion_k_ >= 0) {  // (Else EntityRun makes them.)
    near_link_boxes_a_ = &interval_motions_[static_cast<size_t>(a)]->NearLinkBoxesOf(
        motion_k_, NearMargin(entity_options_.delta_m));
    // The near boxes' unions apart in every piece: EntityRun would clear
    // the entry from its near boxes (every link pair apart; against an
    // avatar when its root items are within the work limit, which
    // links x pieces bounds), so it is cleared here without the answer's
    // set-up, as the daemon clears it in EntityRun.
    const std::vector<Aabb>& near_e = b.is_valid() ? avatar_near_unions_[b] : object_near_boxes_[o];
    const Aabb& near_a = avatar_near_unions_[a][static_cast<size_t>(motion_k_)];
    bool apart = !b.is_valid() || static_cast<int64_t>(A.skeleton.num_links()) *
                                          static_cast<int64_t>(window->pieces.size()) <=
                                      entity_options_.max_intervals;
    for (const Piece& p : window->pieces) {
      apart = apart && BoxesApart(near_a, near_e[static_cast<size_t>(p.k)]);
    }
    if (apart) {
      entry->answer.culled_by_box = true;
      return entry;
    }
  }
  if (b.is_valid() && link_boxes_a_ == nullptr) {
    if (motion_k_ >= 0) {
      link_boxes_a_ = &interval_motions_[static_cast<size_t>(a)]->LinkBoxesOf(motion_k_);
    } else {
      link_boxes_ = LinkSweepBoxes(A.skeleton, *motion_, 0.0);
      link_boxes_a_ = &link_boxes_;
    }
  }
  const PairSide side{FilterSide{A.id, w_.world.rules[a]},    A.skeleton,        u0, u1, &*memo_,
                      b.is_valid() ? link_boxes_a_ : nullptr, near_link_boxes_a_};
  entry->answer =
      b.is_valid()
          ? AnswerAgainstAvatar(side, WindowOfAvatar(w_.world, b), *window, entity_options_,
                                AvatarWindowScale(b, window->pieces),
                                interval_motions_[static_cast<size_t>(b)].get())
          : AnswerAgainstObject(side, WindowOfObject(w_.world, o), *window, entity_options_);
  return entry;
}

double WorldAnswerer::AvatarWindowScale(AvatarIndex b, const std::vector<Piece>& pieces) const {
  // WindowScale(avatars[b], pieces) from the kept maxima.
  const std::vector<double>& samples = avatar_sample_scales_[static_cast<size_t>(b)];
  SWEPTCCD_CHECK(!pieces.empty() && !samples.empty());
  const size_t first = static_cast<size_t>(pieces.front().k);
  const size_t last = std::min(static_cast<size_t>(pieces.back().k) + 1, samples.size() - 1);
  SWEPTCCD_CHECK(first <= last);
  double scale = 0;
  for (size_t k = first; k <= last; ++k) scale = std::max(scale, samples[k]);
  return std::max(scale, avatar_skeleton_scales_[static_cast<size_t>(b)]);
}

const PairMotion& WorldAnswerer::RecordMotion(AvatarIndex a, size_t r) const {
  if (motion_ != nullptr && motion_a_ == a && motion_r_ == r) return *motion_;
  const AvatarEntity& A = w_.world.avatars[a];
  const PairOutcome& rec = A.records[r];
  const std::vector<int64_t>& times = avatar_times_[a];
  const size_t k = static_cast<size_t>(
      std::lower_bound(times.begin(), times.end(), rec.pose0.utime) - times.begin());
  if (k + 1 < times.size() && SamePose(A.used[k], rec.pose0) &&
      SamePose(A.used[k + 1], rec.pose1)) {
    motion_ = &interval_motions_[static_cast<size_t>(a)]->MotionOf(static_cast<int>(k));
    motion_k_ = static_cast<int>(k);
  } else {
    own_motion_.emplace(A.skeleton, rec.pose0, rec.pose1, A.motion);
    motion_ = &*own_motion_;
    motion_k_ = -1;
  }
  if (memo_) {
    memo_->Rebind(*motion_);  // Its memory kept from record to record.
  } else {
    memo_.emplace(*motion_);
  }
  motion_a_ = a;
  motion_r_ = r;
  link_boxes_a_ = nullptr;
  near_link_boxes_a_ = nullptr;
  return *motion_;
}

Aabb WorldAnswerer::PairBox(AvatarIndex a, size_t r) const {
  const PairMotion& motion = RecordMotion(a, r);
  // The interval's box was made from the same samples by the same function.
  if (motion_k_ >= 0) return avatar_boxes_[static_cast<size_t>(a)][static_cast<size_t>(motion_k_)];
  return AvatarMotionBox(w_.world.avatars[a].skeleton, motion);
}

QueryResult WorldAnswerer::AnswerEnvironment(AvatarIndex a, size_t r,
                                             const PairClears* clears) const {
  if (w_.env.num_objects() == 0) return QueryResult();  // `free`.
  const AvatarEntity& A = w_.world.avatars[a];
  const PairOutcome& rec = A.records[r];
  QueryOptions options = options_;
  options.motion = A.motion;  // Each avatar moves by its own model.
  return engines_[a]->Query(RecordMotion(a, r), rec.pose0, rec.pose1, options, clears);
}

std::string WorldAnswerer::RecordJson(AvatarIndex a, size_t r, const PairClears* clears) const {
  const AvatarEntity& A = w_.world.avatars[a];
  const PairOutcome& rec = A.records[r];
  ojson j;
  if (!rec.valid) {
    j = ojson::parse(InvalidResultToJson(rec.pair, rec.utime0, rec.utime1, rec.error));
    j["avatar"] = A.id;
    j["others"] = ojson::array();
    return j.dump(-1, ' ', false, ojson::error_handler_t::replace);
  }
  const auto start = std::chrono::steady_clock::now();
  const QueryResult env_result = AnswerEnvironment(a, r, clears);
  const int64_t u0 = rec.pose0.utime, u1 = rec.pose1.utime;
  ojson others = ojson::array();
  auto add = [&](const std::string& id, bool is_object, const std::optional<Entry>& e) {
    if (!e) return;
    others.push_back(EntityJson(
        MakeEntityRecord(id, is_object, u0, u1, e->t_from, e->t_to, e->answer, options_.per_link)));
  };
  for (AvatarIndex b(0); b < static_cast<int>(w_.world.avatars.size()); ++b) {
    if (b != a) add(w_.world.avatars[b].id, false, AnswerAvatar(a, r, b));
  }
  for (TrackedObjectIndex o(0); o < static_cast<int>(w_.world.objects.size()); ++o) {
    add(w_.world.objects[o].id, true, AnswerObject(a, r, o));
  }
  const double elapsed_us =
      std::chrono::duration<double, std::micro>(std::chrono::steady_clock::now() - start).count();
  j = ojson::parse(ResultToJson(rec.pair, u0, u1, env_result, options_.per_link, elapsed_us));
  j["avatar"] = A.id;
  j["others"] = others;
  return j.dump();
}

}  // namespace sweptccd::world
