#include "service/ops/metrics_server.h"

#include <poll.h>
#include <spdlog/spdlog.h>
#include <sys/socket.h>
#include <sys/time.h>

#include <atomic>
#include <boost/asio.hpp>
#include <boost/beast/core.hpp>
#include <boost/beast/http.hpp>
#include <thread>

#include "core/errors.h"
#include "msgs/text.h"
#include "service/ops/prometheus_text.h"

namespace sweptccd {

namespace beast = boost::beast;
namespace http = beast::http;
namespace net = boost::asio;
using tcp = net::ip::tcp;

namespace {

constexpr int kRequestBudgetMs = 2000;
constexpr uint32_t kMaxHeadBytes = 8192;

bool SplitHostPort(const std::string& listen, std::string* host, std::string* port) {
  const size_t colon = listen.rfind(':');
  if (colon == std::string::npos || colon == 0 || colon + 1 == listen.size()) return false;
  *host = listen.substr(0, colon);
  if (host->size() > 2 && host->front() == '[' && host->back() == ']') {
    *host = host->substr(1, host->size() - 2);
  }
  *port = listen.substr(colon + 1);
  return true;
}

}  // namespace

struct MetricsServer::Impl {
  net::io_context io;
  tcp::acceptor acceptor{io};
  std::function<std::string()> render;
  std::thread thread;
  std::atomic<bool> stopping{false};

  void Serve(tcp::socket socket) {
    // The request's whole budget as socket timeouts: a slow client is cut.
    timeval tv{kRequestBudgetMs / 1000, (kRequestBudgetMs % 1000) * 1000};
    setsockopt(socket.native_handle(), SOL_SOCKET, SO_RCVTIMEO, &tv, sizeof(tv));
    setsockopt(socket.native_handle(), SOL_SOCKET, SO_SNDTIMEO, &tv, sizeof(tv));
    beast::flat_buffer buffer(kMaxHeadBytes);
    http::request_parser<http::empty_body> parser;
    parser.header_limit(kMaxHeadBytes);
    parser.body_limit(0);
    beast::error_code ec;
    http::read(socket, buffer, parser, ec);
    if (ec) return;  // Malformed, too large or too slow: closed unanswered.
    const auto& req = parser.get();
    http::response<http::string_body> res;
    res.version(11);
    res.keep_alive(false);
    res.set(http::field::server, "sweptccd-metrics");
    const std::string target(req.target());
    if (target != "/metrics") {
      res.result(http::status::not_found);
      res.set(http::field::content_type, "text/plain");
      res.body() = "only /metrics is here\n";
    } else if (req.method() != http::verb::get && req.method() != http::verb::head) {
      res.result(http::status::method_not_allowed);
      res.set(http::field::allow, "GET, HEAD");
      res.set(http::field::content_type, "text/plain");
      res.body() = "use GET\n";
    } else {
      res.result(http::status::ok);
      res.set(http::field::content_type, kPrometheusContentType);
      res.body() = render();
      if (req.method() == http::verb::head) {
        res.prepare_payload();
        http::response_serializer<http::string_body> sr(res);
        http::write_header(socket, sr, ec);
        return;
      }
    }
    res.prepare_payload();
    http::write(socket, res, ec);
    socket.shutdown(tcp::socket::shutdown_both, ec);
  }

  void Run() {
    while (!stopping.load()) {
      pollfd fd{acceptor.native_handle(), POLLIN, 0};
      if (poll(&fd, 1, 200) <= 0) continue;
      beast::error_code ec;
      tcp::socket socket(io);
      acceptor.accept(socket, ec);
      if (ec) continue;
      try {
        Serve(std::move(socket));
      } catch (const std::exception& e) {
        spdlog::warn("metrics request: {}", EscapeForDisplay(e.what(), 200));
      }
    }
  }
};

MetricsServer::MetricsServer(const std::string& listen, std::function<std::string()> render)
    : impl_(std::make_unique<Impl>()) {
  impl_->render = std::move(render);
  std::string host, port;
  if (!SplitHostPort(listen, &host, &port)) {
    throw InputError("metrics.listen '" + EscapeForDisplay(listen) + "': give HOST:PORT");
  }
  try {
    tcp::resolver resolver(impl_->io);
    const auto results = resolver.resolve(host, port, tcp::resolver::numeric_service);
    const tcp::endpoint endpoint = *results.begin();
    impl_->acceptor.open(endpoint.protocol());
    impl_->acceptor.set_option(net::socket_base::reuse_address(true));
    impl_->acceptor.bind(endpoint);
    impl_->acceptor.listen(16);
  } catch (const std::exception& e) {
    throw InputError("metrics.listen '" + EscapeForDisplay(listen) + "': " + e.what());
  }
  spdlog::info("metrics: http://{}/metrics", listen);
}

MetricsServer::~MetricsServer() { Stop(); }

void MetricsServer::Start() {
  impl_->thread = std::thread([impl = impl_.get()] { impl->Run(); });
}

void MetricsServer::Stop() {
  impl_->stopping = true;
  if (impl_->thread.joinable()) impl_->thread.join();
}

int MetricsServer::port() const { return impl_->acceptor.local_endpoint().port(); }

}  // namespace sweptccd
