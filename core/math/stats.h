// Small figures every benchmark and report shares: percentiles of a sample and the result hash.
#pragma once

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <vector>

#include "math/pose.h"

namespace godhand {

/// Linear-interpolated percentile p ∈ [0, 1] of v (0 for an empty sample).
inline double percentile(std::vector<double> v, double p) {
  if (v.empty()) return 0.0;
  std::sort(v.begin(), v.end());
  const double idx = p * static_cast<double>(v.size() - 1);
  const size_t lo = static_cast<size_t>(std::floor(idx)), hi = static_cast<size_t>(std::ceil(idx));
  return v[lo] + (v[hi] - v[lo]) * (idx - static_cast<double>(lo));
}

/// FNV-1a over the bit patterns of doubles: result_hash (same input ⇒ same hash), the check
/// that two runs (in-process and distributed, or two machines) computed the same poses.
struct ResultHash {
  std::uint64_t h = 1469598103934665603ull;
  void add(double x) {
    std::uint64_t bits;
    std::memcpy(&bits, &x, sizeof bits);
    for (int i = 0; i < 8; ++i) {
      h ^= (bits >> (8 * i)) & 0xffu;
      h *= 1099511628211ull;
    }
  }
  /// p (x, y, z) then q (w, x, y, z).
  void add(const Pose& X) {
    for (int i = 0; i < 3; ++i) add(X.p[i]);
    add(X.q.w()); add(X.q.x()); add(X.q.y()); add(X.q.z());
  }
};

}  // namespace godhand
