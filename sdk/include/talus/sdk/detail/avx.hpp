// talus/sdk/detail/avx.hpp -- whether the SDK's chunk helpers (wave_speed.hpp,
// hooke.hpp) take their AVX forms. A model is built for the baseline
// x86-64 target, so the wider form is chosen at run time, once.
#pragma once

#if defined(__x86_64__) && (defined(__GNUC__) || defined(__clang__))
#define TALUS_SDK_HAS_QUAD 1
#include <immintrin.h>
#endif

namespace talus::sdk::detail {

// Read once; a test may turn it off to compare the forms.
inline bool &quad_enabled() {
#if defined(TALUS_SDK_HAS_QUAD)
    static bool on = [] {
        __builtin_cpu_init();
        return __builtin_cpu_supports("avx") != 0;
    }();
#else
    static bool on = false;
#endif
    return on;
}

} // namespace talus::sdk::detail
