#pragma once
// Error types and internal invariant checks.
//
// InputError is thrown for anything that comes from outside (files, flags,
// messages); its message names the place and the problem, ready to print.
// SWEPTCCD_CHECK guards internal invariants: a failure is a bug, so it aborts
// loudly with file, function and line.

#include <stdexcept>
#include <string>

namespace sweptccd {

class InputError : public std::runtime_error {
 public:
  explicit InputError(const std::string& message) : std::runtime_error(message) {}
};

namespace internal {
[[noreturn]] void CheckFailed(const char* condition, const char* file, int line,
                              const char* function);
}  // namespace internal

}  // namespace sweptccd

#define SWEPTCCD_CHECK(condition)                                                 \
  do {                                                                            \
    if (!(condition)) {                                                           \
      ::sweptccd::internal::CheckFailed(#condition, __FILE__, __LINE__, __func__); \
    }                                                                             \
  } while (false)
