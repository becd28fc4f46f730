#pragma once
// The interface through which a query hands its swept-volume tests to an
// accelerator (the GPU backend, core/gpu/). Core code sees only this.

#include <Eigen/Core>
#include <cstdint>
#include <vector>

namespace sweptccd {

/// One swept-volume test: does any triangle of an object the link is not
/// filtered from come within `radius` of the segment a-b?
struct CullCapsule {
  Eigen::Vector3d a{0, 0, 0}, b{0, 0, 0};  // World frame, metres.
  double radius = 0;                        // Metres.
  int link = 0;
};

/// A conservative batched test. Implementations must be thread-safe.
class CapsuleCuller {
 public:
  virtual ~CapsuleCuller() = default;

  /// Sets (*may_touch)[i] to 0 only when capsule i provably meets no
  /// unfiltered triangle, else 1. Returns false when it could not answer (the
  /// device is gone); the caller then decides everything itself.
  virtual bool Cull(const std::vector<CullCapsule>& capsules,
                    std::vector<uint8_t>* may_touch) const = 0;
};

}  // namespace sweptccd
