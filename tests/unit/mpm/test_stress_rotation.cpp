// The Hughes-Winget rotation (docs/theory.md) against its definition
// Q = (I - A)^-1 (I + A), A = dt skew(L) / 2, computed here with a general
// matrix inverse: the closed form and its in-plane fast path must agree to
// round-off (1e-13 of the stress), and Q sigma Q^T must keep the stress
// invariants (trace, J2, determinant) to round-off.
#include <talus/mpm/stress_rotation.hpp>

#include <talus/sdk/voigt.hpp>

#include <Eigen/Dense>
#include <gtest/gtest.h>

#include <random>

namespace {

Eigen::Matrix3d definition_Q(const double *L, double dt) {
    Eigen::Matrix3d A;
    for (int i = 0; i < 3; ++i)
        for (int j = 0; j < 3; ++j)
            A(i, j) = 0.25 * dt * (L[3 * i + j] - L[3 * j + i]);
    const Eigen::Matrix3d I = Eigen::Matrix3d::Identity();
    return (I - A).inverse() * (I + A);
}

} // namespace

TEST(StressRotation, HughesWingetMatchesItsDefinitionAndKeepsInvariants) {
    std::mt19937_64 rng(3);
    std::uniform_real_distribution<double> u(-1.0, 1.0);
    for (int trial = 0; trial < 500; ++trial) {
        const bool plane = trial % 2 == 0; // in-plane spin: the 2D fast path
        double L[9];
        for (double &v : L)
            v = u(rng);
        if (plane) L[2] = L[5] = L[6] = L[7] = 0.0;
        const double dt = 0.5 * (1.0 + u(rng)); // large rotations too
        talus::sdk::Vec6 s;
        for (int k = 0; k < 6; ++k)
            s[k] = 1e5 * u(rng);
        talus::sdk::Vec6 r = s;
        talus::hughes_winget(L, dt, r.data());
        const Eigen::Matrix3d Q = definition_Q(L, dt);
        const Eigen::Matrix3d S = talus::sdk::stress_to_matrix(s);
        const talus::sdk::Vec6 expect = talus::sdk::matrix_to_stress(Q * S * Q.transpose());
        const double scale = s.cwiseAbs().maxCoeff();
        EXPECT_LT((r - expect).cwiseAbs().maxCoeff(), 1e-13 * scale) << "trial " << trial;
        const Eigen::Matrix3d R = talus::sdk::stress_to_matrix(r);
        EXPECT_NEAR(R.trace(), S.trace(), 1e-12 * scale);
        EXPECT_NEAR(talus::sdk::j2_invariant(r), talus::sdk::j2_invariant(s),
                    1e-12 * scale * scale);
        EXPECT_NEAR(R.determinant(), S.determinant(), 1e-11 * scale * scale * scale);
    }
}

TEST(StressRotation, NoSpinNoChange) {
    const double L[9] = {0.3, 0.2, 0.1, 0.2, -0.4, 0.5, 0.1, 0.5, 0.7}; // symmetric
    talus::sdk::Vec6 s;
    s << 1, 2, 3, 4, 5, 6;
    talus::sdk::Vec6 r = s;
    talus::hughes_winget(L, 0.1, r.data());
    EXPECT_EQ(r, s);
}
