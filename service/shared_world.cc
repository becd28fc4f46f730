#include "service/shared_world.h"

#include <algorithm>
#include <chrono>
#include <exception>
#include <utility>

#include "core/errors.h"
#include "core/query/ccd_query.h"
#include "core/query/result_json.h"
#include "core/world/entity_broad_phase.h"
#include "core/world/window_split.h"

namespace sweptccd {

namespace {

int64_t MicrosSince(SteadyClock::time_point from, SteadyClock::time_point to) {
  return std::max<int64_t>(
      0, std::chrono::duration_cast<std::chrono::microseconds>(to - from).count());
}

void Put3(const Eigen::Vector3d& v, double out[3]) {
  for (int k = 0; k < 3; ++k) out[k] = v[k];
}

// The wire form of the records of core/world/entity_query.h (the numbers
// `sweptccd world` prints, by MakeEntityRecord).
entity_contact_t ContactOf(const world::EntityContactRecord& c) {
  entity_contact_t out;
  out.link = c.link;
  out.other_link = c.other_link;
  out.triangle = c.triangle;
  out.s = c.s;
  Put3(c.point_link, out.point_link);
  Put3(c.point_other, out.point_other);
  Put3(c.normal, out.normal);
  out.separation = c.separation;
  return out;
}

// The bracket fields an entry and a per-link bracket share.
template <typename Msg>
void PutBracket(const world::EntityBracketRecord& p, Msg* out) {
  out->s_lo = p.s_lo;
  out->s_hi = p.s_hi;
  out->t_lo = p.t_lo;
  out->t_hi = p.t_hi;
  out->initially_colliding = p.initially_colliding;
  out->undecided = p.undecided;
}

entity_link_bracket_t LinkBracketOf(const world::EntityBracketRecord& p) {
  entity_link_bracket_t out{};
  out.link = p.link;
  PutBracket(p, &out);
  out.has_witness = p.has_witness;
  if (p.has_witness) out.witness = ContactOf(p.witness);
  return out;
}

// An entry naming the job's entity and window, its result `free`.
shared_entry_t EntryOf(const SharedJob& job) {
  shared_entry_t m{};
  m.entity = job.entity;
  m.entity_kind = job.entity_is_object ? shared_entry_t::KIND_OBJECT : shared_entry_t::KIND_AVATAR;
  m.t_from = job.t_from;
  m.t_to = job.t_to;
  m.result = shared_entry_t::RESULT_FREE;
  m.waited_us = job.waited_us;
  m.ended_by_timeout = job.ended_by_timeout;
  return m;
}

const std::vector<world::EntityRule>& RulesOf(const std::shared_ptr<const AvatarAnswerOptions>& o) {
  static const std::vector<world::EntityRule> none;
  return o ? o->rules : none;
}

// The entity query over the job's slice (the window re-based on it).
world::OtherAnswer AnswerJob(const SharedJob& job, const world::EntityQueryOptions& options) {
  const int64_t u0 = job.pose0.utime, u1 = job.pose1.utime;
  std::optional<PairMotion> own;
  const PairMotion& motion = job.pair_motion
                                 ? *job.pair_motion
                                 : own.emplace(*job.skeleton_a, job.pose0, job.pose1, job.motion_a);
  MotionMemo memo(motion);
  const world::PairSide a{world::FilterSide{job.client_id, RulesOf(job.own_a)}, *job.skeleton_a, u0,
                          u1, &memo};
  if (job.entity_is_object) {
    const world::ObjectWindow o{job.entity, *job.mesh_e, job.object_samples};
    const world::EntryWindow w = world::WindowOver(u0, job.t_from, job.t_to, o.samples.size(),
                                                   [&](size_t k) { return o.samples[k].utime; });
    return world::AnswerAgainstObject(a, o, w, options);
  }
  const world::AvatarWindow b{world::FilterSide{job.entity, RulesOf(job.own_e)}, *job.skeleton_e,
                              job.motion_e, job.avatar_samples};
  const world::EntryWindow w = world::WindowOver(u0, job.t_from, job.t_to, b.samples.size(),
                                                 [&](size_t k) { return b.samples[k].utime; });
  return world::AnswerAgainstAvatar(a, b, w, options);
}

}  // namespace

shared_entry_t AnswerSharedJob(const SharedJob& job, const world::EntityQueryOptions& given) {
  world::EntityQueryOptions options = given;
  if (job.own_a && job.own_a->eps_s > 0) options.eps_s = job.own_a->eps_s;
  if (job.own_a && job.own_a->delta_m > 0) options.delta_m = job.own_a->delta_m;
  shared_entry_t m = EntryOf(job);
  const auto start = SteadyClock::now();
  // A job made outside SharedWorld (tests) has no due time: no wait.
  const double queue_us =
      job.due_time == SteadyClock::time_point{}
          ? 0.0
          : std::chrono::duration<double, std::micro>(start - job.due_time).count();
  if (job.cleared_by_box) {
    m.compute_us = std::chrono::duration<double, std::micro>(SteadyClock::now() - start).count();
    m.queue_us = queue_us;
    return m;
  }
  try {
    const world::EntityRecord r =
        world::MakeEntityRecord(job.entity, job.entity_is_object, job.pose0.utime, job.pose1.utime,
                                job.t_from, job.t_to, AnswerJob(job, options), options.per_link);
    if (r.contact) {
      m.result = shared_entry_t::RESULT_CONTACT;
      PutBracket(r.bracket, &m);
      for (const world::EntityContactRecord& c : r.contacts) m.contacts.push_back(ContactOf(c));
      m.num_contacts = static_cast<int32_t>(m.contacts.size());
    }
    for (const world::EntityBracketRecord& b : r.links) m.links.push_back(LinkBracketOf(b));
    m.num_links = static_cast<int32_t>(m.links.size());
  } catch (const std::exception& e) {
    m = EntryOf(job);
    m.result = shared_entry_t::RESULT_INVALID;
    m.error = std::string("query failed: ") + e.what();
  }
  m.compute_us = std::chrono::duration<double, std::micro>(SteadyClock::now() - start).count();
  m.queue_us = queue_us;
  return m;
}

shared_contact_t SharedMessageOf(const SharedJob& job) {
  shared_contact_t m{};
  m.client_id = job.client_id;
  m.seq0 = job.seq0;
  m.seq1 = job.seq1;
  m.pair = job.pair;
  m.utime0 = job.pose0.utime;
  m.utime1 = job.pose1.utime;
  m.receive_utime = job.receive_utime;
  m.num_entries = 0;
  return m;
}

SharedWorld::SharedWorld(SharedWorldOptions options) : options_(options) {
  if (options_.silence_timeout_us < 1 || options_.max_history < 2 || options_.max_pending < 1) {
    throw InputError(
        "shared world: silence_timeout_us must be >= 1, max_history >= 2 and "
        "max_pending >= 1");
  }
}

void SharedWorld::AddAvatar(const std::string& id, std::shared_ptr<const Skeleton> skeleton,
                            MotionModel motion, Time now, const AvatarAnswerOptions& own) {
  SWEPTCCD_CHECK(!Has(id) && skeleton && own.eps_s >= 0 && own.delta_m >= 0);
  Entity e;
  e.id = id;
  e.skeleton = std::move(skeleton);
  e.motion = motion;
  e.own = std::make_shared<const AvatarAnswerOptions>(own);
  e.last_heard = now;
  e.last_sample_time = now;
  entities_.emplace(id, std::move(e));
  order_.push_back(id);
}

void SharedWorld::AddObject(const std::string& id, std::shared_ptr<const Environment> mesh,
                            Time now) {
  SWEPTCCD_CHECK(!Has(id) && mesh && mesh->num_objects() == 1);
  Entity e;
  e.id = id;
  e.is_object = true;
  e.mesh = std::move(mesh);
  const TriangleBvh& bvh = e.mesh->object(0).bvh;
  e.radius = world::ObjectRadius(bvh);
  e.mesh_scale = bvh.max_abs_coordinate();
  e.last_heard = now;
  e.last_sample_time = now;
  entities_.emplace(id, std::move(e));
  order_.push_back(id);
}

void SharedWorld::RemoveAvatar(const std::string& id, Time now, std::vector<SharedJob>* due) {
  if (!Has(id)) return;
  Settle(
      id, [](const Entry&) { return true; }, /*cut=*/true, now, due);
  for (auto& [other, e] : entities_) {
    e.pending.erase(std::remove_if(e.pending.begin(), e.pending.end(),
                                   [&](const Entry& x) { return x.a == id; }),
                    e.pending.end());
  }
  entities_.erase(id);
  order_.erase(std::remove(order_.begin(), order_.end(), id), order_.end());
}

size_t SharedWorld::pending() const {
  size_t n = 0;
  for (const auto& [id, e] : entities_) n += e.pending.size();
  return n;
}

int64_t SharedWorld::history_size(const std::string& id) const {
  const auto it = entities_.find(id);
  return it == entities_.end() ? 0 : static_cast<int64_t>(it->second.size());
}

Aabb SharedWorld::IntervalBox(const Entity& e, size_t k0, size_t k1,
                              std::shared_ptr<const PairMotion>* motion) {
  if (e.is_object) {
    return world::ObjectMotionBox(e.object_samples[k0], e.object_samples[k1], e.radius,
                                  e.mesh_scale);
  }
  auto m = std::make_shared<const PairMotion>(*e.skeleton, e.avatar_samples[k0],
                                              e.avatar_samples[k1], e.motion);
  const Aabb box = world::AvatarMotionBox(*e.skeleton, *m);
  if (motion != nullptr) *motion = std::move(m);
  return box;
}

void SharedWorld::Append(Entity* e, Time now) {
  // The new sample closes an interval: its box (and an avatar's motion,
  // for the pair it closes), on the receiving thread, once, rather than
  // once per entry that uses it.
  if (e->size() >= 2) {
    e->boxes.push_back(IntervalBox(*e, e->size() - 2, e->size() - 1, &e->last_motion));
  }
  e->last_heard = now;
  e->last_sample_time = now;
  while (static_cast<int>(e->size()) > options_.max_history) {
    if (e->is_object) {
      e->object_samples.pop_front();
    } else {
      e->avatar_samples.pop_front();
    }
    e->boxes.pop_front();  // One fewer than the samples, so one is there.
    e->evicted = true;
  }
}

void SharedWorld::OnAvatarSample(const std::string& id, int64_t session, const Pose& pose, Time now,
                                 std::vector<SharedJob>* due) {
  const auto it = entities_.find(id);
  if (it == entities_.end()) return;
  Entity& e = it->second;
  if (e.has_stream && session != e.session) {
    // A new stream: what waited for the old one ends at its last sample.
    Settle(
        id, [](const Entry&) { return true; }, /*cut=*/true, now, due);
    e.avatar_samples.clear();
    e.boxes.clear();
    e.last_motion.reset();
    e.evicted = false;
  }
  e.has_stream = true;
  e.session = session;
  // ClientSession accepted it: strictly after the last sample of the stream.
  SWEPTCCD_CHECK(e.avatar_samples.empty() || pose.utime > e.avatar_samples.back().utime);
  e.avatar_samples.push_back(pose);
  Append(&e, now);
  Settle(
      id, [&](const Entry& x) { return Covered(e, x); }, /*cut=*/false, now, due);
}

std::optional<Rejection> SharedWorld::OnObjectPose(const object_pose_t& msg,
                                                   int64_t max_utime_jump_us, Time now,
                                                   std::vector<SharedJob>* due) {
  const auto it = entities_.find(msg.object_id);
  if (it == entities_.end() || !it->second.is_object) {
    return Rejection{rejection_code::kUnknownObject,
                     "object_id '" + msg.object_id +
                         "' is not a tracked object of this daemon; configure it under "
                         "`objects:` (id, mesh, key)"};
  }
  Entity& e = it->second;
  double v[7];
  for (int k = 0; k < 3; ++k) v[k] = msg.position[k];
  for (int k = 0; k < 4; ++k) v[3 + k] = msg.orientation[k];
  // The rule and the wording of an avatar's link pose (one link).
  if (const std::optional<PoseProblem> problem = world::FindRigidProblem(v)) {
    return PoseRejection(*problem,
                         "object '" + msg.object_id + "' seq " + std::to_string(msg.seq) + ": ");
  }
  world::RigidSample x;
  SWEPTCCD_CHECK(world::MakeRigidSample(msg.utime, v, &x).empty());
  const bool new_stream = !e.has_stream || msg.session > e.session;
  if (!new_stream) {
    if (msg.session < e.session) {
      return Rejection{rejection_code::kStaleSession,
                       "object '" + msg.object_id + "' session " + std::to_string(msg.session) +
                           " is older than its current session " + std::to_string(e.session) +
                           "; a restarted tracker takes a greater session"};
    }
    if (msg.seq <= e.last_seq) {
      return Rejection{rejection_code::kNonIncreasingSeq,
                       "object '" + msg.object_id + "' seq " + std::to_string(msg.seq) +
                           " is not greater than " + std::to_string(e.last_seq) +
                           "; number samples strictly increasingly"};
    }
    // A stream's history is never empty: a new stream starts with its sample.
    SWEPTCCD_CHECK(!e.object_samples.empty());
    const int64_t last = e.object_samples.back().utime;
    if (msg.utime <= last) {
      return Rejection{rejection_code::kNonIncreasingUtime,
                       "object '" + msg.object_id + "' utime " + std::to_string(msg.utime) +
                           " is not after " + std::to_string(last) +
                           "; stamp samples strictly increasingly"};
    }
    // The avatar's rule (UtimeJump: no signed overflow for hostile utimes).
    if (UtimeJump(last, msg.utime) > static_cast<uint64_t>(max_utime_jump_us)) {
      return Rejection{rejection_code::kUtimeJump,
                       "object '" + msg.object_id + "' utime " + std::to_string(msg.utime) +
                           " is more than max_utime_jump_s after " + std::to_string(last) +
                           "; fix the tracker's clock, or start a new session"};
    }
  }
  if (new_stream && e.has_stream) {
    Settle(
        msg.object_id, [](const Entry&) { return true; }, /*cut=*/true, now, due);
    e.object_samples.clear();
    e.boxes.clear();
    e.evicted = false;
  }
  e.has_stream = true;
  e.session = msg.session;
  e.last_seq = msg.seq;
  e.object_samples.push_back(x);
  Append(&e, now);
  Settle(
      msg.object_id, [&](const Entry& y) { return Covered(e, y); }, /*cut=*/false, now, due);
  return std::nullopt;
}

bool SharedWorld::Covered(const Entity& e, const Entry& entry) {
  // The window [t_from, utime1] and every sample the offline answer uses for
  // it are in once E has a sample at or after utime1: SplitWindow's pieces
  // end with E's interval into its first sample at or after t_to, and skip
  // that sample's instant (a boundary instant of a longer window), so
  // nothing after it is read. So a sample stamped at utime1 itself covers
  // (trackers that stamp every body at the same frame times get their
  // shared answer in that frame, not the next), except for a window that is
  // one instant (E's first sample at utime1): its one piece lies in E's
  // interval after that sample, which needs the next sample.
  if (e.size() == 0) return false;
  const int64_t newest = e.utime(e.size() - 1), u1 = entry.pair->pose1.utime;
  if (newest > u1) return true;
  return newest == u1 && std::max(entry.pair->pose0.utime, e.utime(0)) < u1;
}

bool SharedWorld::MakeJob(const Entity& e, const Entry& entry, bool cut, Time now,
                          SharedJob* job) const {
  const size_t n = e.size();
  const int64_t u0 = entry.pair->pose0.utime, u1 = entry.pair->pose1.utime;
  // The window rule of `sweptccd world` (window_split.h) over the kept
  // samples; its pieces over the slice [first, last] are E's intervals
  // first + k, whose boxes are those of the whole history.
  const std::optional<world::EntryWindow> window =
      world::WindowOf(u0, u1, n, [&](size_t k) { return e.utime(k); });
  if (!window) return false;  // No overlap: no entry (as offline).
  const int64_t t_from = window->t_from, t_to = window->t_to;
  job->cleared_by_box =
      options_.broad_phase && !world::EntryNear(entry.pair->box_a, window->pieces, [&](size_t k) {
        return n == 1 ? IntervalBox(e, 0, 0) : e.boxes[k];
      });
  job->client_id = entry.a;
  job->pair = entry.pair->pair;
  job->seq0 = entry.pair->seq0;
  job->seq1 = entry.pair->seq1;
  job->receive_utime = entry.pair->receive_utime;
  job->skeleton_a = entry.skeleton_a;
  job->motion_a = entry.motion_a;
  job->pair_motion = entry.pair->motion;
  job->own_a = entry.own_a;
  job->own_e = e.own;  // Null for an object.
  if (job->cleared_by_box) {
    // Only the utimes are read (SharedMessageOf, the pair's batch key).
    job->pose0.utime = u0;
    job->pose1.utime = u1;
  } else {
    job->pose0 = entry.pair->pose0;
    job->pose1 = entry.pair->pose1;
  }
  job->entity = e.id;
  job->entity_is_object = e.is_object;
  job->skeleton_e = e.skeleton;
  job->motion_e = e.motion;
  job->mesh_e = e.mesh;
  job->avatar_samples.clear();
  job->object_samples.clear();
  for (size_t k = window->first; k <= window->last && !job->cleared_by_box; ++k) {
    if (e.is_object) {
      job->object_samples.push_back(e.object_samples[k]);
    } else {
      job->avatar_samples.push_back(e.avatar_samples[k]);
    }
  }
  job->t_from = t_from;
  job->t_to = t_to;
  // The window may reach before the oldest sample kept: then it is cut too.
  job->ended_by_timeout = cut || (e.evicted && e.utime(0) > u0);
  job->waited_us = MicrosSince(entry.pair->receive_time, cut ? now : e.last_sample_time);
  job->due_time = now;
  return true;
}

template <class Pred>
void SharedWorld::Settle(const std::string& id, Pred pred, bool cut, Time now,
                         std::vector<SharedJob>* due) {
  const auto it = entities_.find(id);
  if (it == entities_.end()) return;
  Entity& e = it->second;
  auto keep = e.pending.begin();
  for (auto x = e.pending.begin(); x != e.pending.end(); ++x) {
    if (pred(*x)) {
      SettleOne(e, *x, cut, now, due);
      continue;
    }
    if (keep != x) *keep = std::move(*x);
    ++keep;
  }
  e.pending.erase(keep, e.pending.end());
}

void SharedWorld::SettleOne(const Entity& e, const Entry& entry, bool cut, Time now,
                            std::vector<SharedJob>* due) {
  SharedJob job;
  if (!MakeJob(e, entry, cut, now, &job)) return;
  if (job.ended_by_timeout) ++entries_cut_;
  if (job.cleared_by_box) ++entries_cleared_;
  due->push_back(std::move(job));
}

void SharedWorld::AddPair(const std::string& id, const PosePair& pair, Time now,
                          std::vector<SharedJob>* due) {
  const auto it = entities_.find(id);
  if (it == entities_.end() || it->second.is_object) return;
  const Entity& a = it->second;
  // One copy of the pair and its box for all its entries: an entry then
  // allocates nothing of its own.
  auto shared = std::make_shared<SharedPair>();
  static_cast<PosePair&>(*shared) = pair;
  // A's box over the pair: the box of A's history interval holding the same
  // two poses when there is one (made as the second arrived), else made here.
  // (Searched from the newest sample: the pair is at or near the end.)
  size_t k = a.size();
  while (k > 0 && a.utime(k - 1) > pair.pose0.utime) --k;
  // A's motion likewise: the one made with the box of A's last interval
  // when the pair is that interval, else made here; once for all entries.
  const bool in_history = k > 0 && k < a.size() && SamePose(a.avatar_samples[k - 1], pair.pose0) &&
                          SamePose(a.avatar_samples[k], pair.pose1);
  if (in_history && k + 1 == a.size()) shared->motion = a.last_motion;
  if (!shared->motion) {
    shared->motion =
        std::make_shared<const PairMotion>(*a.skeleton, pair.pose0, pair.pose1, a.motion);
  }
  shared->box_a =
      in_history ? a.boxes[k - 1] : world::AvatarMotionBox(*a.skeleton, *shared->motion);
  for (const std::string& other : order_) {
    if (other == id) continue;
    Entry entry;
    entry.a = id;
    entry.skeleton_a = a.skeleton;
    entry.motion_a = a.motion;
    entry.own_a = a.own;
    entry.pair = shared;
    entry.created = now;
    entry.number = next_entry_number_++;
    // Covered already (E is ahead): due now, never pending.
    Entity& e = entities_.at(other);
    if (Covered(e, entry)) {
      SettleOne(e, entry, /*cut=*/false, now, due);
    } else {
      e.pending.push_back(std::move(entry));
    }
  }
  // (Silence is cut by CutSilent, on the daemon's timer: not here, where a
  // scan of every entry per pair would cost O(entities x pending).)
  // Over the cap: the oldest entry of all (the least number among the
  // entities' oldest) is cut, as one list in creation order would cut.
  while (pending() > static_cast<size_t>(options_.max_pending)) {
    Entity* oldest = nullptr;
    for (auto& [other, e] : entities_) {
      if (!e.pending.empty() &&
          (oldest == nullptr || e.pending.front().number < oldest->pending.front().number)) {
        oldest = &e;
      }
    }
    SWEPTCCD_CHECK(oldest != nullptr);
    ++entries_overflowed_;
    SettleOne(*oldest, oldest->pending.front(), /*cut=*/true, now, due);
    oldest->pending.pop_front();
  }
}

void SharedWorld::CutSilent(Time now, std::vector<SharedJob>* due) {
  const auto timeout = std::chrono::microseconds(options_.silence_timeout_us);
  for (const std::string& id : order_) {
    const Entity& e = entities_.at(id);
    const bool silent = now - e.last_heard >= timeout;
    Settle(
        id, [&](const Entry& x) { return silent || now - x.created >= timeout; },
        /*cut=*/true, now, due);
  }
}

void SharedWorld::CutAll(Time now, std::vector<SharedJob>* due) {
  for (const std::string& id : order_) {
    Settle(
        id, [](const Entry&) { return true; }, /*cut=*/true, now, due);
  }
}

}  // namespace sweptccd
