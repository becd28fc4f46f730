#pragma once
// Shared fixtures of the service tests: a two-link skeleton, a floor (in
// memory and as files for the daemon), tracker messages that lower the avatar
// onto the floor, a capturing Publisher with an optional gate that holds
// workers inside PublishContact, and an LCM listener for memq:// tests.

#include <gtest/gtest.h>

#include <lcm/lcm-cpp.hpp>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <condition_variable>
#include <filesystem>
#include <fstream>
#include <map>
#include <memory>
#include <mutex>
#include <string>
#include <vector>

#include "core/query/ccd_query.h"
#include "core/scene/environment.h"
#include "core/avatar/skeleton.h"
#include "msgs/channels.h"
#include "service/client_session.h"
#include "service/collision_service.h"
#include "service/publisher.h"
#include "sweptccd/contact_event_t.hpp"
#include "sweptccd/rejection_t.hpp"
#include "sweptccd/status_t.hpp"

namespace sweptccd {
namespace test {

// pelvis: vertical capsule 0.3 m long, radius 0.1; arm: along x, radius 0.05.
inline std::shared_ptr<const Skeleton> TwoLinkSkeleton() {
  std::vector<Link> links(2);
  links[0].name = "pelvis";
  links[0].parent = -1;
  links[0].a_L = {0, 0, 0};
  links[0].b_L = {0, 0, 0.3};
  links[0].radius = 0.1;
  links[1].name = "arm";
  links[1].parent = 0;
  links[1].a_L = {0, 0, 0};
  links[1].b_L = {0.3, 0, 0};
  links[1].radius = 0.05;
  return std::make_shared<Skeleton>(Skeleton::FromLinks("two", links, "test"));
}

// A 20 m x 20 m floor at z = 0 (object 0).
inline std::shared_ptr<const Environment> FloorEnvironment() {
  TriangleMesh mesh;
  mesh.vertices = {{-10, -10, 0}, {10, -10, 0}, {10, 10, 0}, {-10, 10, 0}};
  mesh.indices = {0, 1, 2, 0, 2, 3};
  auto env = std::make_shared<Environment>();
  env->AddMesh(mesh, "floor");
  return env;
}

// Pelvis origin at height z (metres), arm rotated by `angle` about z at the
// top of the pelvis. Contact with the floor when z <= 0.1.
inline tracker_pose_t MakePose(const std::string& client, int64_t seq, int64_t utime, double z,
                               double angle = 0) {
  tracker_pose_t m;
  m.utime = utime;
  m.client_id = client;
  m.session = 1;
  m.seq = seq;
  m.num_links = 2;
  m.position = {{0.1 * seq, 0, z}, {0.1 * seq, 0, z + 0.3}};
  m.orientation = {{1, 0, 0, 0}, {std::cos(angle / 2), 0, 0, std::sin(angle / 2)}};
  std::fill(std::begin(m.mac), std::end(m.mac), uint8_t{0});
  return m;
}

// Height of pose k of a descending stream: from 1 m, 0.07 m lower per pose.
inline double Height(int64_t k) { return 1.0 - 0.07 * static_cast<double>(k); }

// Pose k of client `client`'s descending, turning stream at 120 Hz.
inline tracker_pose_t Sample(const std::string& client, int64_t k) {
  return MakePose(client, k, 2'000'000 + k * 8'333, Height(k), 0.1 * static_cast<double>(k));
}

// A fresh folder for one test's files, under the build tree.
inline std::string TestDir(const std::string& name) {
  const std::filesystem::path dir =
      std::filesystem::path(SWEPTCCD_BINARY_DIR) / "test_files" / name;
  std::filesystem::remove_all(dir);
  std::filesystem::create_directories(dir);
  return dir.string();
}

inline std::string WriteFile(const std::string& path, const std::string& text) {
  std::ofstream out(path, std::ios::binary | std::ios::trunc);
  out << text;
  EXPECT_TRUE(out.good()) << path;
  return path;
}

// TwoLinkSkeleton() as a SPEC skeleton file.
inline std::string WriteTwoLinkSkeleton(const std::string& dir) {
  return WriteFile(dir + "/two.json", R"({"name": "two", "links": [
    {"name": "pelvis", "parent": null, "a": [0, 0, 0], "b": [0, 0, 0.3], "radius": 0.1},
    {"name": "arm", "parent": "pelvis", "a": [0, 0, 0], "b": [0.3, 0, 0], "radius": 0.05}]})");
}

// FloorEnvironment() as an OBJ file.
inline std::string WriteFloorObj(const std::string& dir) {
  return WriteFile(dir + "/floor.obj",
                   "v -10 -10 0\nv 10 -10 0\nv 10 10 0\nv -10 10 0\nf 1 2 3\nf 1 3 4\n");
}

// Collects what the service publishes over LCM (callbacks on the thread that
// handles the LCM instance; reads from any thread).
class Listener {
 public:
  void OnContact(const lcm::ReceiveBuffer*, const std::string&, const contact_event_t* m) {
    std::lock_guard<std::mutex> lock(mutex_);
    contacts_.push_back(*m);
    cv_.notify_all();
  }
  void OnReject(const lcm::ReceiveBuffer*, const std::string&, const rejection_t* m) {
    std::lock_guard<std::mutex> lock(mutex_);
    rejections_.push_back(*m);
    cv_.notify_all();
  }
  void OnStatus(const lcm::ReceiveBuffer*, const std::string&, const status_t* m) {
    std::lock_guard<std::mutex> lock(mutex_);
    statuses_.push_back(*m);
    cv_.notify_all();
  }
  // Subscribes to the service's default output channels.
  void SubscribeTo(lcm::LCM* lcm) {
    lcm->subscribe(kContactChannel, &Listener::OnContact, this);
    lcm->subscribe(kRejectChannel, &Listener::OnReject, this);
    lcm->subscribe(kStatusChannel, &Listener::OnStatus, this);
  }
  // Waits (on state, not time) until `n` statuses arrived; false if they do
  // not within `limit` (a guard against hanging, never the expected path).
  bool WaitForStatuses(size_t n, std::chrono::seconds limit = std::chrono::seconds(60)) {
    std::unique_lock<std::mutex> lock(mutex_);
    return cv_.wait_for(lock, limit, [&] { return statuses_.size() >= n; });
  }
  std::vector<contact_event_t> contacts() const {
    std::lock_guard<std::mutex> lock(mutex_);
    return contacts_;
  }
  std::vector<rejection_t> rejections() const {
    std::lock_guard<std::mutex> lock(mutex_);
    return rejections_;
  }
  std::vector<status_t> statuses() const {
    std::lock_guard<std::mutex> lock(mutex_);
    return statuses_;
  }

