// The objective rotation of the start stress for strain-increment models
// (docs/theory.md): header-only so the solver inlines it into its particle
// loop and the tests can check it against its definition.
#pragma once

namespace talus {

// Hughes-Winget incremental rotation (Hughes & Winget 1980):
// Q = (I - A)^-1 (I + A) with A = dt skew(L) / 2. For a skew matrix this
// Cayley transform has the closed form Q = I + 2 (A + A^2) / (1 + |a|^2),
// a the axial vector of A; Q is exactly orthogonal, so the rotated stress
// keeps its invariants.
//
// T is double, or a vector of doubles with one point per lane (the
// solver's kinematics, kinematics.cpp); L is indexable by 0..8 (row-major,
// of T or double). The three cases (no spin: no change; a spin about z
// alone, always so in plane strain: a plane rotation; any other: Q s Q^T)
// are computed and chosen per lane, so that a point gets the same bits
// whether alone or in a vector. AnyAxis false: the caller knows that every
// lane spins about z or not at all (L_xz, L_zx, L_yz, L_zy zero), and the
// general case, a third of the work in plane strain, is left out.
template <bool AnyAxis, class T, class Lm>
[[gnu::always_inline]] inline void hughes_winget_lanes(const Lm &L, double dt, T (&sig)[6]) {
    const T a1 = 0.25 * dt * (L[7] - L[5]); // A_zy
    const T a2 = 0.25 * dt * (L[2] - L[6]); // A_xz
    const T a3 = 0.25 * dt * (L[3] - L[1]); // A_yx
    const T aa = a1 * a1 + a2 * a2 + a3 * a3;
    const T c = 2.0 / (1.0 + aa);
    const T sxx = sig[0], syy = sig[1], szz = sig[2], sxy = sig[3], syz = sig[4], sxz = sig[5];
    // A spin about z alone: the angle with cos = 1 - c a3^2, sin = c a3.
    const T co = 1.0 - c * a3 * a3, si = c * a3;
    const T cc = co * co, ss = si * si, cs = co * si;
    T r[6];
    r[0] = cc * sxx - 2.0 * cs * sxy + ss * syy;
    r[1] = ss * sxx + 2.0 * cs * sxy + cc * syy;
    r[2] = szz;
    r[3] = cs * (sxx - syy) + (cc - ss) * sxy;
    r[5] = co * sxz - si * syz;
    r[4] = si * sxz + co * syz;
    const auto still = aa == 0.0;
    if constexpr (!AnyAxis) {
        for (int m = 0; m < 6; ++m)
            sig[m] = still ? sig[m] : r[m];
        return;
    }
    // Any other spin: A + A^2 with A^2 = a a^T - |a|^2 I.
    const T Q[3][3] = {{1.0 + c * (a1 * a1 - aa), c * (-a3 + a1 * a2), c * (a2 + a1 * a3)},
                       {c * (a3 + a2 * a1), 1.0 + c * (a2 * a2 - aa), c * (-a1 + a2 * a3)},
                       {c * (-a2 + a3 * a1), c * (a1 + a3 * a2), 1.0 + c * (a3 * a3 - aa)}};
    const T S[3][3] = {{sxx, sxy, sxz}, {sxy, syy, syz}, {sxz, syz, szz}};
    T QS[3][3];
    for (int i = 0; i < 3; ++i)
        for (int j = 0; j < 3; ++j)
            QS[i][j] = Q[i][0] * S[0][j] + Q[i][1] * S[1][j] + Q[i][2] * S[2][j];
    // a1 = a2 = 0 as the one compare |a1| + |a2| == 0 (false for NaN, as
    // each compare), and the two selects apart: on vectors, the compiler
    // builds an AND of two compare masks, or a select nested in another
    // sharing their conditions, lane by lane from scalar compares where the
    // target has no 64-bit mask vectors (AVX-512 without DQ).
    const T abs_a = (a1 < 0.0 ? -a1 : a1) + (a2 < 0.0 ? -a2 : a2);
    const auto about_z = abs_a == 0.0;
    // Voigt order: (0 0), (1 1), (2 2), (0 1), (1 2), (0 2).
    constexpr int row[6] = {0, 1, 2, 0, 1, 0}, col[6] = {0, 1, 2, 1, 2, 2};
    for (int m = 0; m < 6; ++m) {
        const int i = row[m], j = col[m];
        const T general = QS[i][0] * Q[j][0] + QS[i][1] * Q[j][1] + QS[i][2] * Q[j][2];
        // No spin is a spin about z (a1 = a2 = 0), so the plane case's
        // select goes first and the general one last. (Not quite the same
        // selection when |a|^2 underflows to 0 with a1 or a2 nonzero, below
        // about 1e-154: the general rotation, exact to round-off, is then
        // applied where the stress was kept.) The other nesting
        // (general or plane, then still or not) the compiler builds in the
        // vector kernels as a branch per lane that computes `general` in
        // scalar code where the lane needs it
        // (bench/results/2026-11-28-stress-rotation-whole-records-ice-lake.md).
        const T kept = still ? sig[m] : r[m];
        sig[m] = about_z ? kept : general;
    }
}

// The same for one point's Voigt stress.
[[gnu::always_inline]] inline void hughes_winget(const double *L, double dt, double *sig) {
    double s[6] = {sig[0], sig[1], sig[2], sig[3], sig[4], sig[5]};
    hughes_winget_lanes<true>(L, dt, s);
    for (int k = 0; k < 6; ++k)
        sig[k] = s[k];
}

// The rotation matrix of the same increment, row-major: what
// hughes_winget applies to the stress as Q s Q^T (for a model that rotates
// tensor-valued state itself: talus_batch.rotation, UMAT's DROT).
inline void hughes_winget_rotation(const double *L, double dt, double *Q) {
    const double a1 = 0.25 * dt * (L[7] - L[5]);
    const double a2 = 0.25 * dt * (L[2] - L[6]);
    const double a3 = 0.25 * dt * (L[3] - L[1]);
    const double aa = a1 * a1 + a2 * a2 + a3 * a3;
    const double c = 2.0 / (1.0 + aa);
    Q[0] = 1.0 + c * (a1 * a1 - aa);
    Q[1] = c * (-a3 + a1 * a2);
    Q[2] = c * (a2 + a1 * a3);
    Q[3] = c * (a3 + a2 * a1);
    Q[4] = 1.0 + c * (a2 * a2 - aa);
    Q[5] = c * (-a1 + a2 * a3);
    Q[6] = c * (-a2 + a3 * a1);
    Q[7] = c * (a1 + a3 * a2);
    Q[8] = 1.0 + c * (a3 * a3 - aa);
}

} // namespace talus
