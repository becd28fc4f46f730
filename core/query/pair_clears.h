#pragma once
// The intervals of one pair's dyadic time-slicing tree that an accelerator
// proved free before the descent (the device descent, docs/GPU.md, "The
// free part of the descent on the device"). The query skips them: each is
// an interval its own exact test would clear, so the descent takes the same
// path and gives the same answer. Plain values; thread-compatible.

#include <cstdint>
#include <vector>

#include "core/typed_index.h"

namespace sweptccd {

class PairClears {
 public:
  /// The deepest tree recorded: depths 0 .. kMaxLevels - 1 (31 intervals per
  /// link, one 32-bit word).
  static constexpr int kMaxLevels = 5;

  /// Nothing cleared, for `num_links` links and depths below `levels`.
  void Reset(int num_links, int levels);
  /// Marks interval k (of 2^depth) of `link` cleared; out of range: ignored.
  void Set(LinkIndex link, int depth, uint32_t k);
  /// The link's bits as a word: bit 2^depth - 1 + k.
  void SetWord(LinkIndex link, uint32_t word);

  /// Whether [s0, s1] of `link`, at `depth` of the tree, was cleared. Only a
  /// dyadic interval [k 2^-depth, (k + 1) 2^-depth] can be (checked exactly).
  bool Cleared(LinkIndex link, int depth, double s0, double s1) const;

  int levels() const { return levels_; }
  int num_links() const { return static_cast<int>(words_.size()); }
  /// Intervals marked, all links.
  int64_t count() const;

 private:
  int levels_ = 0;
  std::vector<uint32_t> words_;  // Per link.
};

}  // namespace sweptccd
