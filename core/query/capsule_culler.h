#pragma once
// The interface through which a query hands its swept-volume tests to an
// accelerator (the GPU backend, core/gpu/). Core code sees only this.

#include <cstdint>
#include <vector>

#include "core/query/link_capsule.h"

namespace sweptccd {

/// A conservative batched swept-volume test: for each capsule, does any
/// triangle of an object its link is not filtered from come within `radius`
/// of the segment a-b? Implementations must be thread-safe.
class CapsuleCuller {
 public:
  virtual ~CapsuleCuller() = default;

  /// Sets (*may_touch)[i] to 0 only when capsule i provably meets no
  /// unfiltered triangle, else 1. Returns false when it could not answer (the
  /// device is gone); the caller then decides everything itself.
  virtual bool Cull(const std::vector<LinkCapsule>& capsules,
                    std::vector<uint8_t>* may_touch) const = 0;
};

}  // namespace sweptccd
