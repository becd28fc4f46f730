// The daemon's loop on memq:// (in-process, never the network): built from a
// configuration like sweptccd-service's, started, fed poses, stopped; the
// answers checked against the engine. Waits on WaitUntilIdle, never sleeps.
#include "service/daemon/daemon.h"

#include <gtest/gtest.h>

#include <cstdio>
#include <lcm/lcm-cpp.hpp>
#include <string>

#include "core/errors.h"
#include "msgs/signing.h"
#include "service/collision_service.h"
#include "tests/service/service_test_util.h"

namespace sweptccd {
namespace {

using test::Sample;

// The room key of a test's daemon: a new mode-600 key file in its folder.
std::string RoomKeyFile(const std::string& dir) {
  const std::string path = dir + "/room.key";
  std::remove(path.c_str());
  WriteNewKeyFile(path);
  return path;
}

// Publishes `m` signed with the room key of the test's daemon (signed mode,
// the default, refuses anything else).
int PublishSigned(Daemon* daemon, const ServiceConfig& config, const tracker_pose_t& m) {
  const MacKey key = LoadKeyFile(config.security.room_key);
  const std::vector<uint8_t> bytes = EncodeSigned(m, &key);
  return daemon->lcm()->publish(kPoseChannel, bytes.data(),
                                static_cast<unsigned int>(bytes.size()));
}

ServiceConfig MemqConfig(const std::string& test_name) {
  const std::string dir = test::TestDir("daemon_test_" + test_name);
  ServiceConfig config;
  config.security.room_key = RoomKeyFile(dir);
  config.lcm_url = "memq://";
  config.environment = {test::WriteFloorObj(dir)};
  const std::string skeleton = test::WriteTwoLinkSkeleton(dir);
  for (const char* id : {"a", "b"}) {
    ClientSpec spec;
    spec.id = id;
    spec.skeleton_path = skeleton;
    config.clients.push_back(spec);
  }
  config.backend = gpu::BackendKind::kCpu;
  config.status_period_s = 3600;  // No timer status unless a test asks for it.
  config.log_level = "warn";
  config.security.mode =
      "unsigned";  // memq:// in one process; signing is tested in lcm_transport_test.
  ValidateServiceConfig(config);
  return config;
}

TEST(DaemonTest, AnswersEveryPairThenStopsWithAFinalStatus) {
  const ServiceConfig config = MemqConfig("answers");
  Daemon daemon(config);
  test::Listener listener;
  listener.SubscribeTo(daemon.lcm());
  daemon.Start();
  constexpr int kPoses = 16;  // Contact from pose 13 on (Height <= 0.1 m).
  for (int64_t k = 0; k < kPoses; ++k) {
    for (const char* id : {"a", "b"}) {
      const tracker_pose_t m = Sample(id, k);
      ASSERT_EQ(PublishSigned(&daemon, config, m), 0);
    }
    daemon.WaitUntilIdle();  // One pose per client at a time: no latest-wins skipping.
    ASSERT_EQ(listener.contacts().size(), static_cast<size_t>(2 * k)) << "after pose " << k;
  }
  const tracker_pose_t stranger = Sample("nobody", 0);
  PublishSigned(&daemon, config, stranger);
  daemon.WaitUntilIdle();
  ASSERT_EQ(listener.rejections().size(), 1u);
  EXPECT_EQ(listener.rejections()[0].reason, rejection_code::kUnknownClient);

  daemon.Stop();
  daemon.WaitUntilIdle();  // After Stop: delivers what Stop published.
  const std::vector<status_t> statuses = listener.statuses();
  // Start announces the daemon (a status at once: live clients see a new
  // instance and re-join); Stop publishes one last status.
  ASSERT_EQ(statuses.size(), 2u);
  EXPECT_EQ(statuses[0].instance, daemon.service()->instance());
  EXPECT_EQ(statuses[1].instance, statuses[0].instance);
  EXPECT_GT(statuses[0].instance, 0);
  for (int i = 0; i < 2; ++i) EXPECT_EQ(statuses[0].pairs_answered[i], 0);
  EXPECT_EQ(statuses[1].backend, "cpu");
  EXPECT_EQ(statuses[1].rejected_unattributed, 1);
  for (int i = 0; i < 2; ++i) EXPECT_EQ(statuses[1].pairs_answered[i], kPoses - 1);

  const auto skeleton = test::TwoLinkSkeleton();
  const auto env = test::FloorEnvironment();
  int contact = 0;
  for (const char* id : {"a", "b"}) {
    int64_t next = 0;
    for (const contact_event_t& e : listener.contacts()) {
      if (e.client_id != id) continue;
      SCOPED_TRACE(std::string(id) + " pair " + std::to_string(next));
      EXPECT_EQ(e.pair, next);
      test::ExpectMatchesEngine(e, Sample(id, next), Sample(id, next + 1), *skeleton, *env,
                                QueryOptions{});
      contact += e.result == contact_event_t::RESULT_CONTACT;
      ++next;
    }
    EXPECT_EQ(next, kPoses - 1);
  }
  EXPECT_GT(contact, 0);

  // Stopped: poses are no longer taken, and Stop stays idempotent.
  const tracker_pose_t late = Sample("a", kPoses);
  PublishSigned(&daemon, config, late);
  daemon.WaitUntilIdle();
  EXPECT_EQ(listener.contacts().size(), static_cast<size_t>(2 * (kPoses - 1)));
  daemon.Stop();
}

TEST(DaemonTest, PublishesStatusOnItsTimer) {
  ServiceConfig config = MemqConfig("timer");
  config.status_period_s = 0.001;
  Daemon daemon(config);
  test::Listener listener;
  listener.SubscribeTo(daemon.lcm());
  daemon.Start();
  // Statuses are published and delivered by the loop thread alone.
  ASSERT_TRUE(listener.WaitForStatuses(3));
  daemon.Stop();
  EXPECT_EQ(listener.statuses()[0].num_clients, 2);
}

TEST(DaemonTest, StopWithoutStartAnswersWhatWasQueued) {
  const ServiceConfig config = MemqConfig("no_start");
  Daemon daemon(config);
  test::Listener listener;
  listener.SubscribeTo(daemon.lcm());
  for (int64_t k = 0; k < 2; ++k) {
    const tracker_pose_t m = Sample("a", k);
    PublishSigned(&daemon, config, m);
  }
  daemon.WaitUntilIdle();  // No loop: handled on this thread.
  ASSERT_EQ(listener.contacts().size(), 1u);
  daemon.Stop();
}

TEST(DaemonTest, RefusesWhatItCannotBuild) {
  ServiceConfig config = MemqConfig("refusals");
  ServiceConfig bad_level = config;
  bad_level.log_level = "loud";
  try {
    Daemon daemon(bad_level);
    ADD_FAILURE() << "an unknown log level was accepted";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("loud"), std::string::npos) << e.what();
  }
  ServiceConfig missing_mesh = config;
  missing_mesh.environment = {config.environment[0] + ".missing.obj"};
  EXPECT_THROW(Daemon{missing_mesh}, InputError);
  // A tracked object whose mesh is missing, or is no mesh: one line naming
  // the file, and no daemon.
  for (const char* bad : {".missing.obj", ".txt"}) {
    ServiceConfig object_mesh = config;
    object_mesh.shared_world = true;
    ObjectSpec cup;
    cup.id = "cup";
    cup.mesh_path = config.environment[0] + bad;
    if (std::string(bad) == ".txt") {
      std::FILE* f = std::fopen(cup.mesh_path.c_str(), "w");
      ASSERT_NE(f, nullptr);
      std::fputs("not a mesh\n", f);
      std::fclose(f);
    }
    object_mesh.objects = {cup};
    try {
      Daemon daemon(object_mesh);
      ADD_FAILURE() << "an object with mesh " << cup.mesh_path << " was accepted";
    } catch (const InputError& e) {
      const std::string what = e.what();
      EXPECT_NE(what.find(cup.mesh_path), std::string::npos) << what;
      EXPECT_EQ(what.rfind("objects: 'cup' mesh: ", 0), 0u) << what;
      EXPECT_EQ(what.find('\n'), std::string::npos) << "one line: " << what;
    }
  }
  ServiceConfig bad_url = config;
  bad_url.lcm_url = "nosuchprovider://";
  try {
    Daemon daemon(bad_url);
    ADD_FAILURE() << "an unusable LCM URL was accepted";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("nosuchprovider://"), std::string::npos) << e.what();
  }
}

