#pragma once
// The result records of SPEC section 7, one JSON object per pair.

#include <cstdint>
#include <optional>
#include <string>

#include "core/query/ccd_query.h"

namespace sweptccd {

/// The record for a queried pair (no trailing newline).
std::string ResultToJson(int64_t pair, int64_t utime0, int64_t utime1, const QueryResult& result,
                         bool per_link, double elapsed_us);

/// The record for an invalid pair, with the reason.
std::string InvalidResultToJson(int64_t pair, std::optional<int64_t> utime0,
                                std::optional<int64_t> utime1, const std::string& error);

}  // namespace sweptccd
