// talus/sdk/wave_speed.hpp -- the elastic wave speeds of a chunk of points,
// for a model's quick pass (material.hpp, Points).
//
// c = sqrt(M / rho) for a modulus M (the P-wave modulus K + 4G/3 for the
// fastest wave of an isotropic solid) and each point's density. Point by
// point, the division and the square root wait on each other, and GCC keeps
// std::sqrt's errno path (a compare, a branch and a call), so the loop does
// not vectorise without -fno-math-errno; here two points share each
// division and square root. Both are correctly rounded IEEE operations in
// either form, so each point's bits are those of std::sqrt(M / rho).
#pragma once

#include <cmath>
#include <cstddef>

#if defined(__SSE2__)
#include <emmintrin.h>
#endif

namespace talus::sdk {

// c[k] = sqrt(modulus / density[k]) for k < n.
inline void wave_speeds(double modulus, const double *density, double *c, std::size_t n) {
    std::size_t k = 0;
#if defined(__SSE2__)
    const __m128d m = _mm_set1_pd(modulus);
    for (; k + 1 < n; k += 2)
        _mm_storeu_pd(c + k, _mm_sqrt_pd(_mm_div_pd(m, _mm_loadu_pd(density + k))));
#endif
    for (; k < n; ++k)
        c[k] = std::sqrt(modulus / density[k]);
}

} // namespace talus::sdk
