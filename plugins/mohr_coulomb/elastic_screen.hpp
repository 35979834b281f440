// The elastic screen of Mohr-Coulomb's quick pass: the trial stress of an
// increment and whether it lies clearly inside the yield surface, for one
// point (double) or four at once (a 256-bit vector of doubles, one point a
// lane).
//
// Both forms are the same template, so a point gets the same operations in
// the same order whichever form screened it: its trial stress and its
// verdict are the same bits (IEEE additions and multiplications are
// correctly rounded lane by lane; nothing here may be fused into a
// multiply-add: the vector form's target, AVX2, has no FMA, and the plugin
// is compiled with -ffp-contract=off for builds whose own target has it,
// such as -march=native: CMakeLists.txt). That
// keeps a point's result independent of its neighbours in the batch, which
// decide which form it meets (tests/unit/plugins/test_mohr_coulomb.cpp).
//
// The scalar screen with its early returns takes a mispredicted branch on
// most plastic points of a mixed block, whose yielding points are scattered
// through it (bench/results/2026-11-27-mohr-coulomb-screen-epyc-zen4.md);
// the four-lane form has no branch per point and shares each operation
// among four points.
#pragma once

#include "principal_return.hpp"

#include <cstddef>
#include <cstdint>
#include <cstring>

#if defined(__x86_64__) && (defined(__GNUC__) || defined(__clang__))
#define TALUS_MC_HAS_QUAD_SCREEN 1
#include <immintrin.h>
#endif

