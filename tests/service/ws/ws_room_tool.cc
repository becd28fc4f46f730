// The C++ client (WsLiveClient) against a real door, for
// tests/service/e2e_websocket_rooms.sh:
//   ws_room_tool rooms PORT ROOM ROOM_KEY SKELETON
//     through a static room map: a client of another room than the door's
//     is refused with 409 before any frame (one clear error, never joined,
//     FailoverStats::wrong_rooms counted); a client of ROOM joins.
//   ws_room_tool configured PORT ID OWN_KEY ROOM_KEY SKELETON POSES EXPECTED
//     ID is a client of the daemon's configuration with its own key
//     (docs/WEBSOCKET.md "Configured clients"): a join proven with the room
//     key is bad_proof; with its own key it is accepted, a second client
//     instance (another nonce) gets id_in_use, a join with another skeleton
//     bad_skeleton; the walk streamed lock-step, each pair equal to `sweptccd
//     query`'s record (EXPECTED) and answered once; a repeated seq gets the
//     LCM door's rejection non_increasing_seq. OWN_KEY and ROOM_KEY "-": an
//     unsigned room (no proofs; the bad_proof step is left out).
//   ws_room_tool fence PORT STALE_PORT ROOM ROOM_KEY SKELETON
//     a resolver that answers PORT, then once STALE_PORT (a server of ROOM
//     started earlier: an older instance, a stale answer), then PORT: the
//     client joins PORT's daemon and prints "joined instance I"; the script
//     SIGKILLs that daemon and starts it again; the client must refuse the
//     stale server's hello (older than the instance it joined: fenced) and
//     join the restarted one.
//   ws_room_tool joint-frames OUT
//     writes 16 joint frames of WebXR's hand (webxr-hand, the default
//     skeleton's bone lengths) lowered 2 cm a frame from 0.22 m above the
//     floor through it, for `sweptccd skeleton --joints` and `sweptccd query`.
//   ws_room_tool joints PORT ROOM_KEY FRAMES EXPECTED
//     joins with webxr-hand's default skeleton and streams FRAMES lock-step
//     with WsLiveClient::PublishJointFrame: each pair equal to `sweptccd
//     query`'s record on the command's conversion (EXPECTED); a frame with
//     an untracked joint and a joint skeleton of another size are refused
//     with their one line and nothing is sent.
// Prints "ok MODE: ..." on success, else "FAIL MODE: ..." and exits 1.
#include <algorithm>
#include <atomic>
#include <chrono>
#include <condition_variable>
#include <cstdio>
#include <fstream>
#include <map>
#include <mutex>
#include <nlohmann/json.hpp>
#include <optional>
#include <string>
#include <thread>
#include <vector>

#include "core/avatar/joint_frame.h"
#include "core/avatar/joint_set.h"
#include "msgs/signing.h"
#include "sweptccd_client/room_resolver.h"
#include "sweptccd_client/tracker_pose.h"
#include "sweptccd_client/ws_client.h"

