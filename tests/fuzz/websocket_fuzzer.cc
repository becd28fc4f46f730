// libFuzzer target: the WebSocket door's parsers of outside input
// (docs/WEBSOCKET.md). The first byte picks one:
//   even: a client message (DecodeClientMessage under the door's limits);
//     what decodes must encode (ToJson) and decode again to the same LCM
//     bytes.
//   odd: the HTTP request of a handshake, read by Beast's request parser
//     with the door's header limit (8 KiB), then the upgrade test and the
//     view file mapping of its target (path checks; no such folder, so no
//     file is touched).
#include <boost/beast/core.hpp>
#include <boost/beast/http.hpp>
#include <boost/beast/websocket.hpp>
#include <cstdint>
#include <cstdlib>
#include <vector>

#include "fuzz_input.h"
#include "service/ws/client_message.h"
#include "service/ws/lcm_json.h"
#include "service/ws/static_files.h"

namespace {

namespace beast = boost::beast;
namespace http = beast::http;
using namespace sweptccd;

template <class T>
std::vector<uint8_t> Lcm(const T& m) {
  std::vector<uint8_t> b(static_cast<size_t>(m.getEncodedSize()));
  m.encode(b.data(), 0, static_cast<int>(b.size()));
  return b;
}

void Message(const std::string& text) {
  WireLimits limits;
  limits.max_message_bytes = 256 * 1024;
  limits.max_links = 64;
  limits.max_join_links = 64;
  const ws::ClientDecodeResult r = ws::DecodeClientMessage(text, limits);
  if (!r.ok()) {
    if (r.code.empty() || r.problem.empty()) std::abort();
    return;
  }
  const ws::ClientMessage& m = *r.message;
  std::string again;
  switch (m.kind) {
    case ws::ClientMessage::Kind::kJoin:
      again = ws::ToJson(m.join, m.proof).dump();
      break;
    case ws::ClientMessage::Kind::kPose:
      again = ws::ToJson(m.pose).dump();
      break;
    case ws::ClientMessage::Kind::kLeave:
      again = ws::ToJson(m.leave).dump();
      break;
    case ws::ClientMessage::Kind::kObjectPose:
      again = ws::ToJson(m.object_pose).dump();
      break;
    default:
      return;
  }
  limits.max_message_bytes = 64 << 20;  // Re-encoding may add digits.
  const ws::ClientDecodeResult back = ws::DecodeClientMessage(again, limits);
  if (!back.ok()) std::abort();
  switch (m.kind) {
    case ws::ClientMessage::Kind::kJoin:
      if (Lcm(m.join) != Lcm(back.message->join)) std::abort();
      break;
    case ws::ClientMessage::Kind::kPose:
      if (Lcm(m.pose) != Lcm(back.message->pose)) std::abort();
      break;
    case ws::ClientMessage::Kind::kLeave:
      if (Lcm(m.leave) != Lcm(back.message->leave)) std::abort();
      break;
    default:
      if (Lcm(m.object_pose) != Lcm(back.message->object_pose)) std::abort();
  }
}

void Handshake(const std::string& bytes) {
  http::request_parser<http::empty_body> parser;
  parser.header_limit(8192);
  parser.eager(true);
  beast::error_code ec;
  parser.put(boost::asio::buffer(bytes), ec);
  if (ec || !parser.is_header_done()) return;
  const auto& req = parser.get();
  (void)beast::websocket::is_upgrade(req);
  (void)req[http::field::sec_websocket_protocol];
  (void)req[http::field::origin];
  const std::string target(req.target().data(), req.target().size());
  const auto file = ws::ResolveViewFile("/nonexistent-sweptccd-view", target);
  if (file) std::abort();  // No such folder: nothing may resolve.
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  if (size == 0) return 0;
  const std::string rest = sweptccd::fuzz::AsText(data + 1, size - 1);
  if (data[0] % 2 == 0) {
    Message(rest);
  } else {
    Handshake(rest);
  }
  return 0;
}
