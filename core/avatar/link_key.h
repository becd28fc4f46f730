#pragma once
// How a rule names a link of a skeleton: the one resolver of the collision
// filter (SPEC 5, `--ignore`), the world file's rules (SPEC 8 "Filters") and
// the daemon's `ignore_entities` (docs/SERVICE.md "Filters").

#include <cstdint>
#include <optional>
#include <string>

#include "core/typed_index.h"

namespace sweptccd {

class Skeleton;

/// A link key written as text: a link name first, then "*" (every link:
/// kAllLinks), then 1-9 decimal digits as an index below the link count.
/// So a link literally named "*" or "3" is that link, never all links or
/// link 3. Throws InputError "`where`: unknown link 'KEY' in skeleton 'NAME'
/// (N links; give a link name, an index below N or "*")".
LinkIndex ResolveLinkKey(const std::string& key, const Skeleton& skeleton,
                         const std::string& where);

/// A link key written as a JSON number: that index. Throws InputError
/// "`where`: link index I is out of range (skeleton 'NAME' has N links)"
/// unless 0 <= index < the link count.
LinkIndex ResolveLinkIndex(int64_t index, const Skeleton& skeleton, const std::string& where);

/// A link key with no skeleton to read names from (a live client to come):
/// "*" (kAllLinks) or 1-9 decimal digits (any index: its skeleton is not
/// known yet); nullopt for anything else, which would be a name.
std::optional<LinkIndex> LinkKeyWithoutNames(const std::string& key);

}  // namespace sweptccd
