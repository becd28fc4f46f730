#include "core/errors.h"

#include <cstdio>
#include <cstdlib>

namespace sweptccd {
namespace internal {

void CheckFailed(const char* condition, const char* file, int line, const char* function) {
  std::fprintf(stderr, "SweptCCD internal error: check '%s' failed in %s at %s:%d\n", condition,
               function, file, line);
  std::abort();
}

}  // namespace internal
}  // namespace sweptccd
