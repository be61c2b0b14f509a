// The tests' random instances: one generator (std::mt19937_64) and one way of drawing each kind of
// value, shared by the test and benchmark files that used to carry a copy each. Every draw is
// sequenced left to right (one statement per coordinate), so a seed gives the same instances
// with every compiler (function arguments are evaluated in an unspecified order).
#pragma once

#include <random>

#include "math/pose.h"

namespace godhand::test_support {

struct Rng {
  std::mt19937_64 gen;
  explicit Rng(unsigned seed) : gen(seed) {}
  double uniform(double lo, double hi) { return std::uniform_real_distribution<double>(lo, hi)(gen); }
  int integer(int lo, int hi) { return std::uniform_int_distribution<int>(lo, hi)(gen); }
  /// Uniform in the cube [−half, half]³.
  Vec3 vec(double half) {
    const double x = uniform(-half, half);
    const double y = uniform(-half, half);
    const double z = uniform(-half, half);
    return Vec3(x, y, z);
  }
  /// Uniform in an axis-aligned box (anything with lo and hi corners).
  template <class Box>
  Vec3 inBox(const Box& b) {
    const double x = uniform(b.lo.x(), b.hi.x());
    const double y = uniform(b.lo.y(), b.hi.y());
    const double z = uniform(b.lo.z(), b.hi.z());
    return Vec3(x, y, z);
  }
  /// Uniform on the unit sphere.
  Vec3 direction() {
    std::normal_distribution<double> n(0.0, 1.0);
    const double x = n(gen);
    const double y = n(gen);
    const double z = n(gen);
    return Vec3(x, y, z).normalized();
  }
  /// Uniform over the rotations.
  Quat rotation() {
    std::normal_distribution<double> n(0.0, 1.0);
    const double w = n(gen);
    const double x = n(gen);
    const double y = n(gen);
    const double z = n(gen);
    return Quat(w, x, y, z).normalized();
  }
};

}  // namespace godhand::test_support
