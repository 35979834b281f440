// Phase 3, G2P (method/g2p.hpp), against the closed form for a grid
// velocity that is affine in space: with the nodes' velocities set from
// v(x) = b + A x and v~(x) = b~ + A~ x at their points (node_point), every
// shape reproduces them at a particle away from the faces (a partition of
// unity exact for linear fields, its gradients for their slope), so
//   PIC:   v_p = v~(x_p), L_p = A~, and the step dt v~(x_p) or, with the
//          second-order motion, dt (v(x_p) + v~(x_p)) / 2 (eqs. 36-38);
//   FLIP:  v_p <- v_p + v~(x_p) - v(x_p);
//   APIC:  v_p = v~(x_p) and C_p = A~ (Jiang et al. 2015 reproduce affine
//          fields exactly).
// Each is a sum of at most 64 nodes' products of order 1 in another order:
// 1e-12 bounds the rounding with a wide margin; L's and C's terms are 1/h
// (20 here) times larger and cancel to order 1: 1e-10.
#include "phase_fixture.hpp"

#include "method/g2p.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <vector>

namespace {

using talus::Motion;
using talus::ShapeKind;
using talus::Transfer;
using talus::test::PhaseParts;
namespace node = talus::node;

struct Affine {
    double b[3], A[3][3];
    double at(const double *x, int D, int r) const {
        double v = b[r];
        for (int c = 0; c < D; ++c)
            v += A[r][c] * x[c];
        return v;
    }
};
const Affine kStart{{0.3, -0.2, 0.1}, {{0.5, -1.0, 0.2}, {0.7, 0.1, -0.4}, {0.3, 0.9, -0.6}}};
const Affine kEnd{{0.1, 0.4, -0.3}, {{-0.8, 0.6, 0.5}, {0.2, 1.1, -0.7}, {-0.5, 0.4, 0.3}}};

void set_grid(talus::Grid &grid, ShapeKind shape) {
    const int D = grid.geo.dim;
    grid.reset();
    const std::size_t vs = node::velocity(D), ve = node::kEndVelocity;
    for (std::size_t i = 0; i < grid.n_nodes; ++i) {
        const auto x = grid.node_point(i, shape);
        for (int r = 0; r < D; ++r) {
            grid.vel[node::kRecord * i + vs + static_cast<std::size_t>(r)] =
                kStart.at(x.data(), D, r);
            grid.vel[node::kRecord * i + ve + static_cast<std::size_t>(r)] =
                kEnd.at(x.data(), D, r);
        }
    }
}

class G2p : public ::testing::TestWithParam<std::tuple<int, ShapeKind>> {};

TEST_P(G2p, ReproducesAnAffineGridVelocity) {
    const auto [D, shape] = GetParam();
    struct Way {
        Transfer transfer;
        double alpha;
        Motion motion;
    };
    for (const Way way : {Way{Transfer::flip, 0.0, Motion::end_velocity},
                          Way{Transfer::flip, 1.0, Motion::mean_velocity},
                          Way{Transfer::flip, 0.95, Motion::end_velocity},
                          Way{Transfer::apic, 0.0, Motion::mean_velocity}}) {
        PhaseParts c(D, shape, 2000);
        set_grid(c.grid, shape);
        const std::vector<double> v_before[3] = {{c.sets[0].v[0].begin(), c.sets[0].v[0].end()},
                                                 {c.sets[0].v[1].begin(), c.sets[0].v[1].end()},
                                                 {c.sets[0].v[2].begin(), c.sets[0].v[2].end()}};
        const double dt = 1e-3;
        const talus::G2pTargets t{
            c.grid.geo, c.sets, c.loads, shape, way.transfer, way.alpha, talus::kernel_isa()};
        talus::g2p_velocity(t, c.grid.vel.data(), dt, way.motion, /*store_gradient=*/true);
        const talus::ParticleSet &s = c.sets[0];
        for (std::size_t p = 0; p < s.n; ++p) {
            double x[3] = {s.x[0][p], s.x[1][p], D == 3 ? s.x[2][p] : 0.0};
            for (int r = 0; r < D; ++r) {
                const std::size_t rr = static_cast<std::size_t>(r);
                const double vt = kEnd.at(x, D, r), v0 = kStart.at(x, D, r);
                const double expect_v = vt + way.alpha * (v_before[rr][p] - v0);
                EXPECT_NEAR(s.v[rr][p], expect_v, 1e-12) << "particle " << p << " axis " << r;
                const double step =
                    way.motion == Motion::mean_velocity ? 0.5 * dt * (v0 + vt) : dt * vt;
                EXPECT_NEAR(s.dx[rr][p], step, 1e-12 * dt) << "particle " << p << " axis " << r;
                for (int k = 0; k < D; ++k) {
                    const std::size_t at = 9 * p + static_cast<std::size_t>(3 * r + k);
                    EXPECT_NEAR(s.L[at], kEnd.A[r][k], 1e-10) << "particle " << p;
                    if (way.transfer == Transfer::apic) {
                        EXPECT_NEAR(s.C[at], kEnd.A[r][k], 1e-10) << "particle " << p;
                    }
                }
            }
            if (::testing::Test::HasFailure()) return; // one particle's report is enough
        }
    }
}

INSTANTIATE_TEST_SUITE_P(Shapes, G2p,
                         ::testing::Combine(::testing::Values(2, 3),
                                            ::testing::Values(ShapeKind::linear, ShapeKind::gimp,
                                                              ShapeKind::bspline2,
                                                              ShapeKind::bspline3)));

} // namespace
