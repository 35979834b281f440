// The plane pass's arithmetic (mohr_coulomb.cpp): for a point whose trial
// stress the elastic screen did not pass, from its ordered principal trial
// stresses and directions, whether the stress stays (admissible), returns
// onto the shear plane or onto the cut-off plane, or needs the full update,
// and the plane return's stress and plastic strain.
//
// One template over the lane type: a double (a point alone, any processor)
// or four doubles a vector (AVX2, four points at once). Each lane runs
// the operations of finish() in the model, through the same functions
// (principal_return.hpp) and the same spectral composition as the SDK's
// SymmetricEigen::compose_stress, in the same order, and nothing is fused
// into a multiply-add (the plugin is compiled with -ffp-contract=off): a
// point's bits do not depend on the form that took it (tested in
// tests/unit/plugins/test_mohr_coulomb.cpp). A plastic point's
// decompositions and returns are most of this model's cost where points
// leave the screen (bench/results/2026-11-28-mohr-coulomb-plane-pass-ice-lake.md);
// each lane shares its operations with three others and takes no branch.
#pragma once

#include "principal_return.hpp"

#include <talus/sdk/spectral.hpp>

#include <cmath>
#include <cstddef>

// The vector form with GCC on x86-64 (the form it was written and checked
// with); elsewhere the one-lane form, the same bits.
#if defined(__x86_64__) && defined(__GNUC__) && !defined(__clang__)
#define TALUS_MC_HAS_PLANE_QUAD 1
#include <immintrin.h>
#endif

