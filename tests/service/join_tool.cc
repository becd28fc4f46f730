// Test helper for tests/service/e2e_live.sh (not a GoogleTest binary): sends
// one join that the daemon must refuse, of the kind named, over real LCM, and
// checks the reply's reason code.
//
//   join_tool URL ROOM_KEY SKELETON.json KIND
//
// KIND: bad_skeleton (two roots), too_many_links (300 links), bad_filter,
// bad_options (motion 9), stale_request (utime an hour old),
// too_many_clients (joins until the daemon is full; MAX_LIVE of them must be
// accepted first, the next refused). Prints "KIND: reason R: MESSAGE" (the
// message escaped); exits 0 when the reason is the expected one, 1 otherwise.
#include <chrono>
#include <cstdio>
#include <functional>
#include <lcm/lcm-cpp.hpp>
#include <optional>
#include <string>

#include "core/avatar/skeleton.h"
#include "core/errors.h"
#include "msgs/channels.h"
#include "msgs/checked_decode.h"
#include "msgs/signing.h"
#include "msgs/text.h"
#include "sweptccd_client/live_client.h"

namespace {

using namespace sweptccd;

struct Waiter {
  int64_t nonce = 0;
  std::optional<join_reply_t> reply;
  void On(const lcm::ReceiveBuffer* rbuf, const std::string&) {
    DecodeResult<join_reply_t> r = DecodeChecked<join_reply_t>(rbuf->data, rbuf->data_size, {});
    if (r.ok() && r.message->nonce == nonce) reply = *r.message;
  }
};

int64_t Now() {
  return std::chrono::duration_cast<std::chrono::microseconds>(
             std::chrono::system_clock::now().time_since_epoch())
      .count();
}

}  // namespace

int main(int argc, char** argv) {
  if (argc != 5) {
    std::fprintf(stderr, "usage: %s URL ROOM_KEY SKELETON.json KIND\n", argv[0]);
    return 2;
  }
  try {
    lcm::LCM lcm(argv[1]);
    if (!lcm.good()) throw InputError(std::string("cannot open ") + argv[1]);
    const MacKey room = LoadKeyFile(argv[2]);
    const Skeleton skeleton = LoadSkeletonFile(argv[3]);
    const std::string kind = argv[4];
    const BoxKeyPair pair = NewBoxKeyPair();
    Waiter waiter;
    lcm.subscribe(kJoinReplyChannel, &Waiter::On, &waiter);
    auto join = [&](const std::string& id, int64_t nonce,
                    const std::function<void(join_request_t*)>& spoil) -> join_reply_t {
      join_request_t j;
      j.utime = Now();
      j.client_id = id;
      j.nonce = nonce;
      std::copy(pair.public_key.begin(), pair.public_key.end(), j.public_key);
      j.motion = join_request_t::MOTION_ARTICULATED;
      j.eps_s = j.delta_m = 0;
      FillJoinSkeleton(skeleton, &j);
      j.num_ignore = 0;
      j.num_ignore_entities = 0;
      spoil(&j);
      const std::vector<uint8_t> bytes = EncodeSigned(j, &room);
      waiter.nonce = nonce;
      waiter.reply.reset();
      lcm.publish(kJoinChannel, bytes.data(), static_cast<unsigned>(bytes.size()));
      const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(5);
      while (!waiter.reply && std::chrono::steady_clock::now() < deadline) lcm.handleTimeout(100);
      if (!waiter.reply) throw InputError("no join reply within 5 s for '" + id + "'");
      return *waiter.reply;
    };
    int expected = -1;
    join_reply_t reply;
    const auto none = [](join_request_t*) {};
    if (kind == "bad_skeleton") {
      expected = join_reply_t::REASON_BAD_SKELETON;
      reply = join("bad_skel", 1, [](join_request_t* j) { j->parent[1] = -1; });
    } else if (kind == "too_many_links") {
      expected = join_reply_t::REASON_TOO_MANY_LINKS;
      reply = join("big", 2, [](join_request_t* j) {
        while (j->num_links < 300) {
          j->link_name.push_back("extra" + std::to_string(j->num_links));
          j->parent.push_back(0);
          j->a.push_back({0, 0, 0});
          j->b.push_back({0.1, 0, 0});
          j->radius.push_back(0.01);
          ++j->num_links;
        }
      });
    } else if (kind == "bad_filter") {
      expected = join_reply_t::REASON_BAD_FILTER;
      reply = join("filtered", 3, [](join_request_t* j) {
        j->num_ignore = 1;
        j->ignore = {"no_such_link:0"};
      });
    } else if (kind == "bad_options") {
      expected = join_reply_t::REASON_BAD_OPTIONS;
      reply = join("moving", 4, [](join_request_t* j) { j->motion = 9; });
    } else if (kind == "stale_request") {
      expected = join_reply_t::REASON_STALE_REQUEST;
      reply = join("late", 5, [](join_request_t* j) { j->utime -= 3'600'000'000; });
    } else if (kind == "too_many_clients") {
      expected = join_reply_t::REASON_TOO_MANY_CLIENTS;
      for (int i = 0;; ++i) {
        reply = join("fill" + std::to_string(i), 100 + i, none);
        if (reply.reason != join_reply_t::REASON_ACCEPTED || i > 4096) break;
      }
    } else {
      throw InputError("unknown KIND '" + kind + "'");
    }
    std::printf("%s: reason %d: %s\n", kind.c_str(), static_cast<int>(reply.reason),
                EscapeForDisplay(reply.message).c_str());
    return reply.reason == expected ? 0 : 1;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "join_tool: %s\n", e.what());
    return 2;
  }
}