 private:
  mutable std::mutex mutex_;
  std::condition_variable cv_;
  std::vector<contact_event_t> contacts_;
  std::vector<rejection_t> rejections_;
  std::vector<status_t> statuses_;
};

inline Pose ToPose(const tracker_pose_t& m, int num_links) {
  Pose p;
  auto rejection = ValidateTrackerPose(m, num_links, &p);
  EXPECT_FALSE(rejection.has_value()) << rejection->message;
  return p;
}

class CapturingPublisher : public Publisher {
 public:
  void PublishContact(const contact_event_t& event) override {
    std::unique_lock<std::mutex> lock(mutex_);
    ++entered_;
    cv_.notify_all();
    cv_.wait(lock, [this] { return !gated_; });
    contacts_.push_back(event);
    if (throw_on_contact_) throw std::runtime_error("capturing publisher told to throw");
  }
  void PublishRejection(const rejection_t& r) override {
    std::lock_guard<std::mutex> lock(mutex_);
    rejections_.push_back(r);
  }
  void PublishStatus(const status_t& s) override {
    std::lock_guard<std::mutex> lock(mutex_);
    statuses_.push_back(s);
  }
  // Also counts shared entries published before their pair's contact event.
  void PublishSharedContact(const shared_contact_t& s) override {
    std::lock_guard<std::mutex> lock(mutex_);
    const bool env_first = std::any_of(contacts_.begin(), contacts_.end(), [&](const auto& e) {
      return e.client_id == s.client_id && e.pair == s.pair;
    });
    if (!env_first) ++shared_before_contact_;
    shared_.push_back(s);
  }
  std::vector<shared_contact_t> shared_messages() const {
    std::lock_guard<std::mutex> lock(mutex_);
    return shared_;
  }
  // One entry of a shared_contact_t with its message's pair fields.
  struct SharedEntry {
    std::string client_id;
    int64_t pair = 0, seq0 = 0, seq1 = 0, utime0 = 0, utime1 = 0;
    shared_entry_t entry;
  };
  // Every entry of every shared_contact_t, in publication order.
  std::vector<SharedEntry> shared() const {
    std::lock_guard<std::mutex> lock(mutex_);
    std::vector<SharedEntry> out;
    for (const shared_contact_t& m : shared_) {
      for (const shared_entry_t& e : m.entries) {
        out.push_back({m.client_id, m.pair, m.seq0, m.seq1, m.utime0, m.utime1, e});
      }
    }
    return out;
  }
  int shared_before_contact() const {
    std::lock_guard<std::mutex> lock(mutex_);
    return shared_before_contact_;
  }

