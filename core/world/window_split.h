#pragma once
// Internal to the entity engine (docs/DESIGN.md, section 5a): the one window
// rule of a shared-world entry. A's pair [utime0, utime1] meets entity E
// over the window [max(utime0, E's first sample), min(utime1, E's last)];
// the window is split at E's sample times into pieces, each with one motion
// of E. `sweptccd world` (WorldAnswerer) and the daemon (SharedWorld) both
// call these, over E's whole history or the live service's kept samples.
//
// Time runs as tau, microseconds since the pair's utime0 (exact for the
// integer utimes of every sample).

#include <algorithm>
#include <cstddef>
#include <cstdint>
#include <optional>
#include <vector>

namespace sweptccd::world {

/// One piece of the window: [tau0, tau1] in which E moves with one motion,
/// that of its samples k and k+1 (k+1 == k for an entity with one sample).
struct Piece {
  double tau0 = 0, tau1 = 0;
  int k = 0;
  double e_tau0 = 0;            // Sample k's time in tau.
  double e_dur = 0;             // Microseconds from sample k to k+1 (0: static).
  double SE(double tau) const;  // E's normalised time at tau, in [0, 1].
};

/// The window of one entry: its ends (utimes), its pieces (chronological,
/// contiguous, non-empty) and the samples they use, [first, last] (every
/// sample an answer reads: a live service holding only these, re-based so
/// that `first` is its sample 0, answers bit-equal).
struct EntryWindow {
  int64_t t_from = 0, t_to = 0;
  std::vector<Piece> pieces;
  size_t first = 0, last = 0;
};

/// Splits the window [t_from, t_to] (utimes, t_from <= t_to, inside both
/// the pair and [times(0), times(n - 1)]) at the sample times, into *out
/// (replaced; its capacity reused); `times(k)` is sample k's utime
/// (strictly increasing), n >= 1.
template <class Times>
void SplitWindowInto(int64_t utime0, int64_t t_from, int64_t t_to, size_t n, const Times& times,
                     std::vector<Piece>* out) {
  std::vector<Piece>& pieces = *out;
  pieces.clear();
  pieces.reserve(4);  // A pair's window meets a few of E's intervals.
  if (n == 1) {
    pieces.push_back({static_cast<double>(t_from - utime0), static_cast<double>(t_to - utime0), 0,
                      static_cast<double>(times(0) - utime0), 0});
    return;
  }
  // The first interval that can overlap: the last sample at or before
  // t_from (at most the last interval: a window that is the last sample's
  // instant). A binary search: the daemon's histories are long.
  size_t lo = 0, hi = n;
  while (lo < hi) {
    const size_t mid = lo + (hi - lo) / 2;
    if (times(mid) <= t_from) {
      lo = mid + 1;
    } else {
      hi = mid;
    }
  }
  const size_t first = std::min(lo == 0 ? 0 : lo - 1, n - 2);
  for (size_t k = first; k + 1 < n && times(k) <= t_to; ++k) {
    const int64_t from = std::max(t_from, times(k));
    const int64_t to = std::min(t_to, times(k + 1));
    if (from > to) continue;
    if (from == to && t_from < t_to) continue;  // A boundary instant of a longer window.
    pieces.push_back({static_cast<double>(from - utime0), static_cast<double>(to - utime0),
                      static_cast<int>(k), static_cast<double>(times(k) - utime0),
                      static_cast<double>(times(k + 1) - times(k))});
    if (t_from == t_to) break;
  }
}

/// The same, returned.
template <class Times>
std::vector<Piece> SplitWindow(int64_t utime0, int64_t t_from, int64_t t_to, size_t n,
                               const Times& times) {
  std::vector<Piece> pieces;
  SplitWindowInto(utime0, t_from, t_to, n, times, &pieces);
  return pieces;
}

/// The same over a vector of utimes.
std::vector<Piece> SplitWindow(int64_t utime0, int64_t t_from, int64_t t_to,
                               const std::vector<int64_t>& samples);

/// The window [t_from, t_to] (as SplitWindow's) with its pieces and the
/// samples they use, into *w.
template <class Times>
void FillWindow(int64_t utime0, int64_t t_from, int64_t t_to, size_t n, const Times& times,
                EntryWindow* w) {
  w->t_from = t_from;
  w->t_to = t_to;
  SplitWindowInto(utime0, t_from, t_to, n, times, &w->pieces);
  w->first = static_cast<size_t>(w->pieces.front().k);
  w->last = std::min(static_cast<size_t>(w->pieces.back().k) + 1, n - 1);
}

/// The same, returned.
template <class Times>
EntryWindow WindowOver(int64_t utime0, int64_t t_from, int64_t t_to, size_t n, const Times& times) {
  EntryWindow w;
  FillWindow(utime0, t_from, t_to, n, times, &w);
  return w;
}

/// The window of A's pair [utime0, utime1] over E's n samples (times as
/// above), into *w (its capacity reused): false, *w untouched, when E has
/// none or they do not overlap the pair (then there is no entry).
template <class Times>
bool WindowInto(int64_t utime0, int64_t utime1, size_t n, const Times& times, EntryWindow* w) {
  if (n == 0) return false;
  const int64_t t_from = std::max(utime0, times(0));
  const int64_t t_to = std::min(utime1, times(n - 1));
  if (t_from > t_to) return false;
  FillWindow(utime0, t_from, t_to, n, times, w);
  return true;
}

/// The same, returned: nullopt when there is no entry.
template <class Times>
std::optional<EntryWindow> WindowOf(int64_t utime0, int64_t utime1, size_t n, const Times& times) {
  std::optional<EntryWindow> w(std::in_place);  // Every return returns it (no copy).
  if (!WindowInto(utime0, utime1, n, times, &*w)) w.reset();
  return w;
}

/// The same over a vector of utimes.
std::optional<EntryWindow> WindowOf(int64_t utime0, int64_t utime1,
                                    const std::vector<int64_t>& samples);

}  // namespace sweptccd::world