namespace {

using namespace sweptccd;
using Clock = std::chrono::steady_clock;

int Fail(const std::string& mode, const std::string& why) {
  std::printf("FAIL %s: %s\n", mode.c_str(), why.c_str());
  return 1;
}

std::vector<std::string> ReadLines(const std::string& path) {
  std::vector<std::string> out;
  std::ifstream in(path);
  std::string line;
  while (std::getline(in, line)) {
    if (!line.empty()) out.push_back(line);
  }
  return out;
}

// A key file, or "-": none (an unsigned room).
std::optional<MacKey> KeyArg(const std::string& path) {
  if (path == "-") return std::nullopt;
  return LoadKeyFile(path);
}

// Whether event `e` answers exactly the pair (seq1 - 1, seq1) and equals
// `sweptccd query`'s record for it (expected[seq1 - 1]): the result, and for
// a contact the bracket, initially_colliding and the first witness's link
// and triangle. A record that does not read as expected is a mismatch (an
// exception here would be lost inside the client's callback).
bool AnswersRecord(const contact_event_t& e, const std::vector<std::string>& expected) {
  const size_t k = static_cast<size_t>(e.seq1 - 1);
  if (!(e.seq0 == e.seq1 - 1 && e.seq1 >= 1 && k < expected.size())) return false;
  try {
    const nlohmann::json want = nlohmann::json::parse(expected[k]);
    const int w = want["result"] == "contact" ? 1 : want["result"] == "free" ? 0 : 2;
    if (e.result != w) return false;
    if (w != 1) return true;
    return e.s_lo == want["s_lo"].get<double>() && e.s_hi == want["s_hi"].get<double>() &&
           e.initially_colliding == want["initially_colliding"].get<bool>() &&
           !e.contacts.empty() && e.contacts[0].link == want["contacts"][0]["link"].get<int>() &&
           e.contacts[0].triangle == want["contacts"][0]["triangle"].get<int64_t>();
  } catch (const std::exception&) {
    return false;
  }
}

WsLiveClient::Options Base(uint16_t port, const std::string& id, const std::optional<MacKey>& key,
                           const Skeleton& skeleton) {
  WsLiveClient::Options o;
  o.host = "127.0.0.1";
  o.port = port;
  o.client_id = id;
  o.room_key = key;
  o.skeleton = skeleton;
  o.reconnect = false;
  o.join_timeout_s = 3;
  o.heartbeat_timeout_s = 0;
  return o;
}

int Rooms(uint16_t port, const std::string& room, const MacKey& key, const Skeleton& skeleton) {
  const std::string door = "ws://127.0.0.1:" + std::to_string(port);
  auto map = std::make_shared<StaticRoomMap>(StaticRoomMap::FromText(
      nlohmann::json{{"rooms", {{room, door}, {"other-room", door}}}}.dump(), "map"));
  WsLiveClient::Options o = Base(port, "wanderer", key, skeleton);
  o.resolver = map;
  o.room = "other-room";
  std::string frames;
  {
    WsLiveClient wrong(o);
    wrong.OnText([&](const std::string& t) { frames += t; });
    const JoinResult r = wrong.Join();
    const auto f = wrong.failover();
    if (r.ok() || wrong.joined()) return Fail("rooms", "a client of another room joined");
    if (f.wrong_rooms != 1 || f.last_error.find("(409)") == std::string::npos ||
        f.last_error.find("'other-room'") == std::string::npos ||
        f.last_error.find("holds room '" + room + "'") == std::string::npos) {
      return Fail("rooms", "wrong_rooms " + std::to_string(f.wrong_rooms) + ", error '" +
                               f.last_error + "'");
    }
    if (!frames.empty()) return Fail("rooms", "frames of another room delivered: " + frames);
    std::printf("refused: %s\n", f.last_error.c_str());
  }
  o.room = room;
  o.client_id = "resident";
  WsLiveClient right(o);
  const JoinResult r = right.Join();
  if (!r.ok() || right.failover().wrong_rooms != 0) {
    return Fail("rooms", "the room's own client did not join: " + r.message + " " +
                             right.failover().last_error);
  }
  right.Leave();
  std::printf("ok rooms: another room's client refused with 409, '%s' joined\n", room.c_str());
  return 0;
}

// Answers its doors in turn, then the last one for good.
class SequenceResolver : public RoomResolver {
 public:
  explicit SequenceResolver(std::vector<DoorAddress> doors) : doors_(std::move(doors)) {}
  DoorAddress Resolve(const std::string&) override {
    std::lock_guard<std::mutex> lock(mutex_);
    return doors_[std::min(next_++, doors_.size() - 1)];
  }

