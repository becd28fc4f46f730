// The daemon's shared world (service/shared_world.h) against `sweptccd
// world`'s engine (core/world/world_query.h) on the same samples: two avatars
// at 90 Hz and 60 Hz with different phases and network delays and a tracked
// object at 30 Hz, fed in arrival order on a fake steady clock (no sleeps);
// every entry equal to the offline one. Then the cuts: silence, a full
// pending list, a history too short, a new session; and bad object poses.

#include "service/shared_world.h"

#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <algorithm>
#include <cstdio>
#include <functional>
#include <limits>
#include <map>
#include <nlohmann/json.hpp>
#include <random>
#include <set>
#include <string>
#include <tuple>
#include <vector>

#include "core/world/entity_broad_phase.h"
#include "core/world/world_query.h"

namespace sweptccd {
namespace {

using Time = SharedWorld::Time;
using json = nlohmann::json;

Time At(int64_t us) { return Time(std::chrono::microseconds(us)); }

std::shared_ptr<const Skeleton> Arm() {
  Link root{"upper", -1, {0, 0, 0}, {0, 0.3, 0}, 0.05};
  Link child{"fore", 0, {0, 0, 0}, {0.3, 0, 0}, 0.04};
  return std::make_shared<const Skeleton>(Skeleton::FromLinks("arm", {root, child}, "test"));
}

// A cube of half size h around the object's frame origin.
std::shared_ptr<const Environment> Cube(double h) {
  TriangleMesh m;
  for (int c = 0; c < 8; ++c) {
    m.vertices.emplace_back((c & 1) ? h : -h, (c & 2) ? h : -h, (c & 4) ? h : -h);
  }
  const uint32_t f[12][3] = {{0, 1, 3}, {0, 3, 2}, {4, 6, 7}, {4, 7, 5}, {0, 4, 5}, {0, 5, 1},
                             {2, 3, 7}, {2, 7, 6}, {0, 2, 6}, {0, 6, 4}, {1, 5, 7}, {1, 7, 3}};
  for (const auto& t : f) m.indices.insert(m.indices.end(), {t[0], t[1], t[2]});
  auto env = std::make_shared<Environment>();
  env->AddMesh(m, "cube");
  return env;
}

// A random walk of the arm around `center` (its bones keep their length).
class Walker {
 public:
  Walker(uint64_t seed, Eigen::Vector3d center) : rng_(seed), p_(center), center_(center) {}
  Pose Next(int64_t utime) {
    std::normal_distribution<double> n(0, 1);
    p_ += 0.02 * Eigen::Vector3d(n(rng_), n(rng_), n(rng_)) + 0.1 * (center_ - p_);
    q_ = (q_ * Eigen::Quaterniond(Eigen::AngleAxisd(0.15 * n(rng_), Eigen::Vector3d::UnitZ())))
             .normalized();
    Pose pose;
    pose.utime = utime;
    pose.links.push_back(LinkPose{p_, q_});
    pose.links.push_back(LinkPose{p_ + q_ * Eigen::Vector3d(0, 0.3, 0), q_});
    return pose;
  }

