#pragma once
// The result records of SPEC section 7: one answered pair with its brackets
// in microseconds (ResultRecord), built once by MakeResultRecord and written
// by every front end: `sweptccd query` as one JSON object per pair
// (RecordToJson), the collision service as a contact_event_t
// (service/contact_event.h).

#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "core/query/ccd_query.h"

namespace sweptccd {

/// One link's bracket with its times (per-link mode).
struct LinkRecord {
  LinkBracket bracket;
  double t_lo = 0;  // Microseconds, rounded down from bracket.s_lo (BracketTimeLo).
  double t_hi = 0;  // Microseconds, rounded up from bracket.s_hi (BracketTimeHi).
};

/// An answered (not invalid) pair as the records report it.
struct ResultRecord {
  int64_t pair = 0;
  int64_t utime0 = 0, utime1 = 0;  // Microseconds.
  bool contact = false;
  /// False whenever !contact, whatever the engine left there.
  bool initially_colliding = false;
  bool undecided = false;
  /// Normalised times and microseconds; 0 when !contact.
  double s_lo = 0, s_hi = 0, t_lo = 0, t_hi = 0;
  std::vector<ContactRecord> contacts;  // Empty when !contact.
  bool per_link = false;                // The query ran in per-link mode.
  std::vector<LinkRecord> links;        // Every bracket the engine reported, in its order.
  QueryStats stats;
};

/// The record of `result`, the answer for pair `pair` between poses stamped
/// utime0 < utime1. Pure; never throws except std::bad_alloc.
ResultRecord MakeResultRecord(int64_t pair, int64_t utime0, int64_t utime1,
                              const QueryResult& result, bool per_link);

/// The SPEC section 7 JSON object for `record` (no trailing newline). Doubles
/// are written in the shortest form that reads back exactly.
std::string RecordToJson(const ResultRecord& record, double elapsed_us);

/// RecordToJson(MakeResultRecord(...)): the record for a queried pair.
std::string ResultToJson(int64_t pair, int64_t utime0, int64_t utime1, const QueryResult& result,
                         bool per_link, double elapsed_us);

/// The record for an invalid pair, with the reason.
std::string InvalidResultToJson(int64_t pair, std::optional<int64_t> utime0,
                                std::optional<int64_t> utime1, const std::string& error);

}  // namespace sweptccd
