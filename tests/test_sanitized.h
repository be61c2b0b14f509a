// The sanitizer build (deploy/run.sh test's second run: clang, -O1, ASan + UBSan, 15–40× slower
// here) checks memory and undefined behaviour, not statistics: the long randomised property
// tests run a fraction of their trials there, and all of them in the first (release) run of the
// same CI. Clang 14 does not define GCC's __SANITIZE_ADDRESS__ (the sweep tests' own check of it
// ran every motion under clang's ASan for a day: 160 of the sanitizer run's 930 test-seconds).
#pragma once

namespace godhand::test_support {

#if defined(__SANITIZE_ADDRESS__)
inline constexpr bool kSanitized = true;
#elif defined(__has_feature)
#if __has_feature(address_sanitizer)
inline constexpr bool kSanitized = true;
#else
inline constexpr bool kSanitized = false;
#endif
#else
inline constexpr bool kSanitized = false;
#endif

/// `n` trials in a plain build; n / divisor (at least 1) under the sanitizers.
constexpr int sanitizedTrials(int n, int divisor) { return kSanitized ? (n / divisor > 0 ? n / divisor : 1) : n; }

}  // namespace godhand::test_support
