#include "core/query/result_json.h"

#include <nlohmann/json.hpp>

namespace sweptccd {

namespace {

nlohmann::json Vec(const Eigen::Vector3d& v) { return {v.x(), v.y(), v.z()}; }

nlohmann::json ContactJson(const ContactRecord& c) {
  return {{"link", c.link.value()},
          {"object", c.object.value()},
          {"triangle", c.triangle},
          {"s", c.s},
          {"point_link", Vec(c.point_link)},
          {"point_env", Vec(c.point_env)},
          {"normal", Vec(c.normal)},
          {"separation", c.separation}};
}

// nlohmann's dump() writes doubles in the shortest form that reads back
// exactly, so the brackets keep every bit. t_lo rounds down and t_hi up.
}  // namespace

std::string ResultToJson(int64_t pair, int64_t utime0, int64_t utime1, const QueryResult& result,
                         bool per_link, double elapsed_us) {
  nlohmann::json j;
  j["pair"] = pair;
  j["utime0"] = utime0;
  j["utime1"] = utime1;
  j["result"] = result.contact ? "contact" : "free";
  if (result.contact) {
    j["initially_colliding"] = result.initially_colliding;
    j["undecided"] = result.undecided;
    j["s_lo"] = result.s_lo;
    j["s_hi"] = result.s_hi;
    j["t_lo"] = BracketTimeLo(utime0, utime1, result.s_lo);
    j["t_hi"] = BracketTimeHi(utime0, utime1, result.s_hi);
    nlohmann::json contacts = nlohmann::json::array();
    for (const ContactRecord& c : result.contacts) contacts.push_back(ContactJson(c));
    j["contacts"] = contacts;
  } else {
    j["initially_colliding"] = false;
    j["undecided"] = false;
  }
  if (per_link) {
    nlohmann::json links = nlohmann::json::array();
    for (const LinkBracket& b : result.links) {
      nlohmann::json e = {{"link", b.link.value()},
                          {"s_lo", b.s_lo},
                          {"s_hi", b.s_hi},
                          {"t_lo", BracketTimeLo(utime0, utime1, b.s_lo)},
                          {"t_hi", BracketTimeHi(utime0, utime1, b.s_hi)},
                          {"initially_colliding", b.initially_colliding},
                          {"undecided", b.undecided}};
      if (b.has_witness) e["contact"] = ContactJson(b.witness);
      links.push_back(e);
    }
    j["links"] = links;
  }
  j["elapsed_us"] = elapsed_us;
  j["stats"] = {{"links_tested", result.stats.links_tested},
                {"links_culled", result.stats.links_culled},
                {"intervals", result.stats.intervals},
                {"triangle_tests", result.stats.triangle_tests}};
  if (result.stats.cull_round_trips > 0) {  // The GPU backend's share.
    j["stats"]["gpu_round_trips"] = result.stats.cull_round_trips;
    j["stats"]["gpu_capsules"] = result.stats.cull_capsules;
    j["stats"]["gpu_cleared"] = result.stats.cull_cleared;
  }
  return j.dump();
}

std::string InvalidResultToJson(int64_t pair, std::optional<int64_t> utime0,
                                std::optional<int64_t> utime1, const std::string& error) {
  nlohmann::json j;
  j["pair"] = pair;
  if (utime0) j["utime0"] = *utime0;
  if (utime1) j["utime1"] = *utime1;
  j["result"] = "invalid";
  j["error"] = error;
  return j.dump(-1, ' ', false, nlohmann::json::error_handler_t::replace);
}

}  // namespace sweptccd
