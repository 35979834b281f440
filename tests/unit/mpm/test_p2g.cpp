// Phase 1, P2G (method/p2g.hpp), against the identities its sums must keep
// whatever the shape (docs/theory.md, eqs. 20, 21, 28, 29): the weights are
// a partition of unity that reproduces linear fields at the nodes' points
// (node_point), so for particles away from the faces
//   sum_i m_i = sum_p m_p,            sum_i m_i x_i = sum_p m_p x_p,
//   sum_i p_i = sum_p m_p v_p,        sum_i f_i = sum_p m_p g,
// and, since sum_i grad w_ip = 0 and sum_i x_i (x) grad w_ip = I, the
// internal forces sum to zero and their first moment is the particles'
// volume-weighted stress: sum_i x_i (x) f_int,i = -sum_p V_p sigma_p.
// Each is a sum of a few thousand products in another order than the
// phase's; its scale is the sum of the node totals' magnitudes (for the
// forces smaller than the terms', which cancel in part at a node). The
// roundings of the two orders differ by some 1e-15 of that scale; a wrong
// sum (a node missed, a sign, a weight) by order one of it: 1e-12 lies
// between, far from both.
#include "phase_fixture.hpp"

#include "method/p2g.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <vector>

namespace {

using talus::ShapeKind;
using talus::test::PhaseParts;
namespace node = talus::node;

struct Sums {
    double m = 0, mx[3]{}, p[3]{}, f[3]{}, xf[3][3]{};
    double scale_m = 0, scale_p = 0, scale_f = 0, scale_xf = 0;
};

Sums nodal_sums(const talus::Grid &grid, ShapeKind shape) {
    Sums s;
    const int D = grid.geo.dim;
    for (std::size_t i = 0; i < grid.n_nodes; ++i) {
        const double *r = &grid.acc[node::kRecord * i];
        const auto x = grid.node_point(i, shape);
        s.m += r[node::kMass];
        s.scale_m += std::abs(r[node::kMass]);
        for (int a = 0; a < D; ++a) {
            s.mx[a] += r[node::kMass] * x[static_cast<std::size_t>(a)];
            s.p[a] += r[node::kMomentum + static_cast<std::size_t>(a)];
            s.scale_p += std::abs(r[node::kMomentum + static_cast<std::size_t>(a)]);
            const double f = r[node::kForce + static_cast<std::size_t>(a)];
            s.f[a] += f;
            s.scale_f += std::abs(f);
            for (int b = 0; b < D; ++b) {
                s.xf[a][b] +=
                    x[static_cast<std::size_t>(a)] * r[node::kForce + static_cast<std::size_t>(b)];
                s.scale_xf += std::abs(x[static_cast<std::size_t>(a)] *
                                       r[node::kForce + static_cast<std::size_t>(b)]);
            }
        }
    }
    return s;
}

class P2g : public ::testing::TestWithParam<std::tuple<int, ShapeKind>> {};

TEST_P(P2g, KeepsMassMomentumTheirMomentsAndTheForceBalance) {
    const auto [D, shape] = GetParam();
    const talus::Vec3 g{0.3, -9.81, D == 3 ? 1.5 : 0.0};
    PhaseParts c(D, shape, 3000, g);
    c.grid.reset();
    talus::P2gSources src{c.grid.geo, c.sets, c.order, c.loads, shape, false, talus::kernel_isa()};
    talus::p2g_momentum_and_forces(src, c.grid.acc.data());
    const Sums s = nodal_sums(c.grid, shape);

    const talus::ParticleSet &ps = c.sets[0];
    double m = 0, mx[3]{}, p[3]{}, Vsig[3][3]{};
    const int voigt[3][3] = {{0, 3, 5}, {3, 1, 4}, {5, 4, 2}};
    for (std::size_t q = 0; q < ps.n; ++q) {
        m += ps.mass[q];
        const double V = ps.J[q] * ps.vol0[q];
        for (int a = 0; a < D; ++a) {
            const std::size_t aa = static_cast<std::size_t>(a);
            mx[a] += ps.mass[q] * ps.x[aa][q];
            p[a] += ps.mass[q] * ps.v[aa][q];
            for (int b = 0; b < D; ++b)
                Vsig[a][b] += V * ps.stress[6 * q + static_cast<std::size_t>(voigt[a][b])];
        }
    }
    const double tol = 1e-12;
    EXPECT_NEAR(s.m, m, tol * s.scale_m);
    for (int a = 0; a < D; ++a) {
        // The first moment's terms are m_i x_i, |x_i| < 2 m in this domain.
        EXPECT_NEAR(s.mx[a], mx[a], tol * s.scale_m * 2.0) << "axis " << a;
        EXPECT_NEAR(s.p[a], p[a], tol * s.scale_p) << "axis " << a;
        // Gravity alone: the internal forces cancel.
        EXPECT_NEAR(s.f[a], m * g[static_cast<std::size_t>(a)], tol * s.scale_f) << "axis " << a;
    }
    // The moment of the forces: the internal part is -sum V sigma; gravity
    // adds sum_p m_p x_p (x) g (its nodal share reproduces x_p exactly).
    for (int a = 0; a < D; ++a)
        for (int b = 0; b < D; ++b)
            EXPECT_NEAR(s.xf[a][b], -Vsig[a][b] + mx[a] * g[static_cast<std::size_t>(b)],
                        tol * s.scale_xf)
                << "component " << a << b;
}

INSTANTIATE_TEST_SUITE_P(Shapes, P2g,
                         ::testing::Combine(::testing::Values(2, 3),
                                            ::testing::Values(ShapeKind::linear, ShapeKind::gimp,
                                                              ShapeKind::bspline2,
                                                              ShapeKind::bspline3)));

// One particle with the tent functions: each of its 2^D nodes gets m N_i,
// N_i the product of the tents (1 - |x - x_i| / h) per axis, a closed form.
// The particle's local coordinate (x - origin) / h carries the rounding of
// x (a few units in the last place of 8.3 and 5.6), and the weights with
// it: 1e-14.
TEST(P2gOneParticle, GivesEachNodeItsTentWeightOfTheMass) {
    PhaseParts c(2, ShapeKind::linear, 1);
    talus::ParticleSet &ps = c.sets[0];
    const talus::GridGeometry &g = c.grid.geo;
    // At (0.3 h, 0.6 h) from the node (8, 5) of the domain.
    ps.x[0][0] = g.origin[0] + (8 + 0.3) * g.h;
    ps.x[1][0] = g.origin[1] + (5 + 0.6) * g.h;
    ps.mass[0] = 2.0;
    c.order.prepare(c.sets, 0.01);
    c.grid.reset();
    talus::P2gSources src{
        g, c.sets, c.order, c.loads, ShapeKind::linear, false, talus::kernel_isa()};
    talus::p2g_momentum(src, c.grid.acc.data());
    const double N[2][2] = {{0.7, 0.3}, {0.4, 0.6}}; // per axis: node k, k + 1
    int reached = 0;
    for (std::size_t i = 0; i < c.grid.n_nodes; ++i) {
        const double mi = c.grid.acc[node::kRecord * i + node::kMass];
        const auto k = g.global(i);
        const int a = k[0] - 8, b = k[1] - 5;
        if (a >= 0 && a <= 1 && b >= 0 && b <= 1) {
            EXPECT_NEAR(mi, 2.0 * N[0][a] * N[1][b], 1e-14) << "node " << k[0] << ", " << k[1];
            ++reached;
        } else {
            EXPECT_EQ(mi, 0.0) << "node " << k[0] << ", " << k[1];
        }
    }
    EXPECT_EQ(reached, 4);
}

} // namespace