  // While closed, workers block inside PublishContact.
  void CloseGate() {
    std::lock_guard<std::mutex> lock(mutex_);
    gated_ = true;
  }
  void OpenGate() {
    std::lock_guard<std::mutex> lock(mutex_);
    gated_ = false;
    cv_.notify_all();
  }
  // Waits until PublishContact has been entered `n` times in total.
  void WaitEntered(int n) {
    std::unique_lock<std::mutex> lock(mutex_);
    cv_.wait(lock, [&] { return entered_ >= n; });
  }
  // How many times PublishContact has been entered.
  int entered() const {
    std::lock_guard<std::mutex> lock(mutex_);
    return entered_;
  }
  void ThrowOnContact(bool on) {
    std::lock_guard<std::mutex> lock(mutex_);
    throw_on_contact_ = on;
  }

  std::vector<contact_event_t> contacts() const {
    std::lock_guard<std::mutex> lock(mutex_);
    return contacts_;
  }
  std::vector<contact_event_t> contacts_of(const std::string& client) const {
    std::lock_guard<std::mutex> lock(mutex_);
    std::vector<contact_event_t> out;
    for (const auto& e : contacts_) {
      if (e.client_id == client) out.push_back(e);
    }
    return out;
  }
  std::vector<rejection_t> rejections() const {
    std::lock_guard<std::mutex> lock(mutex_);
    return rejections_;
  }
  std::vector<status_t> statuses() const {
    std::lock_guard<std::mutex> lock(mutex_);
    return statuses_;
  }

 private:
  mutable std::mutex mutex_;
  std::condition_variable cv_;
  bool gated_ = false;
  bool throw_on_contact_ = false;
  int entered_ = 0;
  std::vector<contact_event_t> contacts_;
  std::vector<rejection_t> rejections_;
  std::vector<status_t> statuses_;
  std::vector<shared_contact_t> shared_;
  int shared_before_contact_ = 0;
};

// Expects `event` to be exactly what CcdEngine::Query answers for (m0, m1).
inline void ExpectMatchesEngine(const contact_event_t& event, const tracker_pose_t& m0,
                                const tracker_pose_t& m1, const Skeleton& skeleton,
                                const Environment& env, const QueryOptions& options) {
  const CcdEngine engine(skeleton, env);
  const Pose p0 = ToPose(m0, skeleton.num_links());
  const Pose p1 = ToPose(m1, skeleton.num_links());
  const QueryResult r = engine.Query(p0, p1, options);
  EXPECT_EQ(event.seq0, m0.seq);
  EXPECT_EQ(event.seq1, m1.seq);
  EXPECT_EQ(event.utime0, m0.utime);
  EXPECT_EQ(event.utime1, m1.utime);
  EXPECT_EQ(event.error, "");
  // Copies: lcm-gen declares the constants without out-of-line definitions,
  // so binding them to EXPECT_EQ's references would not link.
  const int8_t expected_result =
      r.contact ? int8_t{contact_event_t::RESULT_CONTACT} : int8_t{contact_event_t::RESULT_FREE};
  EXPECT_EQ(event.result, expected_result);
  EXPECT_EQ(event.initially_colliding, r.initially_colliding);
  EXPECT_EQ(event.undecided, r.undecided);
  if (r.contact) {
    EXPECT_EQ(event.s_lo, r.s_lo);
    EXPECT_EQ(event.s_hi, r.s_hi);
    EXPECT_EQ(event.t_lo, BracketTimeLo(m0.utime, m1.utime, r.s_lo));
    EXPECT_EQ(event.t_hi, BracketTimeHi(m0.utime, m1.utime, r.s_hi));
  }
  ASSERT_EQ(event.num_contacts, static_cast<int>(r.contacts.size()));
  ASSERT_EQ(event.contacts.size(), r.contacts.size());
  for (size_t i = 0; i < r.contacts.size(); ++i) {
    const contact_record_t& c = event.contacts[i];
    EXPECT_EQ(c.link, r.contacts[i].link);
    EXPECT_EQ(c.object, r.contacts[i].object);
    EXPECT_EQ(c.triangle, r.contacts[i].triangle);
    EXPECT_EQ(c.s, r.contacts[i].s);
    EXPECT_EQ(c.separation, r.contacts[i].separation);
    for (int k = 0; k < 3; ++k) {
      EXPECT_EQ(c.point_link[k], r.contacts[i].point_link[k]);
      EXPECT_EQ(c.point_env[k], r.contacts[i].point_env[k]);
      EXPECT_EQ(c.normal[k], r.contacts[i].normal[k]);
    }
  }
  ASSERT_EQ(event.num_links, static_cast<int>(r.links.size()));
  for (size_t i = 0; i < r.links.size(); ++i) {
    EXPECT_EQ(event.links[i].link, r.links[i].link);
    EXPECT_EQ(event.links[i].s_lo, r.links[i].s_lo);
    EXPECT_EQ(event.links[i].s_hi, r.links[i].s_hi);
    EXPECT_EQ(event.links[i].has_witness, r.links[i].has_witness);
  }
}

}  // namespace test
}  // namespace sweptccd