namespace talus_mc {

#if defined(__GNUC__) || defined(__clang__)
#define TALUS_MC_SCREEN_INLINE [[gnu::always_inline]] inline
#else
#define TALUS_MC_SCREEN_INLINE inline
#endif

// The elastic constants the screen needs.
struct ScreenElastic {
    double lambda = 0.0;
    double moduli[6] = {}; // 2G on the normal components, G on the (engineering) shear ones
    double normal[6] = {}; // 1 on the normal components
};

// t = s0 + lambda tr(de) 1 + 2 G de (engineering shear: G on the shear
// components), component by component in the order the model's hooke()
// evaluates it: s0_i + (de_i m_i + (lambda tr) n_i). The product with n_i = 0
// is kept: it makes a -0 shear increment +0, as there.
template <class T>
TALUS_MC_SCREEN_INLINE void trial_stress(const ScreenElastic &el, const T s0[6], const T de[6],
                                         T t[6]) {
    const T lt = el.lambda * (de[0] + de[1] + de[2]);
    for (int i = 0; i < 6; ++i)
        t[i] = s0[i] + (de[i] * el.moduli[i] + lt * el.normal[i]);
}

// Whether the trial stress t is inside the surface by more than the return's
// tolerance, decided from the invariants without eigenvalues (most points'
// case; the decomposition costs more than the rest of an elastic step). With
// p the mean stress, J2 the second deviatoric invariant, q = sqrt(J2) and
// theta the Lode angle, s1 - s3 = 2 q cos(theta) and s2 - p = 2 q sin(theta)
// / sqrt(3), so (1 + sin phi) s1 - (1 - sin phi) s3 = 2 p sin phi + 2 q
// (cos(theta) - sin(phi) sin(theta) / sqrt(3)) <= 2 p sin phi + 2 q b, b =
// sqrt(1 + sin^2(phi) / 3), and s1 <= p + 2 q / sqrt(3). The test asks both
// bounds to stay below the surface by twice the return's tolerance
// (rounding here is ~1e-15 of the stress, the tolerance 1e-10): the exact
// test then finds the point inside and off the surface, and the result is
// the full path's, bit for bit. Without square root: with R = c cos phi - p
// sin phi, the shear bound is q b < R - tol / 2, where the tolerance 2e-10
// max(|p| + 2 q / sqrt(3), c) is taken at q = R / b, which it exceeds
// whenever the test passes; both sides are then squared.
// `bound`: b (lode_bound), `inv_bound` its inverse. Every part is evaluated
// and the verdicts combined without a branch; a lane whose R is not
// positive (or NaN) fails the first part whatever the others give.
// The verdict: a bool for double, a lane mask (all ones where clearly
// elastic) for a vector; an out-parameter, not a return value, so that the
// vector form passes no vector by value outside AVX code.
template <class T, class Verdict>
TALUS_MC_SCREEN_INLINE void clearly_elastic(const T t[6], const Strength &st, double bound,
                                            double inv_bound, Verdict &verdict) {
    constexpr double k = 1.1547005383792515; // 2 / sqrt(3)
    const T p = (t[0] + t[1] + t[2]) * (1.0 / 3.0);
    const T J2 = ((t[0] - t[1]) * (t[0] - t[1]) + (t[1] - t[2]) * (t[1] - t[2]) +
                  (t[2] - t[0]) * (t[2] - t[0])) *
                     (1.0 / 6.0) +
                 t[3] * t[3] + t[4] * t[4] + t[5] * t[5];
    const T R = st.cohesion * st.cos_phi - p * st.sin_phi;
    // max(|p| + k R / b, c, 1e-300), as std::max picks (the first unless a
    // later one is larger). |p| by a comparison: -0 stays -0, which changes
    // nothing once added to k R / b >= 0 (R > 0 wherever the verdict can
    // pass).
    const T a = (p < 0.0 ? -p : p) + k * R * inv_bound;
    const T ac = a < st.cohesion ? T{} + st.cohesion : a;
    const T tol = 2e-10 * (ac < 1e-300 ? T{} + 1e-300 : ac);
    const T shear = R - 0.5 * tol;
    verdict = (R > 0.0) & (shear > 0.0) & (J2 * bound * bound < shear * shear);
    if (!st.tension_active) return;
    const T tension = st.tension - tol - p; // s1 <= p + k q < T - tol
    verdict = verdict & (tension > 0.0) & (k * k * J2 < tension * tension);
}

#if defined(TALUS_MC_HAS_QUAD_SCREEN)
namespace quad {

using Lanes = double __attribute__((vector_size(32)));

// Four rows of four (a point's components a..a+3 each) as four columns (a
// component's four points each), and back: the same network both ways.
__attribute__((target("avx2"), always_inline)) inline void transpose4(__m256d r[4]) {
    const __m256d u0 = _mm256_unpacklo_pd(r[0], r[1]), u1 = _mm256_unpackhi_pd(r[0], r[1]);
    const __m256d u2 = _mm256_unpacklo_pd(r[2], r[3]), u3 = _mm256_unpackhi_pd(r[2], r[3]);
    r[0] = _mm256_permute2f128_pd(u0, u2, 0x20);
    r[1] = _mm256_permute2f128_pd(u1, u3, 0x20);
    r[2] = _mm256_permute2f128_pd(u0, u2, 0x31);
    r[3] = _mm256_permute2f128_pd(u1, u3, 0x31);
}

// Four points' six components (a stride of 6 doubles) as six columns.
__attribute__((target("avx2"), always_inline)) inline void load6(const double *a, Lanes c[6]) {
    __m256d r[4];
    for (int j = 0; j < 4; ++j)
        r[j] = _mm256_loadu_pd(a + 6 * j);
    transpose4(r);
    for (int i = 0; i < 4; ++i)
        c[i] = (Lanes)r[i];
    // Components 4 and 5: points 0 and 2 in the one vector, 1 and 3 in the
    // other, then paired by unpacking.
    const __m256d e02 =
        _mm256_insertf128_pd(_mm256_castpd128_pd256(_mm_loadu_pd(a + 4)), _mm_loadu_pd(a + 16), 1);
    const __m256d e13 =
        _mm256_insertf128_pd(_mm256_castpd128_pd256(_mm_loadu_pd(a + 10)), _mm_loadu_pd(a + 22), 1);
    c[4] = (Lanes)_mm256_unpacklo_pd(e02, e13);
    c[5] = (Lanes)_mm256_unpackhi_pd(e02, e13);
}

// load6's inverse.
__attribute__((target("avx2"), always_inline)) inline void store6(double *a, const Lanes c[6]) {
    __m256d r[4] = {(__m256d)c[0], (__m256d)c[1], (__m256d)c[2], (__m256d)c[3]};
    transpose4(r);
    for (int j = 0; j < 4; ++j)
        _mm256_storeu_pd(a + 6 * j, r[j]);
    const __m256d e02 = _mm256_unpacklo_pd((__m256d)c[4], (__m256d)c[5]);
    const __m256d e13 = _mm256_unpackhi_pd((__m256d)c[4], (__m256d)c[5]);
    _mm_storeu_pd(a + 4, _mm256_castpd256_pd128(e02));
    _mm_storeu_pd(a + 16, _mm256_extractf128_pd(e02, 1));
    _mm_storeu_pd(a + 10, _mm256_castpd256_pd128(e13));
    _mm_storeu_pd(a + 22, _mm256_extractf128_pd(e13, 1));
}

// The quick pass's screen four points a vector over points [0, n - n % 4)
// of a chunk (arrays as in talus::sdk::Points; `state` values a point,
// yield_mode at index 2), for a strength without softening. A point found
// clearly elastic gets its trial stress in stress_end, yield_mode 0 and
// done = 1; the others keep their yield_mode (state_end may be state_start)
// and, where stress_end is stress_start, their stress; where it is not,
// they get the trial stress there too. Returns how many points it screened.
__attribute__((target("avx2"))) inline std::size_t
screen_quads(const ScreenElastic &el, const Strength &st, double bound, double inv_bound,
             std::size_t n, const double *stress_start, const double *strain_increment,
             double *stress_end, double *state_end, std::size_t state, std::uint8_t *done) {
    std::size_t k = 0;
    for (; k + 3 < n; k += 4) {
        Lanes s0[6], de[6], t[6];
        load6(stress_start + 6 * k, s0);
        load6(strain_increment + 6 * k, de);
        trial_stress(el, s0, de, t);
        decltype(t[0] < 0.0) in;
        clearly_elastic(t, st, bound, inv_bound, in);
        const int bits = _mm256_movemask_pd((__m256d)in);
        // Every lane is written. Where the end stress is the start stress,
        // a point left to update() keeps it; elsewhere it gets the trial
        // stress too, which update() overwrites (Points allows it).
        if (stress_end == stress_start)
            for (int i = 0; i < 6; ++i)
                t[i] = (Lanes)_mm256_blendv_pd((__m256d)s0[i], (__m256d)t[i], (__m256d)in);
        store6(stress_end + 6 * k, t);
        // yield_mode 0 (+0.0: no bit set) where finished, by a mask on its
        // bits: a branch per point, which GCC makes of a conditional
        // assignment, is mispredicted for most plastic points.
        static_assert(kElastic == 0);
        for (std::size_t j = 0; j < 4; ++j) {
            const std::uint64_t finished = (static_cast<unsigned>(bits) >> j) & 1u;
            double *mode = state_end + state * (k + j) + 2;
            std::uint64_t m;
            std::memcpy(&m, mode, sizeof m);
            m &= finished - 1u;
            std::memcpy(mode, &m, sizeof m);
            done[k + j] = static_cast<std::uint8_t>(finished);
        }
    }
    return k;
}

} // namespace quad

// Whether this processor runs screen_quads (read once).
inline bool quad_screen_available() {
    static const bool on = [] {
        __builtin_cpu_init();
        return __builtin_cpu_supports("avx2") != 0;
    }();
    return on;
}
#endif

} // namespace talus_mc
