// talus/sdk/hooke.hpp -- isotropic Hooke's law over a chunk of points, for a
// model's quick pass (material.hpp, Points).
//
// sigma_end = sigma_start + lambda tr(de) I + 2 G de, per point, in the
// Voigt conventions of material_abi.h (tensor shear stress, engineering
// shear strain, so the shear terms are G de). The arrays hold 6 values a
// point, one point after another; written point by point the loop does not
// vectorise (the compiler finds no vector type for groups of 6), and it runs
// for every point of a linear elastic step
// (bench/results/2026-11-28-xeon-ice-lake-hooke-step-end-grid-update.md).
//
// Two points are 12 doubles, three 4-lane vectors whose lanes are always the
// same components (xx yy zz xy | yz xz xx yy | zz xy yz xz), so each lane
// takes its factor (2G or G) and, for a normal component, its point's
// lambda tr(de). Every value goes through the same operations in the same
// order as in the scalar form below (no fused multiply-adds: the AVX target
// has none), so the results are the same bits whichever form runs. Where the
// model's own build may fuse them in the scalar form (an FMA target:
// -march=native and the like) the pairs are left out, so that the forms
// cannot round differently.
#pragma once

#include <cstddef>

#include "detail/avx.hpp"

#if defined(TALUS_SDK_HAS_QUAD) && !defined(__FMA__)
#define TALUS_SDK_HOOKE_PAIRS 1
#endif

namespace talus::sdk {

namespace detail {

// One point: the reference form.
inline void hooke_point(double lambda, double two_shear, double shear, const double *s0,
                        const double *de, double *s1) {
    const double lam_tr = lambda * (de[0] + de[1] + de[2]);
    for (int i = 0; i < 3; ++i) {
        s1[i] = s0[i] + (lam_tr + two_shear * de[i]);
        s1[i + 3] = s0[i + 3] + shear * de[i + 3];
    }
}

#if defined(TALUS_SDK_HOOKE_PAIRS)
// Points [0, n - n % 2), two at a time; returns how many it did.
__attribute__((target("avx"))) inline std::size_t hooke_pairs(double lambda, double two_shear,
                                                              double shear, const double *s0,
                                                              const double *de, double *s1,
                                                              std::size_t n) {
    const __m256d f0 = _mm256_setr_pd(two_shear, two_shear, two_shear, shear);
    const __m256d f1 = _mm256_setr_pd(shear, shear, two_shear, two_shear);
    const __m256d f2 = _mm256_setr_pd(two_shear, shear, shear, shear);
    std::size_t k = 0;
    for (; k + 1 < n; k += 2) {
        const double *d = de + 6 * k, *a = s0 + 6 * k;
        double *b = s1 + 6 * k;
        const __m256d l0 = _mm256_set1_pd(lambda * (d[0] + d[1] + d[2]));
        const __m256d l1 = _mm256_set1_pd(lambda * (d[6] + d[7] + d[8]));
        const __m256d t0 = _mm256_mul_pd(f0, _mm256_loadu_pd(d));
        const __m256d t1 = _mm256_mul_pd(f1, _mm256_loadu_pd(d + 4));
        const __m256d t2 = _mm256_mul_pd(f2, _mm256_loadu_pd(d + 8));
        // lambda tr(de) + 2 G de in the normal components' lanes (blend
        // mask: bit i for lane i), G de alone in the shear ones.
        const __m256d u0 = _mm256_blend_pd(t0, _mm256_add_pd(l0, t0), 0b0111);
        const __m256d u1 = _mm256_blend_pd(t1, _mm256_add_pd(l1, t1), 0b1100);
        const __m256d u2 = _mm256_blend_pd(t2, _mm256_add_pd(l1, t2), 0b0001);
        _mm256_storeu_pd(b, _mm256_add_pd(_mm256_loadu_pd(a), u0));
        _mm256_storeu_pd(b + 4, _mm256_add_pd(_mm256_loadu_pd(a + 4), u1));
        _mm256_storeu_pd(b + 8, _mm256_add_pd(_mm256_loadu_pd(a + 8), u2));
    }
    return k;
}
#endif

} // namespace detail

// Points k < n: s1 (6 k ..) = s0 (6 k ..) + lambda tr(de) I + 2 G de, with
// de (6 k ..) in engineering shear. s1 may be s0 (each value is read before
// it is written); nothing else may overlap.
inline void isotropic_hooke(double lambda, double shear, const double *s0, const double *de,
                            double *s1, std::size_t n) {
    // 2 G de as (2 G) de: the same bits as 2 (G de), a product by two
    // being exact.
    const double two_shear = 2.0 * shear;
    std::size_t k = 0;
#if defined(TALUS_SDK_HOOKE_PAIRS)
    if (detail::quad_enabled()) k = detail::hooke_pairs(lambda, two_shear, shear, s0, de, s1, n);
#endif
    for (; k < n; ++k)
        detail::hooke_point(lambda, two_shear, shear, s0 + 6 * k, de + 6 * k, s1 + 6 * k);
}

} // namespace talus::sdk
