// The processor's cycle counter, for timing parts of a pass many times a
// step for the cost of one instruction rather than a call of the system's
// clock. Ticks, not seconds: the caller scales them by the rate it measures
// against the steady clock over a longer interval. On x86-64 the time-stamp
// counter (at a constant rate on the processors of the last fifteen years:
// the `constant_tsc` flag); elsewhere the steady clock's own count.
#pragma once

#include <chrono>
#include <cstdint>

#if defined(__x86_64__)
#include <x86intrin.h>
#endif

namespace talus {

inline std::uint64_t ticks() {
#if defined(__x86_64__)
    return __rdtsc();
#else
    return static_cast<std::uint64_t>(std::chrono::steady_clock::now().time_since_epoch().count());
#endif
}

// Ticks from a to b, 0 if the counter went back (a thread moved to a core
// whose counter is behind).
inline std::uint64_t ticks_between(std::uint64_t a, std::uint64_t b) { return b > a ? b - a : 0; }

} // namespace talus