// The shared world's filters are resolved against the skeletons at start:
// one line naming the rule and the link for each that cannot be; a rule
// with names that resolve starts.
TEST(DaemonTest, RefusesFiltersItCannotResolve) {
  ServiceConfig config = MemqConfig("entity_rules");
  config.shared_world = true;
  auto refusal = [&](EntityRuleSpec rule) -> std::string {
    ServiceConfig c = config;
    c.clients[0].ignore_entities = {rule};
    try {
      Daemon daemon(c);
    } catch (const InputError& e) {
      return e.what();
    }
    return "";
  };
  const std::string no_link = refusal({"elbow", "b", ""});
  EXPECT_NE(no_link.find("ignore_entities[0].link: unknown link 'elbow'"), std::string::npos)
      << no_link;
  const std::string no_other = refusal({"0", "b", "wrist"});
  EXPECT_NE(no_other.find("other_link: unknown link 'wrist'"), std::string::npos) << no_other;
  const std::string out_of_range = refusal({"7", "b", ""});
  EXPECT_NE(out_of_range.find("unknown link '7'"), std::string::npos) << out_of_range;
  const std::string unknown_by_name = refusal({"*", "someone", "wrist"});
  EXPECT_NE(unknown_by_name.find("not a configured client; give an index"), std::string::npos)
      << unknown_by_name;
  EXPECT_EQ(refusal({"1", "b", "0"}), "");
  EXPECT_EQ(refusal({"*", "someone_later", "3"}), "") << "a live client's id, by index";
}

}  // namespace
}  // namespace sweptccd
