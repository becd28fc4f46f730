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

ResultRecord MakeResultRecord(int64_t pair, int64_t utime0, int64_t utime1,
                              const QueryResult& result, bool per_link) {
  ResultRecord r;
  r.pair = pair;
  r.utime0 = utime0;
  r.utime1 = utime1;
  r.contact = result.contact;
  if (result.contact) {
    r.initially_colliding = result.initially_colliding;
    r.undecided = result.undecided;
    r.s_lo = result.s_lo;
    r.s_hi = result.s_hi;
    r.t_lo = BracketTimeLo(utime0, utime1, result.s_lo);
    r.t_hi = BracketTimeHi(utime0, utime1, result.s_hi);
    r.contacts = result.contacts;
  }
  r.per_link = per_link;
  r.links.reserve(result.links.size());
  for (const LinkBracket& b : result.links) {
    r.links.push_back(LinkRecord{b, BracketTimeLo(utime0, utime1, b.s_lo),
                                 BracketTimeHi(utime0, utime1, b.s_hi)});
  }
  r.stats = result.stats;
  return r;
}

std::string RecordToJson(const ResultRecord& r, double elapsed_us) {
  nlohmann::json j;
  j["pair"] = r.pair;
  j["utime0"] = r.utime0;
  j["utime1"] = r.utime1;
  j["result"] = r.contact ? "contact" : "free";
  j["initially_colliding"] = r.initially_colliding;
  j["undecided"] = r.undecided;
  if (r.contact) {
    j["s_lo"] = r.s_lo;
    j["s_hi"] = r.s_hi;
    j["t_lo"] = r.t_lo;
    j["t_hi"] = r.t_hi;
    nlohmann::json contacts = nlohmann::json::array();
    for (const ContactRecord& c : r.contacts) contacts.push_back(ContactJson(c));
    j["contacts"] = contacts;
  }
  if (r.per_link) {
    nlohmann::json links = nlohmann::json::array();
    for (const LinkRecord& l : r.links) {
      const LinkBracket& b = l.bracket;
      nlohmann::json e = {{"link", b.link.value()},
                          {"s_lo", b.s_lo},
                          {"s_hi", b.s_hi},
                          {"t_lo", l.t_lo},
                          {"t_hi", l.t_hi},
                          {"initially_colliding", b.initially_colliding},
                          {"undecided", b.undecided}};
      if (b.has_witness) e["contact"] = ContactJson(b.witness);
      links.push_back(e);
    }
    j["links"] = links;
  }
  j["elapsed_us"] = elapsed_us;
  j["stats"] = {{"links_tested", r.stats.links_tested},
                {"links_culled", r.stats.links_culled},
                {"intervals", r.stats.intervals},
                {"triangle_tests", r.stats.triangle_tests}};
  if (r.stats.cull_round_trips > 0) {  // The GPU backend's share.
    j["stats"]["gpu_round_trips"] = r.stats.cull_round_trips;
    j["stats"]["gpu_capsules"] = r.stats.cull_capsules;
    j["stats"]["gpu_cleared"] = r.stats.cull_cleared;
  }
  return j.dump();
}

std::string ResultToJson(int64_t pair, int64_t utime0, int64_t utime1, const QueryResult& result,
                         bool per_link, double elapsed_us) {
  return RecordToJson(MakeResultRecord(pair, utime0, utime1, result, per_link), elapsed_us);
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
