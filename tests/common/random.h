#pragma once
// Seeded random generators shared by the core tests (geometry code is tested
// with seeded randomness only: the same seed gives the same cases).

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <cstdint>
#include <random>

namespace sweptccd::testing {

struct Rng {
  explicit Rng(uint64_t seed) : g(seed) {}
  std::mt19937_64 g;
  double U(double lo, double hi) { return std::uniform_real_distribution<double>(lo, hi)(g); }
  int I(int n) { return static_cast<int>(g() % static_cast<uint64_t>(n)); }
  bool P(double p) { return U(0, 1) < p; }
  double N() { return std::normal_distribution<double>()(g); }
  Eigen::Vector3d Box(double h) { return Eigen::Vector3d(U(-h, h), U(-h, h), U(-h, h)); }
  /// A uniformly distributed unit vector.
  Eigen::Vector3d Dir() {
    Eigen::Vector3d v(N(), N(), N());
    return v.normalized();
  }
  Eigen::Quaterniond Quat() {
    Eigen::Quaterniond q(N(), N(), N(), N());
    return q.normalized();
  }
  Eigen::Quaterniond Turn(double angle) {
    return Eigen::Quaterniond(Eigen::AngleAxisd(angle, Dir()));
  }
  /// A random unit vector perpendicular to d (unit).
  Eigen::Vector3d Perp(const Eigen::Vector3d& d) {
    for (;;) {
      Eigen::Vector3d v = Dir();
      v -= v.dot(d) * d;
      if (v.norm() > 0.1) return v.normalized();
    }
  }
};

}  // namespace sweptccd::testing
