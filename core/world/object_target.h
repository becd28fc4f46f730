#pragma once
// Internal to the entity engine (docs/DESIGN.md, section 5a): a tracked
// object as an OtherTarget (one candidate, 0; its triangles from its BVH in
// its own frame), beside core/query's EnvironmentTarget.

#include <memory>

#include "core/world/entity_window.h"
#include "core/world/other_target.h"

namespace sweptccd::world {

/// A's links (who: `a`) against object `o`. `scale` is WindowScale or
/// EntityScale of o (< 0: EntityScale, computed here, O(samples)).
/// Its near box (OtherTarget::NearLinkBoxes) over a piece is its
/// ObjectMotionBox over the piece's interval grown by the margin.
std::unique_ptr<OtherTarget> MakeObjectTarget(const FilterSide& a, const ObjectWindow& o,
                                              double scale = -1);

}  // namespace sweptccd::world
