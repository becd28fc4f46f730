#pragma once
// How much of each long seeded suite to run. The main ctest runs every case
// (no variable, or SWEPTCCD_TEST_SCALE=1). The sanitizer build, where the
// engine runs 15 to 100 times slower, sets a fraction (tools/sanitize.sh):
// a randomized suite then runs the first ceil(n x fraction) of its seeds,
// and a real-data sweep every round(1 / fraction)-th pair, with its
// minimum-count checks scaled alike. The cases that run are the same cases
// as in the full run (same seeds, same pairs), so a finding replays there.

#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <string>

namespace sweptccd::testing {

/// SWEPTCCD_TEST_SCALE in (0, 1]; 1 when unset. A malformed value ends the
/// test binary with a message naming it (a typo must not run a tiny suite).
inline double TestScale() {
  static const double scale = [] {
    const char* text = std::getenv("SWEPTCCD_TEST_SCALE");
    if (text == nullptr || *text == '\0') return 1.0;
    char* end = nullptr;
    const double v = std::strtod(text, &end);
    if (end == text || *end != '\0' || !(v > 0.0) || v > 1.0) {
      std::fprintf(stderr, "SWEPTCCD_TEST_SCALE=\"%s\": want a number in (0, 1]\n", text);
      std::exit(2);
    }
    return v;
  }();
  return scale;
}

/// ceil(n x scale), at least 1: how many of n seeded cases to run.
inline int ScaledCount(int n) {
  const int k = static_cast<int>(std::ceil(n * TestScale()));
  return k < 1 ? 1 : k;
}

/// A minimum count of interesting cases (contacts, touching links...) for a
/// run at this scale: half the full run's minimum, scaled (a prefix of the
/// seeds may hold fewer of them than its share); n when the scale is 1.
inline int ScaledMinimum(int n) {
  return TestScale() == 1.0 ? n : static_cast<int>(n * TestScale() / 2);
}

/// The step between the pairs of a real-data sweep: round(1 / scale).
inline int ScaledStride() { return static_cast<int>(std::lround(1.0 / TestScale())); }

}  // namespace sweptccd::testing
