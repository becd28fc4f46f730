// Fuzzes ParseSkeletonJson (SPEC section 1): a skeleton, or InputError.

#include <cstddef>
#include <cstdint>

#include "core/avatar/skeleton.h"
#include "core/errors.h"
#include "tests/fuzz/fuzz_input.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  try {
    const sweptccd::Skeleton skeleton =
        sweptccd::ParseSkeletonJson(sweptccd::fuzz::AsText(data, size), "fuzz");
    // What a parsed skeleton promises: it serialises and reads back.
    sweptccd::ParseSkeletonJson(sweptccd::SkeletonToJson(skeleton), "fuzz round trip");
  } catch (const sweptccd::InputError&) {
  }
  return 0;
}
