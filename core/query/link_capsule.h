#pragma once
// The one capsule type of the query: a bound on where one link can be over a
// time interval. The engine computes it (SweptBounds), tests triangles
// against it on the CPU, and hands it to an accelerator (CapsuleCuller).

#include <Eigen/Core>

#include "core/typed_index.h"

namespace sweptccd {

/// The segment a-b grown by `radius`: every point of `link` over the interval
/// it was computed for lies inside. Plain data.
struct LinkCapsule {
  Eigen::Vector3d a{0, 0, 0}, b{0, 0, 0};  // World frame, metres.
  double radius = 0;                        // Metres: link radius + motion + tolerance.
  LinkIndex link{0};
};

}  // namespace sweptccd
