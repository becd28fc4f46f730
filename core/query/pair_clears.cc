#include "core/query/pair_clears.h"

#include <algorithm>
#include <bitset>
#include <cmath>

namespace sweptccd {

void PairClears::Reset(int num_links, int levels) {
  levels_ = std::clamp(levels, 0, kMaxLevels);
  words_.assign(static_cast<size_t>(std::max(0, num_links)), 0u);
}

void PairClears::Set(LinkIndex link, int depth, uint32_t k) {
  if (link < 0 || link >= num_links() || depth < 0 || depth >= levels_) return;
  if (k >= (1u << depth)) return;
  words_[link] |= 1u << ((1u << depth) - 1u + k);
}

void PairClears::SetWord(LinkIndex link, uint32_t word) {
  if (link < 0 || link >= num_links()) return;
  // Only bits of recorded depths.
  const uint32_t used = (1u << ((1u << levels_) - 1u)) - 1u;  // levels_ <= 5: bits 0..30.
  words_[link] = word & used;
}

bool PairClears::Cleared(LinkIndex link, int depth, double s0, double s1) const {
  if (link < 0 || link >= num_links() || depth < 0 || depth >= levels_) return false;
  const uint32_t word = words_[link];
  if (word == 0) return false;
  // k = s0 2^depth, exactly, and the interval must be [k, k + 1] 2^-depth.
  const double scaled = std::ldexp(s0, depth);
  if (!(scaled >= 0) || scaled >= static_cast<double>(1u << depth)) return false;
  const auto k = static_cast<uint32_t>(scaled);
  if (static_cast<double>(k) != scaled) return false;
  if (std::ldexp(static_cast<double>(k + 1), -depth) != s1) return false;
  return (word >> ((1u << depth) - 1u + k)) & 1u;
}

int64_t PairClears::count() const {
  int64_t n = 0;
  for (const uint32_t w : words_) n += static_cast<int64_t>(std::bitset<32>(w).count());
  return n;
}

}  // namespace sweptccd
