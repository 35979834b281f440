// The SDK chunk helpers' tests: each runs with the AVX form as the processor
// allows it and without it, so that both forms are checked on a machine
// that has AVX.
#pragma once

#include <talus/sdk/detail/avx.hpp>

#include <gtest/gtest.h>

#include <bit>
#include <cstdint>

namespace talus::sdk::test {

// The bits of x: NaN compares equal to a NaN of the same payload.
inline std::uint64_t bits(double x) { return std::bit_cast<std::uint64_t>(x); }

// Runs f once with the AVX form (named `wide` in the trace) as the processor
// allows it, and once without it (`narrow`), restoring the setting.
template <class F>
void with_each_form(const char *wide, const char *narrow, F &&f) {
    bool &quad = talus::sdk::detail::quad_enabled();
    const bool saved = quad;
    for (const bool on : {saved, false}) {
        quad = on;
        SCOPED_TRACE(on ? wide : narrow);
        f();
    }
    quad = saved;
}

} // namespace talus::sdk::test
