#pragma once
// An answered pair as a contact_event_t: the record of SPEC section 7
// (core/query/result_json.h, shared with `sweptccd query`) copied into the
// message's fields, so the service and the CLI report the same numbers.

#include <string>

#include "core/query/result_json.h"
#include "sweptccd/contact_event_t.hpp"

namespace sweptccd {

/// Sets the answer fields of `event` from `record`: result (free or
/// contact), initially_colliding, undecided, s_lo/s_hi, t_lo/t_hi, contacts,
/// links and their counts. The pair's bookkeeping (client_id, seq, pair,
/// utime0/1, timings) is left as it is. Never throws except std::bad_alloc.
void FillContactEvent(const ResultRecord& record, contact_event_t* event);

/// Marks `event` invalid with `error` and clears every answer field.
void MarkContactEventInvalid(const std::string& error, contact_event_t* event);

}  // namespace sweptccd
