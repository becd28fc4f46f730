#pragma once
// One rule for "the same record" in the core tests: every field of a query's
// record (SPEC section 7) but its statistics, bit for bit: the bracket, each
// witness, each link's bracket with its witness. For comparisons that must
// be exact (a backend against the CPU, q against -q, two engines).

#include <string>

#include "core/query/ccd_query.h"

namespace sweptccd::testing {

/// The first field in which two witnesses differ, or "" when none does.
inline std::string WitnessDifference(const ContactRecord& x, const ContactRecord& y) {
  if (x.link != y.link) return "link";
  if (x.object != y.object) return "object";
  if (x.triangle != y.triangle) return "triangle";
  if (x.s != y.s) return "s";
  if (x.point_link != y.point_link) return "point_link";
  if (x.point_env != y.point_env) return "point_env";
  if (x.normal != y.normal) return "normal";
  if (x.separation != y.separation) return "separation";
  return "";
}

/// Where two records first differ ("witness 2: normal"), or "" when they are
/// the same record.
inline std::string RecordDifference(const QueryResult& a, const QueryResult& b) {
  if (a.contact != b.contact) return "contact";
  if (a.undecided != b.undecided) return "undecided";
  if (a.initially_colliding != b.initially_colliding) return "initially_colliding";
  if (a.s_lo != b.s_lo) return "s_lo";
  if (a.s_hi != b.s_hi) return "s_hi";
  if (a.contacts.size() != b.contacts.size()) return "number of witnesses";
  if (a.links.size() != b.links.size()) return "number of link brackets";
  for (size_t i = 0; i < a.contacts.size(); ++i) {
    const std::string d = WitnessDifference(a.contacts[i], b.contacts[i]);
    if (!d.empty()) return "witness " + std::to_string(i) + ": " + d;
  }
  for (size_t i = 0; i < a.links.size(); ++i) {
    const LinkBracket &x = a.links[i], &y = b.links[i];
    const std::string at = "link bracket " + std::to_string(i) + ": ";
    if (x.link != y.link) return at + "link";
    if (x.s_lo != y.s_lo) return at + "s_lo";
    if (x.s_hi != y.s_hi) return at + "s_hi";
    if (x.undecided != y.undecided) return at + "undecided";
    if (x.initially_colliding != y.initially_colliding) return at + "initially_colliding";
    if (x.has_witness != y.has_witness) return at + "has_witness";
    const std::string d = WitnessDifference(x.witness, y.witness);
    if (!d.empty()) return at + "witness " + d;
  }
  return "";
}

}  // namespace sweptccd::testing
