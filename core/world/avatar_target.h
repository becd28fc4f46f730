#pragma once
// Internal to the entity engine (docs/DESIGN.md, section 5a): another avatar
// as an OtherTarget (its links are the candidates), beside core/query's
// EnvironmentTarget.

#include <memory>

#include "core/world/entity_window.h"
#include "core/world/interval_motions.h"
#include "core/world/other_target.h"

namespace sweptccd::world {

/// A's links (who: `a`) against avatar `b`. `scale` is WindowScale or
/// EntityScale of b (< 0: EntityScale, computed here, O(samples)). B's
/// motions come from `motions` when given (over b), else are kept here.
std::unique_ptr<OtherTarget> MakeAvatarTarget(const FilterSide& a, const AvatarWindow& b,
                                              double scale = -1,
                                              IntervalMotions* motions = nullptr);

}  // namespace sweptccd::world
