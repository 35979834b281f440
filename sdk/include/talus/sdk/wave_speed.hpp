// talus/sdk/wave_speed.hpp -- the elastic wave speeds of a chunk of points,
// for a model's quick pass (material.hpp, Points).
//
// c = sqrt(M / rho) for a modulus M (the P-wave modulus K + 4G/3 for the
// fastest wave of an isotropic solid) and each point's density. Point by
// point, the division and the square root wait on each other, and GCC keeps
// std::sqrt's errno path (a compare, a branch and a call), so the loop does
// not vectorise without -fno-math-errno. Here four points share each
// division and square root where the processor has AVX (chosen at run
// time: a model is built for the baseline target), two elsewhere on
// x86-64. Both are correctly rounded IEEE operations in every form, so each
// point's bits are those of std::sqrt(M / rho).
//
// Four lanes rather than eight: a 512-bit division or square root takes
// twice the time of a 256-bit one (AMD Zen 4) or more (Intel), so eight
// lanes gain nothing over four, while on Zen 4 a 256-bit one takes the time
// of a 128-bit one: four lanes for the cost of two there
// (bench/results/2026-11-27-epyc-zen4-target-machine.md).
#pragma once

#include <cmath>
#include <cstddef>

#if defined(__SSE2__)
#include <emmintrin.h>
#endif

#include "detail/avx.hpp"

namespace talus::sdk {

namespace detail {

#if defined(TALUS_SDK_HAS_QUAD)
// Points [0, n - n % 4), four a vector; returns how many it did.
__attribute__((target("avx"))) inline std::size_t
wave_speeds_quad(double modulus, const double *density, double *c, std::size_t n) {
    const __m256d m = _mm256_set1_pd(modulus);
    std::size_t k = 0;
    for (; k + 3 < n; k += 4)
        _mm256_storeu_pd(c + k, _mm256_sqrt_pd(_mm256_div_pd(m, _mm256_loadu_pd(density + k))));
    return k;
}
#endif

} // namespace detail

// c[k] = sqrt(modulus / density[k]) for k < n.
inline void wave_speeds(double modulus, const double *density, double *c, std::size_t n) {
    std::size_t k = 0;
#if defined(TALUS_SDK_HAS_QUAD)
    if (detail::quad_enabled()) k = detail::wave_speeds_quad(modulus, density, c, n);
#endif
#if defined(__SSE2__)
    const __m128d m = _mm_set1_pd(modulus);
    for (; k + 1 < n; k += 2)
        _mm_storeu_pd(c + k, _mm_sqrt_pd(_mm_div_pd(m, _mm_loadu_pd(density + k))));
#endif
    for (; k < n; ++k)
        c[k] = std::sqrt(modulus / density[k]);
}

} // namespace talus::sdk
