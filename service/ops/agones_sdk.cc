#include "service/ops/agones_sdk.h"

#include <curl/curl.h>
#include <spdlog/spdlog.h>

#include <cstdlib>
#include <memory>

#include "core/errors.h"
#include "msgs/text.h"

namespace sweptccd {

namespace {

constexpr long kTimeoutMs = 1000;
constexpr size_t kMaxAnswerBytes = 1 << 20;

struct Answer {
  std::string body;
  bool too_long = false;
};

size_t Collect(char* data, size_t size, size_t n, void* user) {
  auto* a = static_cast<Answer*>(user);
  if (a->body.size() + size * n > kMaxAnswerBytes) {
    a->too_long = true;
    return 0;  // Aborts the transfer.
  }
  a->body.append(data, size * n);
  return size * n;
}

// One request; true on HTTP 200. `post_body` null: GET.
bool Request(const std::string& url, const char* post_body, Answer* answer) {
  static const bool initialised = curl_global_init(CURL_GLOBAL_DEFAULT) == 0;
  if (!initialised) return false;
  std::unique_ptr<CURL, decltype(&curl_easy_cleanup)> curl(curl_easy_init(), curl_easy_cleanup);
  if (!curl) return false;
  CURL* c = curl.get();
  curl_easy_setopt(c, CURLOPT_URL, url.c_str());
  curl_easy_setopt(c, CURLOPT_TIMEOUT_MS, kTimeoutMs);
  curl_easy_setopt(c, CURLOPT_NOSIGNAL, 1L);
  curl_easy_setopt(c, CURLOPT_PROTOCOLS_STR, "http");
  curl_easy_setopt(c, CURLOPT_NOPROXY, "*");  // The sidecar is on localhost.
  curl_easy_setopt(c, CURLOPT_WRITEFUNCTION, Collect);
  curl_easy_setopt(c, CURLOPT_WRITEDATA, answer);
  curl_slist* headers = nullptr;
  if (post_body) {
    headers = curl_slist_append(headers, "Content-Type: application/json");
    curl_easy_setopt(c, CURLOPT_HTTPHEADER, headers);
    curl_easy_setopt(c, CURLOPT_POSTFIELDS, post_body);
  }
  const CURLcode rc = curl_easy_perform(c);
  long status = 0;
  curl_easy_getinfo(c, CURLINFO_RESPONSE_CODE, &status);
  curl_slist_free_all(headers);
  if (rc != CURLE_OK) {
    spdlog::warn("agones: {}: {}", url,
                 answer->too_long ? "answer over 1 MiB" : curl_easy_strerror(rc));
    return false;
  }
  if (status != 200) {
    spdlog::warn("agones: {}: HTTP {}: {}", url, status, EscapeForDisplay(answer->body, 200));
    return false;
  }
  return true;
}

}  // namespace

std::string AgonesSdk::BaseUrlFromEnvironment() {
  const char* port = std::getenv("AGONES_SDK_HTTP_PORT");
  if (port == nullptr || *port == '\0') {
    throw InputError(
        "--agones: AGONES_SDK_HTTP_PORT is not set (Agones sets it in a GameServer's pod); "
        "run without --agones outside Agones");
  }
  const std::string p(port);
  if (p.size() > 5 || p.find_first_not_of("0123456789") != std::string::npos || std::stoi(p) < 1 ||
      std::stoi(p) > 65535) {
    throw InputError("--agones: AGONES_SDK_HTTP_PORT '" + EscapeForDisplay(p, 20) +
                     "' is not a port number");
  }
  return "http://localhost:" + p;
}

AgonesSdk::AgonesSdk(std::string base_url) : base_url_(std::move(base_url)) {}

bool AgonesSdk::Post(const char* path) {
  Answer answer;
  return Request(base_url_ + path, "{}", &answer);
}

std::string AgonesSdk::GetGameServer() {
  Answer answer;
  return Request(base_url_ + "/gameserver", nullptr, &answer) ? answer.body : std::string();
}

}  // namespace sweptccd
