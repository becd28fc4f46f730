// The client library in a few lines (docs/USAGE.md, "Live clients"): join a
// sweptccd-service daemon with a skeleton, publish poses, print the contact
// events and rejections it answers, leave.
//   sweptccd_client_example LCM_URL CLIENT_ID SKELETON.json [ROOM_KEY_FILE]
// Without ROOM_KEY_FILE the messages go unsigned (a lab-bench daemon).
// The avatar stands 1 m above the origin and sinks 5 cm per pose for 40 poses;
// the program leaves once the pair ending at the last pose is answered (or
// after 5 s). Each answer is printed with the poses it spans: a daemon that
// falls behind answers from the pose it last answered to the newest one
// (latest-wins), so the spans always join up, but may cover several poses.
#include <atomic>
#include <chrono>
#include <cstdio>
#include <thread>

#include "core/errors.h"
#include "msgs/text.h"
#include "sweptccd_client/live_client.h"
#include "sweptccd_client/tracker_pose.h"

int main(int argc, char** argv) {
  using namespace sweptccd;
  if (argc < 4 || argc > 5) {
    std::fprintf(stderr, "usage: %s LCM_URL CLIENT_ID SKELETON.json [ROOM_KEY_FILE]\n", argv[0]);
    return 2;
  }
  try {
    LiveClient::Options options;
    options.lcm_url = argv[1];
    options.client_id = argv[2];
    options.skeleton = LoadSkeletonFile(argv[3]);
    if (argc == 5) options.room_key = LoadKeyFile(argv[4]);
    LiveClient client(options);
    std::atomic<int64_t> last_seq1{-1};
    client.OnContact([&last_seq1](const contact_event_t& e) {
      std::printf("pair %lld (seq %lld-%lld): %s\n", static_cast<long long>(e.pair),
                  static_cast<long long>(e.seq0), static_cast<long long>(e.seq1),
                  e.result == contact_event_t::RESULT_CONTACT ? "contact" : "free");
      last_seq1 = e.seq1;
    });
    client.OnRejection([](const rejection_t& r) {
      std::printf("rejected seq %lld: %s: %s\n", static_cast<long long>(r.seq),
                  EscapeForDisplay(r.reason).c_str(), EscapeForDisplay(r.message).c_str());
    });
    const JoinResult joined = client.Join();
    if (!joined.ok()) {
      std::fprintf(stderr, "error: join refused (%d): %s\n", joined.reason, joined.message.c_str());
      return 1;
    }
    std::printf("joined: session %lld\n", static_cast<long long>(joined.session));
    const int n = options.skeleton->num_links();
    const int64_t t0 = joined.session;  // Any increasing utimes; the session is a fine start.
    constexpr int kPoses = 40;
    for (int k = 0; k < kPoses; ++k) {
      Pose p;                     // Every link frame at the same place, unrotated.
      p.utime = t0 + k * 11'111;  // 90 Hz.
      p.links.assign(
          n, LinkPose{Eigen::Vector3d(0.0, 1.0 - 0.05 * k, 0.0), Eigen::Quaterniond::Identity()});
      tracker_pose_t pose = TrackerPoseOf(p);
      pose.seq = k;
      client.PublishPose(pose);
      std::this_thread::sleep_for(std::chrono::microseconds(11'111));
    }
    // The last answer, then leave (a stalled daemon may answer late).
    const auto give_up = std::chrono::steady_clock::now() + std::chrono::seconds(5);
    while (last_seq1 != kPoses - 1 && std::chrono::steady_clock::now() < give_up) {
      std::this_thread::sleep_for(std::chrono::milliseconds(10));
    }
    std::fflush(stdout);
    client.Leave();
    std::printf("left\n");
  } catch (const InputError& e) {
    std::fprintf(stderr, "error: %s\n", e.what());
    return 2;
  }
  return 0;
}
