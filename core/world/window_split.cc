#include "core/world/window_split.h"

namespace sweptccd::world {

double Piece::SE(double tau) const {
  if (e_dur <= 0) return 0;
  return std::clamp((tau - e_tau0) / e_dur, 0.0, 1.0);
}

std::vector<Piece> SplitWindow(int64_t utime0, int64_t t_from, int64_t t_to,
                               const std::vector<int64_t>& samples) {
  return SplitWindow(utime0, t_from, t_to, samples.size(), [&](size_t k) { return samples[k]; });
}

std::optional<EntryWindow> WindowOf(int64_t utime0, int64_t utime1,
                                    const std::vector<int64_t>& samples) {
  return WindowOf(utime0, utime1, samples.size(), [&](size_t k) { return samples[k]; });
}

}  // namespace sweptccd::world