 private:
  std::mt19937_64 rng_;
  Eigen::Vector3d p_, center_;
  Eigen::Quaterniond q_{1, 0, 0, 0};
};

object_pose_t ObjectPose(const std::string& id, int64_t utime, int64_t seq,
                         const Eigen::Vector3d& p, const Eigen::Quaterniond& q) {
  object_pose_t m{};
  m.utime = utime;
  m.object_id = id;
  m.session = 1;
  m.seq = seq;
  for (int k = 0; k < 3; ++k) m.position[k] = p[k];
  m.orientation[0] = q.w(), m.orientation[1] = q.x(), m.orientation[2] = q.y();
  m.orientation[3] = q.z();
  return m;
}

// One sample as it arrives at the daemon.
struct Arrival {
  int64_t at_us;
  int entity;  // 0 alice, 1 bob, 2 box.
  Pose pose;
  object_pose_t object;
};

// The object sample the daemon makes of a pose (p, q) at t.
world::RigidSample SampleOf(int64_t t, const Eigen::Vector3d& p, const Eigen::Quaterniond& q) {
  world::RigidSample x;
  const double v[7] = {p.x(), p.y(), p.z(), q.w(), q.x(), q.y(), q.z()};
  EXPECT_EQ(world::MakeRigidSample(t, v, &x), "");
  return x;
}

// In the order they reach the daemon (ties as generated).
void SortByArrival(std::vector<Arrival>* arrivals) {
  std::stable_sort(arrivals->begin(), arrivals->end(),
                   [](const Arrival& x, const Arrival& y) { return x.at_us < y.at_us; });
}

// The offline world of the same samples, and its answerer.
struct Offline {
  world::LoadedWorld w;
  std::unique_ptr<world::WorldAnswerer> answerer;
  void AddAvatar(const std::string& id, const std::vector<Pose>& used) {
    world::AvatarEntity a;
    a.id = id;
    a.skeleton = *Arm();
    a.used = used;
    for (size_t k = 1; k < used.size(); ++k) {
      PairOutcome r;
      r.pair = static_cast<int64_t>(k - 1);
      r.valid = true;
      r.utime0 = used[k - 1].utime;
      r.utime1 = used[k].utime;
      r.pose0 = used[k - 1];
      r.pose1 = used[k];
      a.records.push_back(r);
    }
    w.world.avatars.push_back(std::move(a));
    w.world.rules.emplace_back();
    w.env_filters.emplace_back();
  }
  // The `others` entries of avatar a's record r, by entity id.
  std::map<std::string, json> Others(int a, size_t r) const {
    std::map<std::string, json> out;
    const json record = json::parse(answerer->RecordJson(world::AvatarIndex(a), r));
    for (const json& e : record["others"]) {
      out[e["entity"].get<std::string>()] = e;
    }
    return out;
  }
};

// Avatar `id`'s next sample `pose`, received at its utime: the sample, then
// the pair it closes with the previous one of *used (index *pairs).
void Feed(SharedWorld* live, const std::string& id, const Pose& pose, std::vector<Pose>* used,
          int64_t* pairs, std::vector<SharedJob>* due) {
  live->OnAvatarSample(id, 1, pose, At(pose.utime), due);
  if (!used->empty()) {
    PosePair p;
    p.pair = (*pairs)++;
    p.seq0 = p.pair, p.seq1 = p.pair + 1;
    p.pose0 = used->back();
    p.pose1 = pose;
    p.receive_time = At(pose.utime);
    live->AddPair(id, p, At(pose.utime), due);
  }
  used->push_back(pose);
}

// The entity options CollisionService derives from its query options.
world::EntityQueryOptions EntityOptionsOf(const QueryOptions& q) {
  world::EntityQueryOptions eo;
  eo.eps_s = q.eps_s;
  eo.delta_m = q.delta_m;
  eo.max_intervals = q.max_intervals;
  return eo;
}

// A tracked box (Cube(0.08)) with these samples, in the offline world.
void AddBox(Offline* off, const std::vector<world::RigidSample>& used) {
  world::ObjectEntity box;
  box.id = "box";
  box.mesh = Cube(0.08);
  box.used = used;
  off->w.world.objects.push_back(box);
}

void ExpectEqualToOffline(const SharedJob& job, const shared_entry_t& live, const json& off) {
  SCOPED_TRACE(job.client_id + " pair " + std::to_string(job.pair) + " vs " + live.entity);
  EXPECT_EQ(live.t_from, off["window"][0].get<int64_t>());
  EXPECT_EQ(live.t_to, off["window"][1].get<int64_t>());
  EXPECT_EQ(live.entity_kind == shared_entry_t::KIND_OBJECT ? "object" : "avatar",
            off["kind"].get<std::string>());
  ASSERT_NE(+live.result, +shared_entry_t::RESULT_INVALID) << live.error;
  const bool contact = off["result"] == "contact";
  ASSERT_EQ(live.result == shared_entry_t::RESULT_CONTACT, contact);
  EXPECT_EQ(live.initially_colliding, off["initially_colliding"].get<bool>());
  EXPECT_EQ(live.undecided, off["undecided"].get<bool>());
  if (!contact) return;
  EXPECT_EQ(live.s_lo, off["s_lo"].get<double>());
  EXPECT_EQ(live.s_hi, off["s_hi"].get<double>());
  EXPECT_EQ(live.t_lo, off["t_lo"].get<double>());
  EXPECT_EQ(live.t_hi, off["t_hi"].get<double>());
  ASSERT_EQ(live.contacts.size(), off["contacts"].size());
  for (size_t i = 0; i < live.contacts.size(); ++i) {
    const entity_contact_t& c = live.contacts[i];
    const json& o = off["contacts"][i];
    EXPECT_EQ(c.link, o["link"].get<int>());
    EXPECT_EQ(c.other_link, o.contains("other_link") ? o["other_link"].get<int>() : -1);
    EXPECT_EQ(c.triangle, o.contains("triangle") ? o["triangle"].get<int64_t>() : -1);
    EXPECT_EQ(c.s, o["s"].get<double>());
    for (int k = 0; k < 3; ++k) {
      EXPECT_EQ(c.point_link[k], o["point_link"][k].get<double>());
      EXPECT_EQ(c.point_other[k], o["point_other"][k].get<double>());
      EXPECT_EQ(c.normal[k], o["normal"][k].get<double>());
    }
    EXPECT_EQ(c.separation, o["separation"].get<double>());
  }
}

// Per-link mode: the live entry's `links` equal `sweptccd world --per-link`'s.
void ExpectLinksEqualToOffline(const SharedJob& job, const shared_entry_t& live, const json& off) {
  SCOPED_TRACE(job.client_id + " pair " + std::to_string(job.pair) + " vs " + live.entity +
               " (per link)");
  ASSERT_TRUE(off.contains("links"));
  ASSERT_EQ(live.num_links, static_cast<int32_t>(live.links.size()));
  ASSERT_EQ(live.links.size(), off["links"].size());
  for (size_t i = 0; i < live.links.size(); ++i) {
    const entity_link_bracket_t& b = live.links[i];
    const json& o = off["links"][i];
    EXPECT_EQ(b.link, o["link"].get<int>());
    EXPECT_EQ(b.s_lo, o["s_lo"].get<double>());
    EXPECT_EQ(b.s_hi, o["s_hi"].get<double>());
    EXPECT_EQ(b.t_lo, o["t_lo"].get<double>());
    EXPECT_EQ(b.t_hi, o["t_hi"].get<double>());
    EXPECT_EQ(b.initially_colliding, o["initially_colliding"].get<bool>());
    EXPECT_EQ(b.undecided, o["undecided"].get<bool>());
    ASSERT_EQ(static_cast<bool>(b.has_witness), o.contains("contact"));
    if (!b.has_witness) continue;
    const json& w = o["contact"];
    EXPECT_EQ(b.witness.link, w["link"].get<int>());
    EXPECT_EQ(b.witness.s, w["s"].get<double>());
    EXPECT_EQ(b.witness.separation, w["separation"].get<double>());
    for (int k = 0; k < 3; ++k) {
      EXPECT_EQ(b.witness.point_link[k], w["point_link"][k].get<double>());
      EXPECT_EQ(b.witness.point_other[k], w["point_other"][k].get<double>());
    }
  }
}

// far_tail: bob's last samples jump 1000 km away. An answer whose rounding
// slack scaled with the whole stream would change for every earlier window
// (WindowScale keeps it to the window's samples, live and offline).
void RunClientsAtDifferentRates(bool far_tail) {
  const std::vector<std::string> ids = {"alice", "bob", "box"};
  const int64_t period[3] = {11'111, 16'667, 33'333};  // 90, 60, 30 Hz.
  const int64_t phase[3] = {0, 5'000, 12'000};
  const int64_t delay[3] = {1'000, 20'000, 7'000};  // Network delay to the daemon.
  const int64_t start = 1'000'000, end = 2'500'000;
  Walker alice(1, {0, 0, 0}), bob(2, {0.25, 0.05, 0});
  std::mt19937_64 rng(3);
  std::normal_distribution<double> n(0, 1);
  std::vector<Arrival> arrivals;
  std::vector<Pose> used[2];
  std::vector<world::RigidSample> box_used;
  Eigen::Vector3d box_p(0.1, 0.25, 0);
  for (int e = 0; e < 3; ++e) {
    int64_t seq = 0;
    for (int64_t t = start + phase[e]; t <= end; t += period[e]) {
      Arrival a{t + delay[e], e, {}, {}};
      if (e < 2) {
        a.pose = (e == 0 ? alice : bob).Next(t);
        if (far_tail && e == 1 && t > end - 50'000) {
          for (LinkPose& l : a.pose.links) l.p.x() += 1e6;
        }
        used[e].push_back(a.pose);
      } else {
        box_p += 0.03 * Eigen::Vector3d(n(rng), n(rng), n(rng)) +
                 0.2 * (Eigen::Vector3d(0.1, 0.25, 0) - box_p);
        const Eigen::Quaterniond q(Eigen::AngleAxisd(0.3 * n(rng), Eigen::Vector3d::UnitX()));
        a.object = ObjectPose("box", t, ++seq, box_p, q);
        box_used.push_back(SampleOf(t, box_p, q));
      }
      arrivals.push_back(a);
    }
  }
  SortByArrival(&arrivals);

  Offline off;
  off.AddAvatar("alice", used[0]);
  off.AddAvatar("bob", used[1]);
  AddBox(&off, box_used);
  QueryOptions qo;
  off.answerer = std::make_unique<world::WorldAnswerer>(off.w, qo);
  const world::EntityQueryOptions eo = EntityOptionsOf(qo);
  // The same in per-link mode (every 4th entry, to bound the test's time).
  QueryOptions qo_links = qo;
  qo_links.per_link = true;
  const world::WorldAnswerer links_answerer(off.w, qo_links);
  world::EntityQueryOptions eo_links = eo;
  eo_links.per_link = true;
  int per_link_compared = 0, per_link_brackets = 0;

  SharedWorldOptions so;
  so.silence_timeout_us = 200'000;
  SharedWorld live(so);
  // Registered as the streams start (silence counts from registration).
  live.AddAvatar("alice", Arm(), MotionModel::kArticulated, At(start));
  live.AddAvatar("bob", Arm(), MotionModel::kArticulated, At(start));
  live.AddObject("box", Cube(0.08), At(start));

  std::vector<SharedJob> due;
  int64_t pair_count[2] = {0, 0};
  std::optional<Pose> last[2];
  for (const Arrival& a : arrivals) {
    if (a.entity == 2) {
      ASSERT_FALSE(live.OnObjectPose(a.object, 10'000'000, At(a.at_us), &due).has_value());
      continue;
    }
    live.OnAvatarSample(ids[a.entity], 1, a.pose, At(a.at_us), &due);
    if (last[a.entity]) {
      PosePair p;
      p.pair = pair_count[a.entity]++;
      p.seq0 = p.pair, p.seq1 = p.pair + 1;
      p.pose0 = *last[a.entity];
      p.pose1 = a.pose;
      p.receive_time = At(a.at_us);
      live.AddPair(ids[a.entity], p, At(a.at_us), &due);
    }
    last[a.entity] = a.pose;
  }
  const size_t covered = due.size();
  // Every entity stops: what still waits ends at its last sample.
  live.CutSilent(At(end + 1'000'000), &due);
  EXPECT_EQ(live.pending(), 0u);

  // Offline: every overlapping (record, entity) entry, and which of them the
  // live service can certify (the entity has a sample after utime1).
  std::set<std::tuple<std::string, int64_t, std::string>> expected_covered, expected_all;
  const int64_t last_utime[3] = {used[0].back().utime, used[1].back().utime, box_used.back().utime};
  int contacts = 0;
  for (int a = 0; a < 2; ++a) {
    for (size_t r = 0; r < off.w.world.avatars[a].records.size(); ++r) {
      for (const auto& [entity, e] : off.Others(a, r)) {
        expected_all.insert({ids[a], static_cast<int64_t>(r), entity});
        const int ei = entity == "alice" ? 0 : entity == "bob" ? 1 : 2;
        if (last_utime[ei] > *off.w.world.avatars[a].records[r].utime1) {
          expected_covered.insert({ids[a], static_cast<int64_t>(r), entity});
        }
        contacts += e["result"] == "contact";
      }
    }
  }
  EXPECT_GT(contacts, 20) << "the scene must have contacts to compare";
  std::printf("%zu offline entries, %d contacts, %zu certified live at once or after a wait\n",
              expected_all.size(), contacts, covered);
  EXPECT_LT(contacts, static_cast<int>(expected_all.size())) << "and free entries";

  std::set<std::tuple<std::string, int64_t, std::string>> got_covered, got_all;
  int waited = 0;
  for (size_t i = 0; i < due.size(); ++i) {
    const SharedJob& job = due[i];
    const auto key = std::make_tuple(job.client_id, job.pair, job.entity);
    EXPECT_TRUE(got_all.insert(key).second) << "answered twice";
    EXPECT_EQ(job.ended_by_timeout, i >= covered);
    if (!job.ended_by_timeout) got_covered.insert(key);
    waited += job.waited_us > 0;
    const shared_entry_t m = AnswerSharedJob(job, eo);
    const int a = job.client_id == "alice" ? 0 : 1;
    // Entries the entity really ended are equal too: the same samples.
    ExpectEqualToOffline(job, m, off.Others(a, static_cast<size_t>(job.pair)).at(job.entity));
    EXPECT_EQ(m.waited_us, job.waited_us);
    EXPECT_TRUE(m.links.empty()) << "no per-link brackets outside per-link mode";
    if (i % 4 == 0 || m.result == shared_entry_t::RESULT_CONTACT) {
      const shared_entry_t ml = AnswerSharedJob(job, eo_links);
      const json record = json::parse(
          links_answerer.RecordJson(world::AvatarIndex(a), static_cast<size_t>(job.pair)));
      for (const json& o : record["others"]) {
        if (o["entity"] != job.entity) continue;
        ExpectLinksEqualToOffline(job, ml, o);
        ++per_link_compared;
        per_link_brackets += static_cast<int>(ml.links.size());
      }
    }
  }
  EXPECT_GT(per_link_brackets, 10) << per_link_compared << " per-link entries compared";
  EXPECT_EQ(got_covered, expected_covered);
  EXPECT_EQ(got_all, expected_all);
  EXPECT_GT(waited, 100) << "bob's delay makes entries wait";
}

TEST(SharedWorld, ClientsAtDifferentRatesAndAnObjectEqualTheOfflineWorld) {
  RunClientsAtDifferentRates(false);
}

// Trackers that stamp every body at the same frame times (one mocap system):
// a sample stamped at the pair's utime1 covers the window, so each entry is
// due in the frame of its pair, when the last of A's pose and E's sample of
// that frame arrives, not one frame later; every entry still equals the
// offline one. The exception is a window of one instant (bob's first sample
// at alice's utime1): it waits for bob's next sample.
TEST(SharedWorld, SamplesStampedAtTheSameFrameCoverInThatFrame) {
  constexpr int64_t kFrame = 11'111;
  const std::string ids[2] = {"alice", "bob"};
  Walker walkers[2] = {Walker(41, {0, 0, 0}), Walker(42, {0.1, 0.05, 0})};
  std::vector<Pose> used[2];
  std::vector<world::RigidSample> box_used;
  SharedWorld live(SharedWorldOptions{});
  live.AddAvatar("alice", Arm(), MotionModel::kArticulated, At(0));
  live.AddAvatar("bob", Arm(), MotionModel::kArticulated, At(0));
  live.AddObject("box", Cube(0.08), At(0));
  std::vector<SharedJob> due;
  std::vector<int> due_frame;  // The frame in which each job became due.
  int64_t pairs[2] = {0, 0};
  constexpr int kFrames = 40;
  for (int f = 0; f < kFrames; ++f) {
    const int64_t t = 1'000'000 + f * kFrame;
    // In each frame: alice, the box, then bob (bob from frame 1 on).
    for (int who : {0, 2, 1}) {
      if (who == 1 && f == 0) continue;
      if (who == 2) {
        const Eigen::Vector3d p(0.05 * std::sin(0.3 * f), 0.2, 0.02 * f - 0.3);
        const Eigen::Quaterniond q(Eigen::AngleAxisd(0.2 * f, Eigen::Vector3d::UnitX()));
        ASSERT_FALSE(live.OnObjectPose(ObjectPose("box", t, f + 1, p, q), 10'000'000, At(t), &due)
                         .has_value());
        box_used.push_back(SampleOf(t, p, q));
      } else {
        Feed(&live, ids[who], walkers[who].Next(t), &used[who], &pairs[who], &due);
      }
      due_frame.resize(due.size(), f);
    }
  }
  const size_t answered_live = due.size();
  live.CutAll(At(2'000'000), &due);

  Offline off;
  off.AddAvatar("alice", used[0]);
  off.AddAvatar("bob", used[1]);
  AddBox(&off, box_used);
  QueryOptions qo;
  off.answerer = std::make_unique<world::WorldAnswerer>(off.w, qo);
  const world::EntityQueryOptions eo = EntityOptionsOf(qo);

  int same_frame = 0, instant = 0, contacts = 0;
  for (size_t i = 0; i < answered_live; ++i) {
    const SharedJob& job = due[i];
    ASSERT_FALSE(job.ended_by_timeout);
    const int a = job.client_id == "alice" ? 0 : 1;
    // The frame of the pair's second pose: alice's pair k ends in frame
    // k + 1, bob's (from frame 1) in frame k + 2.
    const int pair_frame = static_cast<int>(job.pair) + 1 + a;
    if (job.t_from == job.t_to) {
      ++instant;
      EXPECT_EQ(due_frame[i], pair_frame + 1) << "an instant window waits for the next sample";
    } else {
      ++same_frame;
      EXPECT_EQ(due_frame[i], pair_frame)
          << job.client_id << " pair " << job.pair << " vs " << job.entity;
    }
    const shared_entry_t m = AnswerSharedJob(job, eo);
    contacts += m.result == shared_entry_t::RESULT_CONTACT;
    ExpectEqualToOffline(job, m, off.Others(a, static_cast<size_t>(job.pair)).at(job.entity));
  }
  // Alice's pairs against bob and the box, bob's against alice and the box;
  // only the last frame's pairs are left for the cut.
  EXPECT_EQ(instant, 1) << "alice's pair 0 against bob";
  EXPECT_GT(same_frame, 4 * (kFrames - 3));
  EXPECT_GT(contacts, 5);
  EXPECT_EQ(due.size() - answered_live, 0u) << "every frame's entries were due in their frame";
  std::printf("%d entries due in their own frame, %d instant, %d contacts\n", same_frame, instant,
              contacts);
}

// Filters (SPEC 8 "Filters") in the daemon: alice ignores bob with her
// forearm and the box with her upper arm; bob ignores alice's upper arm with
// his upper arm (a rule of either avatar applies to both answers). Every
// entry equals `sweptccd world` with the same rules, and differs from the
// unfiltered answer somewhere (so the test fails if a rule is not carried).
TEST(SharedWorld, FiltersOfEitherAvatarApplyToTheSharedAnswers) {
  constexpr int64_t kFrame = 11'111;
  const std::string ids[2] = {"alice", "bob"};
  Walker walkers[2] = {Walker(51, {0, 0, 0}), Walker(52, {0.1, 0.05, 0})};
  std::vector<Pose> used[2];
  std::vector<world::RigidSample> box_used;
  AvatarAnswerOptions alice_own, bob_own;
  alice_own.rules = {world::EntityRule{LinkIndex(1), "bob", kAllLinks},
                     world::EntityRule{LinkIndex(0), "box", kAllLinks}};
  bob_own.rules = {world::EntityRule{LinkIndex(0), "alice", LinkIndex(0)}};
  SharedWorld live(SharedWorldOptions{});
  live.AddAvatar("alice", Arm(), MotionModel::kArticulated, At(0), alice_own);
  live.AddAvatar("bob", Arm(), MotionModel::kArticulated, At(0), bob_own);
  live.AddObject("box", Cube(0.08), At(0));
  std::vector<SharedJob> due;
  int64_t pairs[2] = {0, 0};
  for (int f = 0; f < 40; ++f) {
    const int64_t t = 1'000'000 + f * kFrame;
    const Eigen::Vector3d p(0.05 * std::sin(0.3 * f), 0.2, 0.02 * f - 0.3);
    const Eigen::Quaterniond q(Eigen::AngleAxisd(0.2 * f, Eigen::Vector3d::UnitX()));
    ASSERT_FALSE(
        live.OnObjectPose(ObjectPose("box", t, f + 1, p, q), 10'000'000, At(t), &due).has_value());
    box_used.push_back(SampleOf(t, p, q));
    for (int who = 0; who < 2; ++who) {
      Feed(&live, ids[who], walkers[who].Next(t + 2'000 * who), &used[who], &pairs[who], &due);
    }
  }
  auto offline = [&](bool with_rules) {
    auto off = std::make_unique<Offline>();
    off->AddAvatar("alice", used[0]);
    off->AddAvatar("bob", used[1]);
    AddBox(off.get(), box_used);
    if (with_rules) off->w.world.rules = {alice_own.rules, bob_own.rules};
    off->answerer = std::make_unique<world::WorldAnswerer>(off->w, QueryOptions{});
    return off;
  };
  const auto filtered = offline(true), unfiltered = offline(false);
  QueryOptions qo;
  const world::EntityQueryOptions eo = EntityOptionsOf(qo);
  int compared = 0, changed = 0, contacts = 0;
  for (const SharedJob& job : due) {
    ASSERT_FALSE(job.ended_by_timeout);
    const int a = job.client_id == "alice" ? 0 : 1;
    const shared_entry_t m = AnswerSharedJob(job, eo);
    const size_t r = static_cast<size_t>(job.pair);
    ExpectEqualToOffline(job, m, filtered->Others(a, r).at(job.entity));
    ++compared;
    contacts += m.result == shared_entry_t::RESULT_CONTACT;
    json with = filtered->Others(a, r).at(job.entity),
         without = unfiltered->Others(a, r).at(job.entity);
    with.erase("stats"), without.erase("stats");  // Work counts, not the answer.
    changed += with != without;
  }
  std::printf("%d entries compared, %d contacts, %d changed by the filters\n", compared, contacts,
              changed);
  EXPECT_GT(compared, 100);
  EXPECT_GT(contacts, 5) << "some links still touch";
  EXPECT_GT(changed, 5) << "the filters must change some answers";
}

// A client's own tolerances (its join's eps_s and delta_m) answer the
// entries of its own pairs, as they answer its environment part: alice joins
// with eps 2 ms and delta 5 mm, bob with the service's. Every entry equals
// `sweptccd world` run with the tolerances of the record's avatar, and
// alice's coarser eps shows in her brackets (so the test fails if it is not
// carried).
TEST(SharedWorld, AClientsOwnTolerancesAnswerItsEntries) {
  constexpr double kEps = 2e-3, kDelta = 5e-3;
  const std::string ids[2] = {"alice", "bob"};
  Walker walkers[2] = {Walker(31, {0, 0, 0}), Walker(32, {0.12, 0.05, 0})};
  std::vector<Pose> used[2];
  SharedWorld live(SharedWorldOptions{});
  live.AddAvatar("alice", Arm(), MotionModel::kArticulated, At(0), {kEps, kDelta, {}});
  live.AddAvatar("bob", Arm(), MotionModel::kArticulated, At(0));
  std::vector<SharedJob> due;
  int64_t pairs[2] = {0, 0};
  for (int k = 0; k < 60; ++k) {
    for (int e = 0; e < 2; ++e) {
      const int64_t t = 1'000'000 + k * 11'111 + e * 3'000;
      Feed(&live, ids[e], walkers[e].Next(t), &used[e], &pairs[e], &due);
    }
  }
  live.CutAll(At(3'000'000), &due);

  // Offline: the same world, answered once with alice's tolerances and once
  // with the service's.
  Offline off;
  off.AddAvatar("alice", used[0]);
  off.AddAvatar("bob", used[1]);
  QueryOptions service_q, alice_q;
  alice_q.eps_s = kEps;
  alice_q.delta_m = kDelta;
  off.answerer = std::make_unique<world::WorldAnswerer>(off.w, service_q);
  const world::WorldAnswerer alice_answerer(off.w, alice_q);
  const world::EntityQueryOptions eo = EntityOptionsOf(service_q);

  int compared = 0, alice_contacts = 0, coarse = 0, bob_contacts = 0;
  for (const SharedJob& job : due) {
    if (job.ended_by_timeout) continue;
    const bool alice = job.client_id == "alice";
    ASSERT_TRUE(job.own_a);
    EXPECT_EQ(job.own_a->eps_s, alice ? kEps : 0.0);
    EXPECT_EQ(job.own_a->delta_m, alice ? kDelta : 0.0);
    const shared_entry_t m = AnswerSharedJob(job, eo);
    const json record = json::parse(
        (alice ? alice_answerer : *off.answerer)
            .RecordJson(world::AvatarIndex(alice ? 0 : 1), static_cast<size_t>(job.pair)));
    for (const json& o : record["others"]) {
      if (o["entity"] == job.entity) {
        ExpectEqualToOffline(job, m, o);
        ++compared;
      }
    }
    if (m.result != shared_entry_t::RESULT_CONTACT) continue;
    const double width_s = (m.t_hi - m.t_lo) * 1e-6;
    if (alice) {
      ++alice_contacts;
      EXPECT_LE(width_s, kEps);
      coarse += !m.initially_colliding && width_s > service_q.eps_s;
    } else {
      ++bob_contacts;
      EXPECT_LE(width_s, service_q.eps_s);
    }
  }
  std::printf("%d entries compared; contacts: alice %d (%d wider than the service's eps), bob %d\n",
              compared, alice_contacts, coarse, bob_contacts);
  EXPECT_GT(compared, 100);
  EXPECT_GT(bob_contacts, 5);
  EXPECT_GT(coarse, 0) << "alice's eps must show in some bracket";
}

// Regression: the slack of `sweptccd world` once scaled with the entity's
// whole stream, which a live service cannot know; 1000 km at the end made
// every earlier window's answer differ from the live one.
TEST(SharedWorld, AFarLaterSampleChangesNoEarlierAnswer) { RunClientsAtDifferentRates(true); }

struct Fixture {
  SharedWorldOptions so;
  std::unique_ptr<SharedWorld> live;
  Walker alice{5, {0, 0, 0}}, bob{6, {0.2, 0, 0}};
  std::vector<SharedJob> due;
  explicit Fixture(int max_history = 64, int max_pending = 64) {
    so.silence_timeout_us = 100'000;
    so.max_history = max_history;
    so.max_pending = max_pending;
    live = std::make_unique<SharedWorld>(so);
    live->AddAvatar("alice", Arm(), MotionModel::kArticulated, At(0));
    live->AddAvatar("bob", Arm(), MotionModel::kArticulated, At(0));
  }
  PosePair Pair(int64_t k, const Pose& p0, const Pose& p1, int64_t received_us) {
    PosePair p;
    p.pair = k, p.seq0 = k, p.seq1 = k + 1, p.pose0 = p0, p.pose1 = p1;
    p.receive_time = At(received_us);
    return p;
  }
};

TEST(SharedWorld, ASilentEntityEndsTheWindowAtItsLastSampleAfterTheTimeout) {
  Fixture f;
  const Pose b0 = f.bob.Next(1'000'000), b1 = f.bob.Next(1'010'000);
  f.live->OnAvatarSample("bob", 1, b0, At(1'000'000), &f.due);
  f.live->OnAvatarSample("bob", 1, b1, At(1'010'000), &f.due);
  const Pose a0 = f.alice.Next(1'005'000), a1 = f.alice.Next(1'020'000);
  f.live->OnAvatarSample("alice", 1, a0, At(1'005'000), &f.due);
  f.live->OnAvatarSample("alice", 1, a1, At(1'020'000), &f.due);
  f.live->AddPair("alice", f.Pair(0, a0, a1, 1'020'000), At(1'020'000), &f.due);
  EXPECT_TRUE(f.due.empty());
  EXPECT_EQ(f.live->pending(), 1u);
  // Bob's last sample was received at 1.010 s: silent from 1.110 s on.
  f.live->CutSilent(At(1'109'999), &f.due);
  EXPECT_TRUE(f.due.empty());
  f.live->CutSilent(At(1'110'000), &f.due);
  ASSERT_EQ(f.due.size(), 1u);
  const SharedJob& job = f.due[0];
  EXPECT_TRUE(job.ended_by_timeout);
  EXPECT_EQ(job.entity, "bob");
  EXPECT_EQ(job.t_from, 1'005'000);
  EXPECT_EQ(job.t_to, 1'010'000);  // Bob's last sample, not utime1.
  EXPECT_EQ(job.waited_us, 90'000);
  EXPECT_EQ(f.live->pending(), 0u);
  EXPECT_EQ(f.live->entries_cut(), 1);
}

TEST(SharedWorld, AnEntityThatStartsAfterThePairGetsNoEntry) {
  Fixture f;
  const Pose a0 = f.alice.Next(1'000'000), a1 = f.alice.Next(1'010'000);
  f.live->OnAvatarSample("alice", 1, a0, At(1'000), &f.due);
  f.live->OnAvatarSample("alice", 1, a1, At(2'000), &f.due);
  f.live->AddPair("alice", f.Pair(0, a0, a1, 2'000), At(2'000), &f.due);
  EXPECT_EQ(f.live->pending(), 1u) << "bob, not heard from yet, may still cover it";
  f.live->OnAvatarSample("bob", 1, f.bob.Next(1'020'000), At(3'000), &f.due);
  EXPECT_TRUE(f.due.empty()) << "no overlap: nothing to answer, as offline";
  EXPECT_EQ(f.live->pending(), 0u);
}

TEST(SharedWorld, TheWaitOfOneEntryIsBoundedByTheTimeoutToo) {
  Fixture f;
  // Bob keeps talking, but its clock lags: it never covers alice's pair.
  const Pose a0 = f.alice.Next(2'000'000), a1 = f.alice.Next(2'010'000);
  f.live->OnAvatarSample("alice", 1, a0, At(1'000'000), &f.due);
  f.live->OnAvatarSample("alice", 1, a1, At(1'010'000), &f.due);
  f.live->OnAvatarSample("bob", 1, f.bob.Next(1'000'000), At(1'000'000), &f.due);
  f.live->AddPair("alice", f.Pair(0, a0, a1, 1'010'000), At(1'010'000), &f.due);
  for (int64_t t = 1'020'000; t < 1'110'000; t += 10'000) {
    f.live->OnAvatarSample("bob", 1, f.bob.Next(t), At(t), &f.due);
    f.live->CutSilent(At(t), &f.due);
  }
  EXPECT_EQ(f.live->pending(), 1u);
  f.live->CutSilent(At(1'110'000), &f.due);
  EXPECT_EQ(f.live->pending(), 0u);
  EXPECT_TRUE(f.due.empty()) << "bob's samples end before alice's pair: no overlap";
}

TEST(SharedWorld, AFullPendingListCutsItsOldestEntry) {
  Fixture f(/*max_history=*/64, /*max_pending=*/3);
  f.live->OnAvatarSample("bob", 1, f.bob.Next(1'000'000), At(1'000'000), &f.due);
  f.live->OnAvatarSample("bob", 1, f.bob.Next(1'100'000), At(1'000'001), &f.due);
  Pose prev = f.alice.Next(1'000'000);
  f.live->OnAvatarSample("alice", 1, prev, At(1'000'000), &f.due);
  for (int k = 0; k < 5; ++k) {
    const Pose next = f.alice.Next(1'110'000 + 10'000 * k);
    f.live->OnAvatarSample("alice", 1, next, At(1'000'010 + k), &f.due);
    f.live->AddPair("alice", f.Pair(k, prev, next, 1'000'010 + k), At(1'000'010 + k), &f.due);
    prev = next;
  }
  // Pair 0 overlaps bob ([1.0, 1.11] against [1.0, 1.1]); pairs 1-4 do not.
  EXPECT_EQ(f.live->pending(), 3u);
  ASSERT_EQ(f.due.size(), 1u);
  EXPECT_EQ(f.due[0].pair, 0);
  EXPECT_TRUE(f.due[0].ended_by_timeout);
  EXPECT_EQ(f.due[0].t_to, 1'100'000);
}

// Entries wait per entity (a sample looks at its own entity's entries only);
// the cap still cuts the oldest entry of all, whichever entity it waits for.
TEST(SharedWorld, AFullPendingListCutsTheOldestEntryOfAnyEntity) {
  SharedWorldOptions so;
  so.silence_timeout_us = 100'000;
  so.max_pending = 2;
  SharedWorld live(so);
  for (const char* id : {"alice", "bob", "carol", "dave"}) {
    live.AddAvatar(id, Arm(), MotionModel::kArticulated, At(0));
  }
  Walker alice{5, {0, 0, 0}}, bob{6, {0.2, 0, 0}}, carol{7, {0.4, 0, 0}}, dave{8, {0.6, 0, 0}};
  std::vector<SharedJob> due;
  const auto pair = [](int64_t k, const Pose& p0, const Pose& p1) {
    PosePair p;
    p.pair = k, p.seq0 = k, p.seq1 = k + 1, p.pose0 = p0, p.pose1 = p1;
    p.receive_time = At(10);
    return p;
  };
  // Bob and carol lag: their samples end at 1.005 s.
  for (int64_t t : {1'000'000, 1'005'000}) {
    live.OnAvatarSample("bob", 1, bob.Next(t), At(1), &due);
    live.OnAvatarSample("carol", 1, carol.Next(t), At(1), &due);
  }
  const Pose d0 = dave.Next(1'000'000), d1 = dave.Next(1'010'000);
  live.OnAvatarSample("dave", 1, d0, At(2), &due);
  live.OnAvatarSample("dave", 1, d1, At(2), &due);
  const Pose a0 = alice.Next(1'000'000), a1 = alice.Next(1'010'000);
  live.OnAvatarSample("alice", 1, a0, At(2), &due);
  live.OnAvatarSample("alice", 1, a1, At(2), &due);
  // Alice's pair: dave covers it (due at once); it waits for bob, then carol.
  live.AddPair("alice", pair(0, a0, a1), At(3), &due);
  ASSERT_EQ(due.size(), 1u);
  EXPECT_EQ(due[0].entity, "dave");
  EXPECT_EQ(live.pending(), 2u);
  due.clear();
  // Dave's pair: alice covers it (due), bob and carol wait: 4 entries, so
  // the two oldest, alice's, are cut; dave's stay.
  live.AddPair("dave", pair(0, d0, d1), At(5), &due);
  EXPECT_EQ(live.pending(), 2u);
  EXPECT_EQ(live.entries_overflowed(), 2);
  ASSERT_EQ(due.size(), 3u);
  EXPECT_EQ(due[0].client_id, "dave");
  EXPECT_EQ(due[0].entity, "alice");
  EXPECT_FALSE(due[0].ended_by_timeout);
  for (size_t k : {1, 2}) {
    EXPECT_EQ(due[k].client_id, "alice");
    EXPECT_TRUE(due[k].ended_by_timeout);
    EXPECT_EQ(due[k].t_to, 1'005'000);
  }
  EXPECT_EQ(due[1].entity, "bob");
  EXPECT_EQ(due[2].entity, "carol");
  // What is left is dave's, and it settles when bob and carol catch up.
  due.clear();
  live.OnAvatarSample("bob", 1, bob.Next(1'020'000), At(6), &due);
  live.OnAvatarSample("carol", 1, carol.Next(1'020'000), At(6), &due);
  ASSERT_EQ(due.size(), 2u);
  EXPECT_EQ(due[0].client_id, "dave");
  EXPECT_EQ(due[0].entity, "bob");
  EXPECT_EQ(due[1].client_id, "dave");
  EXPECT_EQ(due[1].entity, "carol");
  EXPECT_FALSE(due[0].ended_by_timeout || due[1].ended_by_timeout);
  EXPECT_EQ(live.pending(), 0u);
}

TEST(SharedWorld, AWindowBeforeTheKeptHistoryIsMarkedCut) {
  Fixture f(/*max_history=*/4);
  for (int k = 0; k < 10; ++k) {
    f.live->OnAvatarSample("bob", 1, f.bob.Next(1'000'000 + 10'000 * k), At(k), &f.due);
  }
  EXPECT_EQ(f.live->history_size("bob"), 4);
  const Pose a0 = f.alice.Next(1'005'000), a1 = f.alice.Next(1'075'000);
  f.live->OnAvatarSample("alice", 1, a0, At(20), &f.due);
  f.live->OnAvatarSample("alice", 1, a1, At(21), &f.due);
  f.live->AddPair("alice", f.Pair(0, a0, a1, 21), At(21), &f.due);
  ASSERT_EQ(f.due.size(), 1u);
  EXPECT_TRUE(f.due[0].ended_by_timeout) << "bob's samples before 1.06 s are gone";
  EXPECT_EQ(f.due[0].t_from, 1'060'000);
}

TEST(SharedWorld, ANewSessionCutsWhatWaitedForTheOldStream) {
  Fixture f;
  f.live->OnAvatarSample("bob", 1, f.bob.Next(1'000'000), At(0), &f.due);
  f.live->OnAvatarSample("bob", 1, f.bob.Next(1'010'000), At(1), &f.due);
  const Pose a0 = f.alice.Next(1'000'000), a1 = f.alice.Next(1'020'000);
  f.live->OnAvatarSample("alice", 1, a0, At(2), &f.due);
  f.live->OnAvatarSample("alice", 1, a1, At(3), &f.due);
  f.live->AddPair("alice", f.Pair(0, a0, a1, 3), At(3), &f.due);
  EXPECT_TRUE(f.due.empty());
  f.live->OnAvatarSample("bob", 2, f.bob.Next(5), At(4), &f.due);  // Restarted tracker.
  ASSERT_EQ(f.due.size(), 1u);
  EXPECT_TRUE(f.due[0].ended_by_timeout);
  EXPECT_EQ(f.due[0].t_to, 1'010'000);
  EXPECT_EQ(f.live->history_size("bob"), 1);
}

TEST(SharedWorld, BadObjectPosesAreRefusedAndDisturbNothing) {
  SharedWorldOptions so;
  SharedWorld live(so);
  live.AddAvatar("alice", Arm(), MotionModel::kArticulated, At(0));
  live.AddObject("box", Cube(0.1), At(0));
  std::vector<SharedJob> due;
  const Eigen::Quaterniond q(1, 0, 0, 0);
  ASSERT_FALSE(live.OnObjectPose(ObjectPose("box", 100, 1, {0, 0, 0}, q), 10'000'000, At(0), &due));
  auto reason = [&](const object_pose_t& m) {
    const auto r = live.OnObjectPose(m, 10'000'000, At(1), &due);
    return r ? r->reason : std::string("used");
  };
  EXPECT_EQ(reason(ObjectPose("cup", 200, 2, {0, 0, 0}, q)), "unknown_object");
  EXPECT_EQ(reason(ObjectPose("alice", 200, 2, {0, 0, 0}, q)), "unknown_object")
      << "an avatar's id is no object";
  EXPECT_EQ(reason(ObjectPose("box", 200, 2, {NAN, 0, 0}, q)), "non_finite");
  EXPECT_EQ(reason(ObjectPose("box", 200, 2, {2e9, 0, 0}, q)), "position_out_of_range");
  EXPECT_EQ(reason(ObjectPose("box", 200, 2, {0, 0, 0}, Eigen::Quaterniond(0, 0, 0, 0))),
            "zero_quaternion");
  EXPECT_EQ(reason(ObjectPose("box", 200, 1, {0, 0, 0}, q)), "non_increasing_seq");
  EXPECT_EQ(reason(ObjectPose("box", 100, 2, {0, 0, 0}, q)), "non_increasing_utime");
  EXPECT_EQ(reason(ObjectPose("box", 100 + 10'000'001, 2, {0, 0, 0}, q)), "utime_jump");
  object_pose_t stale = ObjectPose("box", 200, 2, {0, 0, 0}, q);
  stale.session = 0;
  EXPECT_EQ(reason(stale), "stale_session");
  EXPECT_EQ(live.history_size("box"), 1);
  EXPECT_EQ(live.pending(), 0u);
  EXPECT_TRUE(due.empty());
  EXPECT_EQ(reason(ObjectPose("box", 200, 2, {0, 0, 0}, q)), "used");
  EXPECT_EQ(live.history_size("box"), 2);
}

// An object pose is judged by the rule of an avatar's link pose and worded
// as the avatar's (FindRigidProblem, PoseRejection): the same code and the
// same detail (the component, the value, the fix) for the same numbers.
// (Before, a second routine returned a string that the service turned back
// into a code by substring, and its wording named neither.)
TEST(SharedWorld, AnObjectPoseIsJudgedAndWordedAsAnAvatarLinkPose) {
  SharedWorld live(SharedWorldOptions{});
  live.AddObject("box", Cube(0.1), At(0));
  std::vector<SharedJob> due;
  const std::vector<std::pair<Eigen::Vector3d, Eigen::Vector4d>> bad = {
      {{0, NAN, 0}, {1, 0, 0, 0}},       // Non-finite position.
      {{0, 0, 0}, {1, 0, INFINITY, 0}},  // Non-finite orientation.
      {{0, 0, -2e9}, {1, 0, 0, 0}},      // Beyond 1e9 m.
      {{0, 0, 0}, {1e-7, 0, 0, 0}},      // Quaternion norm below 1e-6.
      {{0, 0, 0}, {0, 0, 0, 0}}};        // Zero quaternion.
  for (const auto& [p, q] : bad) {
    object_pose_t m = ObjectPose("box", 100, 7, p, Eigen::Quaterniond(q[0], q[1], q[2], q[3]));
    const std::optional<Rejection> object = live.OnObjectPose(m, 10'000'000, At(1), &due);
    tracker_pose_t t{};
    t.num_links = 1;
    t.position.assign(1, {p[0], p[1], p[2]});
    t.orientation.assign(1, {q[0], q[1], q[2], q[3]});
    Pose pose;
    const std::optional<Rejection> avatar = ValidateTrackerPose(t, 1, &pose);
    ASSERT_TRUE(object.has_value());
    ASSERT_TRUE(avatar.has_value());
    EXPECT_EQ(object->reason, avatar->reason);
    const std::string place = "link 0: ";
    ASSERT_EQ(avatar->message.rfind(place, 0), 0u) << avatar->message;
    EXPECT_EQ(object->message, "object 'box' seq 7: " + avatar->message.substr(place.size()));
  }
  EXPECT_EQ(live.history_size("box"), 0);
  EXPECT_TRUE(due.empty());
}

// The utime_jump rule of objects is the avatar's (UtimeJump): a hostile
// pair of utimes whose signed difference overflows int64 is a jump, not a
// small (wrapped, negative) step. (Before, `msg.utime - last` overflowed
// and the jump was used.)
TEST(SharedWorld, AnObjectUtimeJumpThatOverflowsInt64IsRefused) {
  SharedWorld live(SharedWorldOptions{});
  live.AddObject("box", Cube(0.1), At(0));
  std::vector<SharedJob> due;
  const Eigen::Quaterniond q(1, 0, 0, 0);
  const int64_t lowest = std::numeric_limits<int64_t>::min() + 1;
  const int64_t highest = std::numeric_limits<int64_t>::max();
  ASSERT_FALSE(
      live.OnObjectPose(ObjectPose("box", lowest, 1, {0, 0, 0}, q), 10'000'000, At(0), &due));
  const std::optional<Rejection> r =
      live.OnObjectPose(ObjectPose("box", highest, 2, {0, 0, 0}, q), 10'000'000, At(1), &due);
  ASSERT_TRUE(r.has_value()) << "a jump of ~1.8e19 us was used";
  EXPECT_EQ(r->reason, "utime_jump");
  EXPECT_EQ(live.history_size("box"), 1);
  // The same pair on the avatar path (one code): a jump too.
  EXPECT_EQ(UtimeJump(lowest, highest), std::numeric_limits<uint64_t>::max() - 1);
  EXPECT_EQ(UtimeJump(-5, 5), 10u);
}

// The entry of a cleared job against the full answer of the same job: all
// but compute_us.
void ExpectSameEntry(const shared_entry_t& cleared, const shared_entry_t& full) {
  EXPECT_EQ(cleared.entity, full.entity);
  EXPECT_EQ(cleared.entity_kind, full.entity_kind);
  EXPECT_EQ(cleared.t_from, full.t_from);
  EXPECT_EQ(cleared.t_to, full.t_to);
  EXPECT_EQ(+cleared.result, +full.result) << full.error;
  EXPECT_EQ(cleared.initially_colliding, full.initially_colliding);
  EXPECT_EQ(cleared.undecided, full.undecided);
  EXPECT_EQ(cleared.s_lo, full.s_lo);
  EXPECT_EQ(cleared.s_hi, full.s_hi);
  EXPECT_EQ(cleared.t_lo, full.t_lo);
  EXPECT_EQ(cleared.t_hi, full.t_hi);
  EXPECT_EQ(cleared.num_contacts, full.num_contacts);
  EXPECT_EQ(cleared.contacts.size(), full.contacts.size());
  EXPECT_EQ(cleared.num_links, full.num_links);
  EXPECT_EQ(cleared.links.size(), full.links.size());
  EXPECT_EQ(cleared.waited_us, full.waited_us);
  EXPECT_EQ(cleared.ended_by_timeout, full.ended_by_timeout);
  EXPECT_EQ(cleared.error, full.error);
}

TEST(SharedWorld, AFarEntityIsClearedByTheBoxesAndAnsweredFree) {
  SharedWorldOptions on, off;
  off.broad_phase = false;
  std::vector<SharedJob> due[2];
  Walker alice(5, {0, 0, 0}), bob(6, {5, 0, 0});
  const Pose b0 = bob.Next(1'000'000), b1 = bob.Next(1'012'000), b2 = bob.Next(1'024'000);
  const Pose a0 = alice.Next(1'005'000), a1 = alice.Next(1'016'000);
  int i = 0;
  for (const SharedWorldOptions& so : {on, off}) {
    SharedWorld live(so);
    live.AddAvatar("alice", Arm(), MotionModel::kArticulated, At(0));
    live.AddAvatar("bob", Arm(), MotionModel::kArticulated, At(0));
    for (const Pose& b : {b0, b1, b2}) live.OnAvatarSample("bob", 1, b, At(b.utime), &due[i]);
    live.OnAvatarSample("alice", 1, a0, At(a0.utime), &due[i]);
    live.OnAvatarSample("alice", 1, a1, At(a1.utime), &due[i]);
    PosePair p;
    p.pair = 0, p.seq0 = 0, p.seq1 = 1, p.pose0 = a0, p.pose1 = a1;
    p.receive_time = At(a1.utime);
    live.AddPair("alice", p, At(a1.utime + 100), &due[i]);
    EXPECT_EQ(live.entries_cleared(), i == 0 ? 1 : 0);
    ++i;
  }
  ASSERT_EQ(due[0].size(), 1u);
  ASSERT_EQ(due[1].size(), 1u);
  const SharedJob& cleared = due[0][0];
  const SharedJob& full = due[1][0];
  EXPECT_TRUE(cleared.cleared_by_box);
  EXPECT_FALSE(full.cleared_by_box);
  EXPECT_TRUE(cleared.avatar_samples.empty()) << "a cleared job copies no samples";
  EXPECT_TRUE(cleared.pose0.links.empty());
  EXPECT_EQ(full.avatar_samples.size(), 3u) << "the window spans two of bob's intervals";
  EXPECT_EQ(cleared.pose0.utime, a0.utime);
  EXPECT_EQ(cleared.pose1.utime, a1.utime);
  EXPECT_EQ(SharedMessageOf(cleared).utime0, SharedMessageOf(full).utime0);
  EXPECT_EQ(SharedMessageOf(cleared).utime1, SharedMessageOf(full).utime1);
  for (bool per_link : {false, true}) {
    world::EntityQueryOptions eo;
    eo.per_link = per_link;
    const shared_entry_t c = AnswerSharedJob(cleared, eo), f = AnswerSharedJob(full, eo);
    EXPECT_EQ(+c.result, +shared_entry_t::RESULT_FREE);
    EXPECT_GE(c.compute_us, 0.0);
    ExpectSameEntry(c, f);
  }
}

// A window that ends at one of E's samples does not use E's interval
// after it (SplitWindow skips that boundary instant): bob far until that
// sample and moving onto alice only after it leaves the entry cleared.
TEST(SharedWorld, TheIntervalAfterTheWindowDoesNotKeepAnEntry) {
  SharedWorld live{SharedWorldOptions{}};
  live.AddAvatar("alice", Arm(), MotionModel::kArticulated, At(0));
  live.AddAvatar("bob", Arm(), MotionModel::kArticulated, At(0));
  Walker alice(5, {0, 0, 0}), bob(6, {5, 0, 0});
  std::vector<SharedJob> due;
  const Pose a0 = alice.Next(1'002'000), a1 = alice.Next(1'010'000);
  Pose b2 = bob.Next(1'020'000);
  for (LinkPose& l : b2.links) l.p.x() -= 5;  // Onto alice.
  for (const Pose& b : {bob.Next(1'000'000), bob.Next(1'010'000), b2}) {
    live.OnAvatarSample("bob", 1, b, At(b.utime), &due);
  }
  live.OnAvatarSample("alice", 1, a0, At(a0.utime), &due);
  live.OnAvatarSample("alice", 1, a1, At(a1.utime), &due);
  PosePair p;
  p.pair = 0, p.seq0 = 0, p.seq1 = 1, p.pose0 = a0, p.pose1 = a1;
  p.receive_time = At(a1.utime);
  live.AddPair("alice", p, At(a1.utime), &due);
  ASSERT_EQ(due.size(), 1u);
  EXPECT_EQ(due[0].t_to, 1'010'000);
  EXPECT_TRUE(due[0].cleared_by_box);
  // And a window one microsecond longer uses that interval: kept.
  const Pose a2 = alice.Next(1'010'001);
  live.OnAvatarSample("alice", 1, a2, At(a2.utime), &due);
  p.pair = 1, p.seq0 = 1, p.seq1 = 2, p.pose0 = a1, p.pose1 = a2;
  live.AddPair("alice", p, At(a2.utime), &due);
  ASSERT_EQ(due.size(), 2u);
  EXPECT_FALSE(due[1].cleared_by_box);
}

// WorldAnswerer::AnswerEntity's broad phase, computed anew from the world:
// whether A's box over record r overlaps E's box of an interval of a piece.
bool NearOffline(const world::World& w, int a, size_t r, const std::string& entity) {
  const world::AvatarEntity& A = w.avatars[a];
  const PairOutcome& rec = A.records[r];
  const Aabb box_a =
      world::AvatarMotionBox(A.skeleton, PairMotion(A.skeleton, rec.pose0, rec.pose1, A.motion));
  std::vector<int64_t> times;
  std::function<Aabb(size_t, size_t)> box_e;
  for (const world::AvatarEntity& e : w.avatars) {
    if (e.id != entity) continue;
    for (const Pose& p : e.used) times.push_back(p.utime);
    box_e = [&e](size_t k0, size_t k1) {
      return world::AvatarMotionBox(e.skeleton,
                                    PairMotion(e.skeleton, e.used[k0], e.used[k1], e.motion));
    };
  }
  for (const world::ObjectEntity& e : w.objects) {
    if (e.id != entity) continue;
    for (const world::RigidSample& x : e.used) times.push_back(x.utime);
    const TriangleBvh& bvh = e.mesh->object(0).bvh;
    box_e = [&e, &bvh](size_t k0, size_t k1) {
      return world::ObjectMotionBox(e.used[k0], e.used[k1], world::ObjectRadius(bvh),
                                    bvh.max_abs_coordinate());
    };
  }
  const int64_t u0 = rec.pose0.utime, u1 = rec.pose1.utime;
  const int64_t t_from = std::max(u0, times.front()), t_to = std::min(u1, times.back());
  for (const world::Piece& p : world::SplitWindow(u0, t_from, t_to, times)) {
    const size_t k = static_cast<size_t>(p.k);
    if (box_a.Overlaps(box_e(k, std::min(k + 1, times.size() - 1)))) return true;
  }
  return false;
}

// Random scenes: alice (A) and bob at random rates, a one-sample avatar and
// a box, each near alice or far, drifting so that some windows are near in
// one of E's intervals only. Fed alike to a world with the broad phase and
// one without: a cleared job's full answer is `free` (so the cleared entry
// equals it), and a job is cleared exactly when `sweptccd world` culls the
// same entry by its boxes.
void RunBroadPhase(uint64_t seed, int* cleared_jobs, int* kept_jobs, int* split_cleared) {
  SCOPED_TRACE("seed " + std::to_string(seed));
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> u(0, 1);
  const std::vector<std::string> ids = {"alice", "bob", "solo", "box"};
  const int64_t start = 1'000'000, end = 1'400'000;
  auto random_center = [&]() -> Eigen::Vector3d {
    const Eigen::Vector3d dir =
        Eigen::Vector3d(u(rng) - 0.5, u(rng) - 0.5, u(rng) - 0.5).normalized();
    return dir * (u(rng) < 0.4 ? 0.3 * u(rng) : 0.4 + 1.2 * u(rng));
  };
  auto random_drift = [&]() -> Eigen::Vector3d {  // Metres per second.
    if (u(rng) < 0.5) return Eigen::Vector3d::Zero();
    return Eigen::Vector3d(u(rng) - 0.5, u(rng) - 0.5, u(rng) - 0.5) * 6.0;
  };
  Eigen::Vector3d center[4], drift[4];
  center[0] = Eigen::Vector3d::Zero();
  drift[0] = Eigen::Vector3d::Zero();
  for (int e = 1; e < 4; ++e) center[e] = random_center(), drift[e] = random_drift();
  const int64_t period[4] = {5'000 + static_cast<int64_t>(45'000 * u(rng)),
                             4'000 + static_cast<int64_t>(40'000 * u(rng)), 0,
                             8'000 + static_cast<int64_t>(60'000 * u(rng))};
  Walker walkers[3] = {Walker(seed * 7 + 1, center[0]), Walker(seed * 7 + 2, center[1]),
                       Walker(seed * 7 + 3, center[2])};
  auto pose_of = [&](int e, int64_t t) {
    Pose p = walkers[e].Next(t);
    for (LinkPose& l : p.links) l.p += drift[e] * (static_cast<double>(t - start) * 1e-6);
    return p;
  };
  std::vector<Arrival> arrivals;
  std::vector<Pose> used[3];
  std::vector<world::RigidSample> box_used;
  for (int e = 0; e < 4; ++e) {
    int64_t seq = 0;
    const int64_t delay = static_cast<int64_t>(30'000 * u(rng));
    std::vector<int64_t> times;
    if (e == 2) {
      times.push_back(start + static_cast<int64_t>((end - start) * u(rng)));
    } else {
      for (int64_t t = start + static_cast<int64_t>(period[e] * u(rng)); t <= end; t += period[e]) {
        times.push_back(t);
      }
    }
    for (const int64_t t : times) {
      Arrival a{t + delay, e, {}, {}};
      if (e < 3) {
        a.pose = pose_of(e, t);
        used[e].push_back(a.pose);
      } else {
        const Eigen::Vector3d p = center[3] + drift[3] * (static_cast<double>(t - start) * 1e-6) +
                                  0.02 * Eigen::Vector3d(u(rng), u(rng), u(rng));
        const Eigen::Quaterniond q(Eigen::AngleAxisd(6.0 * u(rng), Eigen::Vector3d::UnitY()));
        a.object = ObjectPose("box", t, ++seq, p, q);
        box_used.push_back(SampleOf(t, p, q));
      }
      arrivals.push_back(a);
    }
  }
  SortByArrival(&arrivals);

  Offline off;
  for (int e = 0; e < 3; ++e) off.AddAvatar(ids[e], used[e]);
  world::ObjectEntity box;
  box.id = "box";
  box.mesh = Cube(0.1);
  box.used = box_used;
  off.w.world.objects.push_back(box);
  QueryOptions qo;
  qo.per_link = true;
  off.answerer = std::make_unique<world::WorldAnswerer>(off.w, qo);
  world::EntityQueryOptions eo = EntityOptionsOf(qo);
  eo.per_link = true;

  SharedWorldOptions so[2];
  so[0].silence_timeout_us = so[1].silence_timeout_us = 100'000;
  so[1].broad_phase = false;
  std::vector<SharedJob> due[2];
  for (int w = 0; w < 2; ++w) {
    SharedWorld live(so[w]);
    for (int e = 0; e < 3; ++e) live.AddAvatar(ids[e], Arm(), MotionModel::kArticulated, At(0));
    live.AddObject("box", Cube(0.1), At(0));
    int64_t pairs[2] = {0, 0};
    std::optional<Pose> last[2];
    for (const Arrival& a : arrivals) {
      if (a.entity == 3) {
        ASSERT_FALSE(live.OnObjectPose(a.object, 10'000'000, At(a.at_us), &due[w]).has_value());
        continue;
      }
      live.OnAvatarSample(ids[a.entity], 1, a.pose, At(a.at_us), &due[w]);
      if (a.entity == 2) continue;  // solo makes no pairs.
      if (last[a.entity]) {
        PosePair p;
        p.pair = pairs[a.entity]++;
        p.seq0 = p.pair, p.seq1 = p.pair + 1;
        p.pose0 = *last[a.entity];
        p.pose1 = a.pose;
        p.receive_time = At(a.at_us);
        live.AddPair(ids[a.entity], p, At(a.at_us), &due[w]);
      }
      last[a.entity] = a.pose;
    }
    live.CutAll(At(end + 1'000'000), &due[w]);
  }
  ASSERT_EQ(due[0].size(), due[1].size());
  std::map<std::pair<int, int64_t>, std::map<std::string, json>> others;
  for (size_t i = 0; i < due[0].size(); ++i) {
    const SharedJob& job = due[0][i];
    const SharedJob& full = due[1][i];
    ASSERT_EQ(job.client_id, full.client_id);
    ASSERT_EQ(job.pair, full.pair);
    ASSERT_EQ(job.entity, full.entity);
    ASSERT_FALSE(full.cleared_by_box);
    const int a = job.client_id == "alice" ? 0 : 1;
    auto& rec = others[{a, job.pair}];
    if (rec.empty()) rec = off.Others(a, static_cast<size_t>(job.pair));
    const json& o = rec.at(job.entity);
    SCOPED_TRACE(job.client_id + " pair " + std::to_string(job.pair) + " vs " + job.entity);
    // WorldAnswerer::AnswerEntity's rule over the whole offline streams (its
    // stats say culled_by_box also when AnswerOther's own box test culls).
    EXPECT_EQ(job.cleared_by_box,
              !NearOffline(off.w.world, a, static_cast<size_t>(job.pair), job.entity))
        << "cut " << job.ended_by_timeout << " window " << job.t_from << ".." << job.t_to;
    if (job.cleared_by_box) {
      EXPECT_TRUE(o["stats"]["culled_by_box"].get<bool>());
    }
    const shared_entry_t m = AnswerSharedJob(job, eo);
    ExpectEqualToOffline(job, m, o);
    ExpectLinksEqualToOffline(job, m, o);
    if (!job.cleared_by_box) {
      ++*kept_jobs;
      continue;
    }
    ++*cleared_jobs;
    *split_cleared += (full.avatar_samples.size() + full.object_samples.size()) > 2;
    world::EntityQueryOptions plain = eo;
    plain.per_link = false;
    const shared_entry_t f = AnswerSharedJob(full, plain);
    EXPECT_EQ(+f.result, +shared_entry_t::RESULT_FREE) << "the boxes cleared a contact";
    ExpectSameEntry(AnswerSharedJob(job, plain), f);
    const shared_entry_t fl = AnswerSharedJob(full, eo);
    EXPECT_EQ(+fl.result, +shared_entry_t::RESULT_FREE);
    for (const entity_link_bracket_t& b : fl.links) {
      EXPECT_FALSE(b.has_witness) << "link " << b.link;
      EXPECT_FALSE(b.initially_colliding) << "link " << b.link;
    }
  }
}

TEST(SharedWorld, TheBroadPhaseClearsExactlyWhatTheWorldCommandCulls) {
  int cleared = 0, kept = 0, split = 0;
  for (uint64_t seed = 1; seed <= 24; ++seed) {
    RunBroadPhase(seed, &cleared, &kept, &split);
    if (HasFatalFailure()) return;
  }
  std::printf("%d entries cleared by the boxes (%d over several intervals), %d kept\n", cleared,
              split, kept);
  EXPECT_GT(cleared, 200);
  EXPECT_GT(kept, 200);
  EXPECT_GT(split, 20);
}

}  // namespace
}  // namespace sweptccd
