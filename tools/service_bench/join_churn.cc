// Join churn for tools/service_bench/join_churn.sh: in one process (no
// process start-up on the measured machine), live clients of the client
// library join at JOINS_HZ, each stays LIFETIME_S and leaves. MODE:
//   join:   joins and leaves only;
//   stream: every live client also publishes a pose (the first pose of
//           POSES.jsonl, stationary) at 90 Hz while it is live;
//   listen: the control: no join, no leave, no pose; at the same times the
//           same receivers open (a DaemonConnection each, as a LiveClient
//           has), live LIFETIME_S and close: what this process costs the
//           machine without asking the daemon anything.
// Runs SECONDS, then prints the joins, the refusals and the join round trip
// (median, p99, max).
//
//   sweptccd_join_churn URL SKELETON.json POSES.jsonl ROOM_KEY JOINS_HZ LIFETIME_S SECONDS MODE
#include <algorithm>
#include <chrono>
#include <cstdio>
#include <deque>
#include <fstream>
#include <memory>
#include <nlohmann/json.hpp>
#include <string>
#include <thread>
#include <vector>

#include "core/errors.h"
#include "core/percentile.h"
#include "msgs/text.h"
#include "sweptccd_client/live_client.h"
#include "sweptccd_client/tracker_pose.h"

namespace {

using Clock = std::chrono::steady_clock;

}  // namespace

int main(int argc, char** argv) {
  using namespace sweptccd;
  if (argc != 9) {
    std::fprintf(stderr,
                 "usage: %s URL SKELETON.json POSES.jsonl ROOM_KEY JOINS_HZ LIFETIME_S "
                 "SECONDS join|stream|listen\n",
                 argv[0]);
    return 2;
  }
  try {
    const std::string url = argv[1];
    const Skeleton skeleton = LoadSkeletonFile(argv[2]);
    std::ifstream in(argv[3]);
    std::string line;
    if (!std::getline(in, line)) throw InputError(std::string(argv[3]) + ": no pose");
    tracker_pose_t pose = TrackerPoseOfLine(line);
    const MacKey room = LoadKeyFile(argv[4]);
    const double joins_hz = std::stod(argv[5]), lifetime_s = std::stod(argv[6]);
    const double seconds = std::stod(argv[7]);
    const std::string mode = argv[8];
    if (mode != "join" && mode != "stream" && mode != "listen") {
      throw InputError("MODE '" + mode + "' is not join, stream or listen");
    }
    const bool stream = mode == "stream";

    struct Live {
      std::unique_ptr<LiveClient> client;          // join, stream.
      std::unique_ptr<DaemonConnection> listener;  // listen.
      Clock::time_point leave_at;
      int64_t seq = 0;
    };
    std::deque<Live> live;
    std::vector<double> join_ms;
    int64_t joins = 0, refused = 0, no_reply = 0, poses = 0;
    const Clock::time_point t0 = Clock::now(),
                            end = t0 + std::chrono::duration_cast<Clock::duration>(
                                           std::chrono::duration<double>(seconds));
    const auto tick = std::chrono::microseconds(11'111);  // 90 Hz.
    const auto join_period =
        std::chrono::duration_cast<Clock::duration>(std::chrono::duration<double>(1.0 / joins_hz));
    Clock::time_point next_join = t0, next_tick = t0;
    int64_t k = 0;
    while (Clock::now() < end) {
      const Clock::time_point now = Clock::now();
      while (!live.empty() && live.front().leave_at <= now) {
        if (live.front().client) live.front().client->Leave();
        live.pop_front();
      }
      const auto life =
          std::chrono::duration_cast<Clock::duration>(std::chrono::duration<double>(lifetime_s));
      if (now >= next_join && mode == "listen") {
        next_join += join_period;
        DaemonConnection::Options o;
        o.lcm_url = url;
        o.only_client_id = "churn" + std::to_string(k++);
        auto listener = std::make_unique<DaemonConnection>(std::move(o));
        listener->Start();
        live.push_back({nullptr, std::move(listener), Clock::now() + life, 0});
      } else if (now >= next_join) {
        next_join += join_period;
        LiveClient::Options o;
        o.lcm_url = url;
        o.client_id = "churn" + std::to_string(k++);
        o.room_key = room;
        o.skeleton = skeleton;
        o.rejoin = false;
        auto client = std::make_unique<LiveClient>(std::move(o));
        const Clock::time_point a = Clock::now();
        const JoinResult r = client->Join();
        join_ms.push_back(std::chrono::duration<double, std::milli>(Clock::now() - a).count());
        if (r.ok()) {
          ++joins;
          live.push_back({std::move(client), nullptr, Clock::now() + life, 0});
        } else if (r.reason < 0) {
          ++no_reply;
        } else {
          ++refused;
          std::fprintf(stderr, "join refused (%d): %s\n", r.reason, r.message.c_str());
        }
      }
      if (stream && now >= next_tick) {
        const int64_t utime = std::chrono::duration_cast<std::chrono::microseconds>(
                                  std::chrono::system_clock::now().time_since_epoch())
                                  .count();
        for (Live& l : live) {
          pose.utime = utime;
          pose.seq = l.seq++;
          poses += l.client->PublishPose(pose);
        }
        next_tick += tick;
      }
      std::this_thread::sleep_until(stream ? std::min(next_join, next_tick) : next_join);
    }
    for (Live& l : live) {
      if (l.client) l.client->Leave();
    }
    const Summary join = Summarise(join_ms);
    std::printf(
        "join churn: %lld joins (%lld refused, %lld unanswered) in %.1f s, %lld poses of "
        "live clients; join round trip median %.2f ms, p99 %.2f ms, max %.2f ms\n",
        static_cast<long long>(joins), static_cast<long long>(refused),
        static_cast<long long>(no_reply), seconds, static_cast<long long>(poses), join.median,
        join.p99, join.max);
    return refused + no_reply == 0 ? 0 : 1;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "error: %s\n", DisplayError(e.what()).c_str());
    return 2;
  }
}