 private:
  std::mutex mutex_;
  std::vector<DoorAddress> doors_;
  size_t next_ = 0;
};

int Fence(uint16_t port, uint16_t stale_port, const std::string& room, const MacKey& key,
          const Skeleton& skeleton) {
  const auto door = [](uint16_t p) { return DoorAddress{"127.0.0.1", p, false, "test"}; };
  WsLiveClient::Options o = Base(port, "fencer", key, skeleton);
  o.resolver = std::make_shared<SequenceResolver>(
      std::vector<DoorAddress>{door(port), door(stale_port), door(port)});
  o.room = room;
  o.reconnect = true;
  o.max_backoff_s = 0.25;
  WsLiveClient client(o);
  const JoinResult first = client.Join();
  if (!first.ok()) return Fail("fence", "no first join: " + first.message);
  std::printf("joined instance %lld\n", static_cast<long long>(first.instance));
  std::fflush(stdout);
  const auto deadline = Clock::now() + std::chrono::seconds(15);
  while (Clock::now() < deadline && !(client.joined() && client.instance() > first.instance)) {
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
  }
  const auto f = client.failover();
  if (!client.joined() || client.instance() <= first.instance || f.fenced_hellos != 1 ||
      f.wrong_rooms != 0) {
    return Fail("fence", "joined " + std::to_string(client.joined()) + " instance " +
                             std::to_string(client.instance()) + ", fenced hellos " +
                             std::to_string(f.fenced_hellos) + ", wrong rooms " +
                             std::to_string(f.wrong_rooms) + ", last error '" + f.last_error + "'");
  }
  std::printf("ok fence: the stale server's older instance fenced (%s), joined instance %lld\n",
              f.last_error.c_str(), static_cast<long long>(client.instance()));
  client.Leave();
  return 0;
}

int Configured(uint16_t port, const std::string& id, const std::optional<MacKey>& own,
               const std::optional<MacKey>& room_key, const Skeleton& skeleton,
               const std::vector<std::string>& poses, const std::vector<std::string>& expected) {
  const std::string mode = "configured";
  if (poses.size() < 2 || expected.size() != poses.size() - 1) {
    return Fail(mode, std::to_string(poses.size()) + " poses, " + std::to_string(expected.size()) +
                          " expected records");
  }
  if (room_key) {  // Proven with the room key, while the client has its own: bad_proof.
    WsLiveClient wrong(Base(port, id, room_key, skeleton));
    std::string codes;
    wrong.OnError([&](const std::string& code, const std::string&) { codes += code + " "; });
    if (wrong.Join().ok()) return Fail(mode, "a join proven with the room key was accepted");
    if (codes.find("bad_proof") == std::string::npos) {
      return Fail(mode, "no bad_proof for the room key, errors: '" + codes + "'");
    }
  }
  {  // Another skeleton than the configured one: bad_skeleton.
    std::vector<Link> links = skeleton.links();
    links[0].radius *= 2;
    WsLiveClient other(Base(port, id, own, Skeleton::FromLinks(id, links, "test")));
    const JoinResult r = other.Join();
    if (r.reason != join_reply_t::REASON_BAD_SKELETON) {
      return Fail(mode, "another skeleton: reason " + std::to_string(r.reason));
    }
  }
  WsLiveClient client(Base(port, id, own, skeleton));
  std::mutex mutex;
  std::condition_variable cv;
  std::map<int64_t, int> answered;  // seq1 -> times
  int64_t mismatches = 0, contacts = 0;
  std::vector<std::string> rejections;
  client.OnContact([&](const contact_event_t& e) {
    std::lock_guard<std::mutex> lock(mutex);
    ++answered[e.seq1];
    if (!AnswersRecord(e, expected)) ++mismatches;
    if (e.result == 1) ++contacts;
    cv.notify_all();
  });
  client.OnRejection([&](const rejection_t& r) {
    std::lock_guard<std::mutex> lock(mutex);
    rejections.push_back(r.reason);
    cv.notify_all();
  });
  const JoinResult joined = client.Join();
  if (!joined.ok()) return Fail(mode, "the configured client's join: " + joined.message);
  {  // A second instance (another nonce) while the first holds the id.
    WsLiveClient second(Base(port, id, own, skeleton));
    const JoinResult r = second.Join();
    if (r.reason != join_reply_t::REASON_ID_IN_USE) {
      return Fail(mode, "a second instance: reason " + std::to_string(r.reason));
    }
  }
  // Lock-step: pose k is sent once pair (k-2, k-1) is answered, so no pair
  // is merged by latest-wins and each equals the query's record.
  for (size_t k = 0; k < poses.size(); ++k) {
    tracker_pose_t p = TrackerPoseOfLine(poses[k]);
    p.seq = static_cast<int64_t>(k);
    if (!client.PublishPose(p)) return Fail(mode, "pose " + std::to_string(k) + " refused");
    std::this_thread::sleep_for(std::chrono::milliseconds(5));  // Under max_pose_rate_hz.
    if (k == 0) continue;
    std::unique_lock<std::mutex> lock(mutex);
    if (!cv.wait_for(lock, std::chrono::seconds(5),
                     [&] { return answered.count(static_cast<int64_t>(k)) > 0; })) {
      return Fail(mode, "no answer for pair " + std::to_string(k));
    }
  }
  // The LCM door's session rules and codes: a repeated seq is refused.
  tracker_pose_t again = TrackerPoseOfLine(poses.back());
  again.seq = static_cast<int64_t>(poses.size() - 1);
  again.utime += 1000;
  client.PublishPose(again);
  {
    std::unique_lock<std::mutex> lock(mutex);
    cv.wait_for(lock, std::chrono::seconds(5), [&] { return !rejections.empty(); });
    if (rejections.size() != 1 || rejections[0] != "non_increasing_seq") {
      return Fail(mode, std::to_string(rejections.size()) + " rejections, first '" +
                            (rejections.empty() ? "" : rejections[0]) + "'");
    }
    int64_t twice = 0;
    for (const auto& [seq1, n] : answered) twice += n > 1 ? 1 : 0;
    if (answered.size() != expected.size() || twice != 0 || mismatches != 0) {
      return Fail(mode, std::to_string(answered.size()) + " of " + std::to_string(expected.size()) +
                            " pairs, " + std::to_string(twice) + " twice, " +
                            std::to_string(mismatches) + " unequal to sweptccd query");
    }
  }
  const int64_t session = client.session();
  client.Leave();
  {  // Its hold ended with the connection: a new instance takes the id.
    WsLiveClient next(Base(port, id, own, skeleton));
    JoinResult r;
    for (int i = 0; i < 20; ++i) {
      r = next.Join();
      if (r.reason != join_reply_t::REASON_ID_IN_USE) break;
      std::this_thread::sleep_for(std::chrono::milliseconds(50));  // The leave is on its way.
    }
    if (!r.ok() || r.session <= session) {
      return Fail(mode, "after leave: reason " + std::to_string(r.reason) + ", session " +
                            std::to_string(r.session) + " after " + std::to_string(session));
    }
    next.Leave();
  }
  std::printf(
      "ok configured: '%s' over the door (%s), %zu pairs equal to sweptccd query (%lld "
      "contacts), non_increasing_seq, id_in_use, %sbad_skeleton\n",
      id.c_str(), room_key ? "signed" : "unsigned", expected.size(),
      static_cast<long long>(contacts), room_key ? "bad_proof, " : "");
  return 0;
}

// The hand of `joints` (every joint at identity orientation, each bone's
// far joint its length along +Y from the near one), at `origin`.
JointFrame HandFrame(const JointSkeleton& joints, const Eigen::Vector3d& origin, int64_t utime) {
  const JointSet& set = joints.joint_set();
  JointFrame frame;
  frame.utime = utime;
  frame.joints.resize(set.num_joints());
  for (JointSample& j : frame.joints) j.p = origin;
  const Skeleton& skeleton = joints.skeleton();
  for (int i = 0; i < skeleton.num_links(); ++i) {  // Parents first.
    const LinkDef& link = *joints.plan()[i].def;
    if (link.joint_b < 0 || link.fixed_length) continue;  // Only bones are measured.
    frame.joints[link.joint_b].p =
        frame.joints[link.joint_a].p + Eigen::Vector3d(0, skeleton.link(i).b_L.norm(), 0);
  }
  return frame;
}

JointSkeleton HandJoints() { return JointSkeleton::Build(FindJointSet("webxr-hand"), {}); }

int WriteJointFrames(const std::string& out_path) {
  const JointSkeleton joints = HandJoints();
  std::ofstream out(out_path);
  for (int k = 0; k < 16; ++k) {
    out << JointFrameToJsonLine(HandFrame(joints, Eigen::Vector3d(1.0, -1.0, 0.22 - 0.02 * k),
                                          1'000'000 + 33'333 * k))
        << '\n';
  }
  out.flush();
  if (!out) return Fail("joint-frames", "cannot write " + out_path);
  std::printf("ok joint-frames: 16 frames in %s\n", out_path.c_str());
  return 0;
}

int Joints(uint16_t port, const MacKey& key, const std::vector<std::string>& frames,
           const std::vector<std::string>& expected) {
  const std::string mode = "joints";
  const JointSkeleton joints = HandJoints();
  if (frames.size() < 2 || expected.size() != frames.size() - 1) {
    return Fail(mode, std::to_string(frames.size()) + " frames, " +
                          std::to_string(expected.size()) + " expected records");
  }
  WsLiveClient client(Base(port, "hand", key, joints.skeleton()));
  std::mutex mutex;
  std::condition_variable cv;
  std::map<int64_t, int> answered;  // seq1 -> times
  int64_t mismatches = 0, contacts = 0;
  client.OnContact([&](const contact_event_t& e) {
    std::lock_guard<std::mutex> lock(mutex);
    ++answered[e.seq1];
    if (!AnswersRecord(e, expected)) ++mismatches;
    if (e.result == 1) ++contacts;
    cv.notify_all();
  });
  const JoinResult joined = client.Join();
  if (!joined.ok()) return Fail(mode, "join: " + joined.message);
  for (size_t k = 0; k < frames.size(); ++k) {
    std::string error;
    const std::optional<JointFrame> frame =
        ParseJointFrameLine(frames[k], joints.joint_set().num_joints(), &error);
    if (!frame) return Fail(mode, "frame " + std::to_string(k) + ": " + error);
    const std::string problem = client.PublishJointFrame(joints, *frame, static_cast<int64_t>(k));
    if (!problem.empty()) return Fail(mode, "frame " + std::to_string(k) + ": " + problem);
    std::this_thread::sleep_for(std::chrono::milliseconds(5));  // Under max_pose_rate_hz.
    if (k == 0) continue;
    std::unique_lock<std::mutex> lock(mutex);
    if (!cv.wait_for(lock, std::chrono::seconds(5),
                     [&] { return answered.count(static_cast<int64_t>(k)) > 0; })) {
      return Fail(mode, "no answer for pair " + std::to_string(k));
    }
  }
  // Refused before anything is sent: an untracked joint a link needs, and
  // the joint skeleton of another set.
  std::string error;
  JointFrame bad = *ParseJointFrameLine(frames.back(), joints.joint_set().num_joints(), &error);
  bad.utime += 33'333;
  bad.joints[joints.joint_set().num_joints() - 1].valid = false;  // pinky-finger-tip
  const std::string untracked =
      client.PublishJointFrame(joints, bad, static_cast<int64_t>(frames.size()));
  const JointSkeleton body = JointSkeleton::Build(FindJointSet("htc-body"), {});
  JointFrame other;
  other.joints.resize(body.joint_set().num_joints());
  const std::string wrong_set =
      client.PublishJointFrame(body, other, static_cast<int64_t>(frames.size()));
  std::this_thread::sleep_for(std::chrono::milliseconds(200));  // An answer would be back.
  std::lock_guard<std::mutex> lock(mutex);
  int64_t twice = 0;
  for (const auto& [seq1, n] : answered) twice += n > 1 ? 1 : 0;
  if (answered.size() != expected.size() || twice != 0 || mismatches != 0) {
    return Fail(mode, std::to_string(answered.size()) + " of " + std::to_string(expected.size()) +
                          " pairs, " + std::to_string(twice) + " twice, " +
                          std::to_string(mismatches) + " unequal to sweptccd query");
  }
  if (contacts == 0) return Fail(mode, "no contact among the pairs: the frames miss the floor");
  if (untracked.find("pinky-finger-tip") == std::string::npos ||
      untracked.find("not tracked") == std::string::npos ||
      wrong_set.find("this client joined with") == std::string::npos) {
    return Fail(mode, "refusals: '" + untracked + "', '" + wrong_set + "'");
  }
  client.Leave();
  std::printf(
      "ok joints: %zu pairs of joint frames equal to sweptccd query (%lld contacts); refused: "
      "'%s', '%s'\n",
      expected.size(), static_cast<long long>(contacts), untracked.c_str(), wrong_set.c_str());
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  try {
    const std::string mode = argc > 1 ? argv[1] : "";
    if (mode == "rooms" && argc == 6) {
      return Rooms(static_cast<uint16_t>(std::stoi(argv[2])), argv[3], LoadKeyFile(argv[4]),
                   LoadSkeletonFile(argv[5]));
    }
    if (mode == "configured" && argc == 9) {
      return Configured(static_cast<uint16_t>(std::stoi(argv[2])), argv[3], KeyArg(argv[4]),
                        KeyArg(argv[5]), LoadSkeletonFile(argv[6]), ReadLines(argv[7]),
                        ReadLines(argv[8]));
    }
    if (mode == "joint-frames" && argc == 3) return WriteJointFrames(argv[2]);
    if (mode == "joints" && argc == 6) {
      return Joints(static_cast<uint16_t>(std::stoi(argv[2])), LoadKeyFile(argv[3]),
                    ReadLines(argv[4]), ReadLines(argv[5]));
    }
    if (mode == "fence" && argc == 7) {
      return Fence(static_cast<uint16_t>(std::stoi(argv[2])),
                   static_cast<uint16_t>(std::stoi(argv[3])), argv[4], LoadKeyFile(argv[5]),
                   LoadSkeletonFile(argv[6]));
    }
  } catch (const std::exception& e) {
    std::printf("FAIL: %s\n", e.what());
    return 1;
  }
  std::fprintf(stderr,
               "usage: ws_room_tool rooms PORT ROOM ROOM_KEY SKELETON\n"
               "       ws_room_tool configured PORT ID OWN_KEY ROOM_KEY SKELETON POSES "
               "EXPECTED\n"
               "       ws_room_tool fence PORT STALE_PORT ROOM ROOM_KEY SKELETON\n"
               "       ws_room_tool joint-frames OUT\n"
               "       ws_room_tool joints PORT ROOM_KEY FRAMES EXPECTED\n");
  return 2;
}