namespace talus_mc {

// Up to eight points, one lane each (structure of arrays).
struct PlaneLanes {
    static constexpr std::size_t kLanes = talus::sdk::kEigenGroup;
    // In: the ordered principal trial stresses (descending) and their unit
    // directions (the SDK's lanes: vectors[i][j][lane], component i of
    // direction j), and the start state.
    talus::sdk::EigenLanes trial;
    alignas(64) double kappa[kLanes], vol[kLanes], last[kLanes];
    // Out: 0 the full update's (nothing else is meaningful), 1 admissible
    // (the trial stress stands; mode_end is its yield mode), 2 returned
    // onto a plane (stress, kappa_end, vol_end and mode_end).
    alignas(64) double verdict[kLanes];
    alignas(64) double stress[6][kLanes];
    alignas(64) double kappa_end[kLanes], vol_end[kLanes], mode_end[kLanes];
};

// One lane's (or a vector of lanes') work, all but the square root of the
// plastic deviatoric strain (`dk_sq`: kappa_end = kappa + sqrt(dk_sq)).
// Without softening: `sys` is the model's fixed systems, `st` their
// strength. The order of candidates is return_map's: the last return's
// (hint) first, then the candidates in turn; the shear plane is candidate
// 0, the cut-off plane 1.
template <class T, class M>
TALUS_MC_LANE_INLINE void plane_lane(const Systems &sys, const Strength &st, const Elastic &el,
                                     const T t[3], const T v[3][3], const T &last, T &verdict,
                                     T stress[6], T &dk_sq, T &dvol, T &mode_end) {
    static_assert(kCandidates[0].mode == kShearPlane && kCandidates[1].mode == kTensionPlane);
    T tol;
    stress_tolerance(t, st, tol);
    M adm;
    admissible(t, st, tol, adm);
    T s0[3] = {t[0], t[1], t[2]}, s1[3];
    M v0 = adm ^ adm, v1 = v0; // false
    if (sys.of[0].solvable) plane_return(kCandidates[0], sys.of[0], t, sys.planes, st, tol, s0, v0);
    if (st.tension_active && sys.of[1].solvable)
        plane_return(kCandidates[1], sys.of[1], t, sys.planes, st, tol, s1, v1);
    else
        for (int i = 0; i < 3; ++i)
            s1[i] = s0[i];
    const M hint1 = last == static_cast<double>(kTensionPlane);
    // A last return onto another part of the surface has its candidate
    // tried first (return_map): left to the full update.
    const M plane_hint = (last == static_cast<double>(kElastic)) |
                         (last == static_cast<double>(kShearPlane)) | hint1;
    M not_v0 = v0, not_adm = adm;
    flip(not_v0);
    flip(not_adm);
    // v1 where the hint is the cut-off, else v1 unless v0.
    const M take1 = v1 & (hint1 | not_v0);
    const M plastic = not_adm & (take1 | v0) & plane_hint;
    T s[3], d[3], x[3];
    for (int i = 0; i < 3; ++i) {
        s[i] = take1 ? s1[i] : s0[i];
        d[i] = t[i] - s[i];
    }
    el.solve(d, x);
    deviatoric_measure_squared(x, dk_sq);
    dvol = (x[0] + x[1]) + x[2];
    // SymmetricEigen::compose_stress: sum_k s_k v(i, k) v(j, k) for the
    // pairs (0 0) (1 1) (2 2) (0 1) (1 2) (0 2).
    constexpr int pair[6][2] = {{0, 0}, {1, 1}, {2, 2}, {0, 1}, {1, 2}, {0, 2}};
    for (int e = 0; e < 6; ++e) {
        const int i = pair[e][0], j = pair[e][1];
        stress[e] = s[0] * v[i][0] * v[j][0] + s[1] * v[i][1] * v[j][1] + s[2] * v[i][2] * v[j][2];
    }
    M on;
    on_surface(t, st, tol, on);
    const T zero{};
    mode_end = plastic ? (take1 ? zero + static_cast<double>(kTensionPlane)
                                : zero + static_cast<double>(kShearPlane))
                       : (on ? last : zero + static_cast<double>(kElastic));
    verdict = adm ? zero + 1.0 : (plastic ? zero + 2.0 : zero);
}

// One lane at a time (any processor).
inline void plane_lanes_each(const Systems &sys, const Strength &st, const Elastic &el,
                             PlaneLanes &p, std::size_t n) {
    for (std::size_t k = 0; k < n; ++k) {
        double t[3], v[3][3], stress[6], dk_sq = 0.0, dvol = 0.0;
        for (int i = 0; i < 3; ++i) {
            t[i] = p.trial.values[i][k];
            for (int j = 0; j < 3; ++j)
                v[i][j] = p.trial.vectors[i][j][k];
        }
        plane_lane<double, bool>(sys, st, el, t, v, p.last[k], p.verdict[k], stress, dk_sq, dvol,
                                 p.mode_end[k]);
        for (int e = 0; e < 6; ++e)
            p.stress[e][k] = stress[e];
        p.kappa_end[k] = p.kappa[k] + std::sqrt(dk_sq);
        p.vol_end[k] = p.vol[k] + dvol;
    }
}

#if defined(TALUS_MC_HAS_PLANE_QUAD)
namespace quad {

// Four lanes a vector: AVX2, whose 256-bit vectors the templates above,
// compiled for the baseline target and inlined, keep as vectors (GCC
// lowers their 512-bit form to scalar code before inlining).
using Lanes = double __attribute__((vector_size(32)));
using Mask = decltype(Lanes{} < Lanes{});

__attribute__((target("avx2"), always_inline)) inline Lanes load(const double *a) {
    return (Lanes)_mm256_loadu_pd(a);
}
__attribute__((target("avx2"), always_inline)) inline void store(double *a, const Lanes &x) {
    _mm256_storeu_pd(a, (__m256d)x);
}

// Lanes [first, first + 4) of p.
__attribute__((target("avx2"))) inline void plane_lanes(const Systems &sys, const Strength &st,
                                                        const Elastic &el, PlaneLanes &p,
                                                        std::size_t first) {
    Lanes t[3], v[3][3];
    for (int i = 0; i < 3; ++i) {
        t[i] = load(p.trial.values[i] + first);
        for (int j = 0; j < 3; ++j)
            v[i][j] = load(p.trial.vectors[i][j] + first);
    }
    const Lanes last = load(p.last + first);
    Lanes verdict, stress[6], dk_sq, dvol, mode_end;
    plane_lane<Lanes, Mask>(sys, st, el, t, v, last, verdict, stress, dk_sq, dvol, mode_end);
    store(p.verdict + first, verdict);
    for (int e = 0; e < 6; ++e)
        store(p.stress[e] + first, stress[e]);
    // Correctly rounded, as std::sqrt.
    store(p.kappa_end + first, load(p.kappa + first) + (Lanes)_mm256_sqrt_pd((__m256d)dk_sq));
    store(p.vol_end + first, load(p.vol + first) + dvol);
    store(p.mode_end + first, mode_end);
}

// Whether this processor runs plane_lanes (read once).
inline bool available() {
    static const bool on = [] {
        __builtin_cpu_init();
        return __builtin_cpu_supports("avx2") != 0;
    }();
    return on;
}

} // namespace quad
#endif

} // namespace talus_mc
