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

/// The values of one figure over a run, in bounded memory: every value up to `capacity`, then a
/// uniform sample of `capacity` of them (reservoir sampling with a fixed seed: the same run keeps
/// the same sample). count() and max() stay exact; percentiles of values() are exact while
/// count() <= capacity and estimates after (sampled()). A benchmark's figures (thousands of
/// values) are exact; a lab left running for a day holds capacity × 8 bytes per figure instead of
/// growing by every frame (39 MB an hour in a soak).
class Sample {
 public:
  static constexpr std::size_t kDefaultCapacity = std::size_t{1} << 18;  // 2 MB of doubles
  explicit Sample(std::size_t capacity = kDefaultCapacity) : capacity_(capacity < 1 ? 1 : capacity) {}
  void add(double x) {
    ++count_;
    if (count_ == 1 || x > max_) max_ = x;
    if (v_.size() < capacity_) {
      v_.push_back(x);
      return;
    }
    // Algorithm R: the n-th value replaces a kept one with probability capacity / n.
    const std::uint64_t j = next() % count_;
    if (j < capacity_) v_[static_cast<size_t>(j)] = x;
  }
  const std::vector<double>& values() const { return v_; }
  std::uint64_t count() const { return count_; }
  bool empty() const { return count_ == 0; }
  bool sampled() const { return count_ > v_.size(); }
  double max() const { return max_; }  ///< 0 for none
  void clear() {
    v_.clear();
    count_ = 0;
    max_ = 0.0;
  }

 private:
  std::uint64_t next() {  // xorshift64*
    rng_ ^= rng_ >> 12;
    rng_ ^= rng_ << 25;
    rng_ ^= rng_ >> 27;
    return rng_ * 2685821657736338717ull;
  }
  std::size_t capacity_;
  std::vector<double> v_;
  std::uint64_t count_ = 0;
  double max_ = 0.0;
  std::uint64_t rng_ = 0x9E3779B97F4A7C15ull;
};

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
