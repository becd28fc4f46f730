#pragma once
// The rounding slack of the certificate (SPEC 6), written once for every
// engine: how far the double-precision distances between geometry whose
// coordinates reach `scale` metres may be off, and the padding of the broad
// phases' boxes, which lies far above it.
//
// A float keeps 24 bits: rounding a coordinate x moves it by at most
// 2^-24 |x|, and a mesh parser can be off by about one float ulp more, so
// 2^-22 |x| covers two ulps with room for the rounding of the distance
// computations (below 1e-8 of |x|); 1 nm covers coordinates near 0.

#include <cmath>

namespace sweptccd {

/// `base` + 2^-22 `scale` + 1 nm, summed in that order (the bits every
/// engine has always computed). `base` is a slack already owed (a mesh's
/// own, or the other entity's).
inline double RoundingSlack(double scale, double base = 0.0) {
  return base + std::ldexp(scale, -22) + 1e-9;
}

/// The slack of an entity of a shared world whose samples and geometry
/// reach `scale`: 10 m of headroom over it (poses are composed from link
/// offsets, each adding its own rounding).
inline double EntitySlack(double scale, double base = 0.0) {
  return RoundingSlack(scale + 10.0, base);
}

/// The padding of a broad-phase box over geometry reaching `scale`: 1 um
/// and 2^-18 of the scale (with its 10 m headroom), far above the rounding
/// of the box's own arithmetic (~1e-15 m per metre) and 16 times the
/// descent's slack, so a box apart stays apart from everything the descent
/// tests.
inline double BoxPad(double scale) { return 1e-6 + std::ldexp(scale + 10.0, -18); }

}  // namespace sweptccd
