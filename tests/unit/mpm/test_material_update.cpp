// Phase 3's material update (method/material_update.hpp) on a set of
// points with a uniform velocity gradient, through the shipped
// linear_elastic plugin, against the closed forms of docs/theory.md
// (eqs. 39-42) and Hooke's law: F = (I + dt L) F0, J = det F,
// rho = rho0 / J, d_eps = dt sym(L), and from a zero start stress
// sigma = lambda tr(d_eps) I + 2 G d_eps (plane strain: d_eps_zz = 0, so
// sigma_zz = lambda tr(d_eps)). Each is a few roundings of values of
// order 1 (F, J: 1e-15 and 1e-14, a handful of ulps) or of E dt (the
// stress: 1e-12 of it, the plugin's Hooke sums in its own order), and of
// the wave speed (1e-12 of it: a division and a root).
#include "phase_fixture.hpp"
#include "solver_helpers.hpp"

#include "method/material_update.hpp"

#include <talus/material/plugin_loader.hpp>

#include <gtest/gtest.h>

#include <cmath>
#include <memory>
#include <vector>

namespace {

using talus::ShapeKind;
using talus::test::PhaseParts;

class MaterialUpdate : public ::testing::TestWithParam<int> {};

TEST_P(MaterialUpdate, GivesTheKinematicsAndHookesStressOfAUniformGradient) {
    const int D = GetParam();
    const double E = 1e7, nu = 0.3, rho0 = 2000.0, dt = 1e-3;
    const double G = E / (2 * (1 + nu)), lambda = E * nu / ((1 + nu) * (1 - 2 * nu));
    talus::PluginRegistry registry({talus::test::plugin_dir()}, false);
    const talus::Model &model = registry.find_model("linear_elastic");
    const std::vector<double> values = {E, nu};
    const std::unique_ptr<talus::MaterialInstance> instance = model.create(values);

    // 300 points: more than two of the plugin's batches of 128.
    PhaseParts c(D, ShapeKind::bspline2, 300);
    talus::ParticleSet &s = c.sets[0];
    s.instance = instance.get();
    s.rho0 = rho0;
    const double L[3][3] = {{0.4, 1.5, -0.3}, {-0.2, -0.6, 0.8}, {0.5, 0.1, 0.25}};
    for (std::size_t p = 0; p < s.n; ++p) {
        s.J[p] = 1.0;
        for (std::size_t k = 0; k < 6; ++k)
            s.stress[6 * p + k] = 0.0;
        for (int r = 0; r < 3; ++r)
            for (int k = 0; k < 3; ++k)
                s.L[9 * p + static_cast<std::size_t>(3 * r + k)] = r < D && k < D ? L[r][k] : 0.0;
    }
    talus::MaterialNames names{{"m"}, {"g"}};
    talus::MaterialUpdate mu(names, 128, c.scenario.cell, talus::kernel_isa());
    mu.prepare(c.sets);
    talus::UpdateFailures failures;
    const talus::Increment inc{0.0, dt, 1, nullptr, nullptr};
    mu.run(c.sets, inc, /*stored_L=*/true, failures);
    ASSERT_EQ(failures.material.first(), nullptr);
    ASSERT_EQ(failures.inverted.first(), nullptr);

    // The closed forms.
    double F[3][3], de[3][3];
    for (int r = 0; r < 3; ++r)
        for (int k = 0; k < 3; ++k) {
            const bool in = r < D && k < D;
            F[r][k] = (r == k ? 1.0 : 0.0) + (in ? dt * L[r][k] : 0.0);
            de[r][k] = in ? 0.5 * dt * (L[r][k] + L[k][r]) : 0.0;
        }
    const double J = F[0][0] * (F[1][1] * F[2][2] - F[1][2] * F[2][1]) -
                     F[0][1] * (F[1][0] * F[2][2] - F[1][2] * F[2][0]) +
                     F[0][2] * (F[1][0] * F[2][1] - F[1][1] * F[2][0]);
    const double tr = de[0][0] + de[1][1] + de[2][2];
    const int voigt[6][2] = {{0, 0}, {1, 1}, {2, 2}, {0, 1}, {1, 2}, {0, 2}};
    double sigma[6];
    for (int k = 0; k < 6; ++k) {
        const int a = voigt[k][0], b = voigt[k][1];
        sigma[k] = (a == b ? lambda * tr : 0.0) + 2.0 * G * de[a][b];
    }
    for (std::size_t p = 0; p < s.n; ++p) {
        EXPECT_NEAR(s.J[p], J, 1e-14) << "point " << p;
        double Fp[9];
        s.F_of(p, Fp);
        for (int r = 0; r < 3; ++r)
            for (int k = 0; k < 3; ++k)
                EXPECT_NEAR(Fp[3 * r + k], F[r][k], 1e-15) << "point " << p << " F" << r << k;
        for (int k = 0; k < 6; ++k)
            EXPECT_NEAR(s.stress[6 * p + static_cast<std::size_t>(k)], sigma[k], 1e-12 * E * dt)
                << "point " << p << " component " << k;
        // The P-wave speed the plugin reports, sqrt((lambda + 2 G) / rho).
        EXPECT_NEAR(s.c[p], std::sqrt((lambda + 2 * G) * J / rho0), 1e-12 * s.c[p])
            << "point " << p;
        if (::testing::Test::HasFailure()) return;
    }
}

INSTANTIATE_TEST_SUITE_P(Dimensions, MaterialUpdate, ::testing::Values(2, 3));

} // namespace
