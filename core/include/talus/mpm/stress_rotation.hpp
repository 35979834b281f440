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
[[gnu::always_inline]] inline void hughes_winget(const double *L, double dt, double *sig) {
    const double a1 = 0.25 * dt * (L[7] - L[5]); // A_zy
    const double a2 = 0.25 * dt * (L[2] - L[6]); // A_xz
    const double a3 = 0.25 * dt * (L[3] - L[1]); // A_yx
    const double aa = a1 * a1 + a2 * a2 + a3 * a3;
    if (aa == 0.0) return;
    const double c = 2.0 / (1.0 + aa);
    if (a1 == 0.0 && a2 == 0.0) {
        // In-plane spin (always so in 2D): a rotation about z by the angle
        // with cos = 1 - c a3^2, sin = c a3.
        const double co = 1.0 - c * a3 * a3, si = c * a3;
        const double sxx = sig[0], syy = sig[1], sxy = sig[3], syz = sig[4], sxz = sig[5];
        const double cc = co * co, ss = si * si, cs = co * si;
        sig[0] = cc * sxx - 2.0 * cs * sxy + ss * syy;
        sig[1] = ss * sxx + 2.0 * cs * sxy + cc * syy;
        sig[3] = cs * (sxx - syy) + (cc - ss) * sxy;
        sig[5] = co * sxz - si * syz;
        sig[4] = si * sxz + co * syz;
        return;
    }
    // A + A^2 with A^2 = a a^T - |a|^2 I.
    double Q[3][3] = {{1.0 + c * (a1 * a1 - aa), c * (-a3 + a1 * a2), c * (a2 + a1 * a3)},
                      {c * (a3 + a2 * a1), 1.0 + c * (a2 * a2 - aa), c * (-a1 + a2 * a3)},
                      {c * (-a2 + a3 * a1), c * (a1 + a3 * a2), 1.0 + c * (a3 * a3 - aa)}};
    const double S[3][3] = {
        {sig[0], sig[3], sig[5]}, {sig[3], sig[1], sig[4]}, {sig[5], sig[4], sig[2]}};
    double QS[3][3];
    for (int i = 0; i < 3; ++i)
        for (int j = 0; j < 3; ++j)
            QS[i][j] = Q[i][0] * S[0][j] + Q[i][1] * S[1][j] + Q[i][2] * S[2][j];
    auto R = [&](int i, int j) {
        return QS[i][0] * Q[j][0] + QS[i][1] * Q[j][1] + QS[i][2] * Q[j][2];
    };
    sig[0] = R(0, 0);
    sig[1] = R(1, 1);
    sig[2] = R(2, 2);
    sig[3] = R(0, 1);
    sig[4] = R(1, 2);
    sig[5] = R(0, 2);
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
