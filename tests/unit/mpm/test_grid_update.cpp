// Phase 2, the grid update (method/grid_update.hpp), node by node against
// its closed form (docs/theory.md, eqs. 31-32): v = p / m and
// v~ = v + dt f / m at every node with mass, zero at a massless one; a
// face's conditions hold as they are defined;
// viscous damping takes alpha m v off the force first, so that
// v~ = v (1 - alpha dt) + dt f / m. The phase computes each with a few
// roundings in its own order: 1e-14 of the value's size plus 1e-14
// (for values near zero, whose roundings come from terms of order one)
// bounds the difference.
#include "phase_fixture.hpp"

#include "method/boundary.hpp"
#include "method/grid_update.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <random>
#include <vector>

namespace {

using talus::FaceType;
using talus::ShapeKind;
using talus::test::PhaseParts;
namespace node = talus::node;

// Random records at every node: a third massless, the others with mass,
// momentum and force of order 1.
void fill(talus::Grid &grid, std::uint32_t seed) {
    std::mt19937 rng(seed);
    std::uniform_real_distribution<double> u(0.0, 1.0), sym(-1.0, 1.0);
    grid.reset();
    for (std::size_t i = 0; i < grid.n_nodes; ++i) {
        double *r = &grid.acc[node::kRecord * i];
        if (u(rng) < 1.0 / 3.0) continue;
        r[node::kMass] = 0.1 + u(rng);
        for (std::size_t d = 0; d < 3; ++d) {
            r[node::kMomentum + d] = sym(rng);
            r[node::kForce + d] = 10.0 * sym(rng);
        }
    }
}

struct Expected {
    double v[3], vt[3];
};

Expected closed_form(const double *r, double dt, double alpha) {
    Expected e{};
    const double m = r[node::kMass];
    for (std::size_t d = 0; d < 3; ++d) {
        e.v[d] = m > 0.0 ? r[node::kMomentum + d] / m : 0.0;
        e.vt[d] = m > 0.0 ? e.v[d] * (1.0 - alpha * dt) + dt * r[node::kForce + d] / m : 0.0;
    }
    return e;
}

class GridUpdate : public ::testing::TestWithParam<int> {};

TEST_P(GridUpdate, GivesEveryFreeNodeItsVelocitiesFromMomentumAndForce) {
    const int D = GetParam();
    for (const double alpha : {0.0, 3.0}) {
        PhaseParts c(D, ShapeKind::bspline2, 0);
        fill(c.grid, 11);
        const std::vector<double> before(c.grid.acc.begin(), c.grid.acc.end());
        const talus::Boundary free(c.scenario, c.conditions, c.grid, 0.0);
        talus::DampingSpec damping;
        if (alpha > 0.0) {
            damping.kind = talus::DampingKind::viscous;
            damping.coefficient = alpha;
        }
        const double dt = 2e-3;
        talus::grid_update(c.grid, free, 0.0, dt, damping);
        const std::size_t vs = node::velocity(D), ve = node::kEndVelocity;
        for (std::size_t i = 0; i < c.grid.n_nodes; ++i) {
            const Expected e = closed_form(&before[node::kRecord * i], dt, alpha);
            for (std::size_t d = 0; d < static_cast<std::size_t>(D); ++d) {
                const double *v = &c.grid.vel[node::kRecord * i];
                EXPECT_NEAR(v[vs + d], e.v[d], 1e-14 * (1.0 + std::abs(e.v[d])))
                    << "node " << i << " axis " << d << " alpha " << alpha;
                EXPECT_NEAR(v[ve + d], e.vt[d], 1e-14 * (1.0 + std::abs(e.vt[d])))
                    << "node " << i << " axis " << d << " alpha " << alpha;
            }
        }
    }
}

// A fixed x- face, a roller y- face and a slip y+ face on their nodes (the
// face's layer of the kernel, Grid::face_nodes): the fixed one holds v and
// v~ at zero; the roller, a bilateral wall, their y components; the slip
// face, a unilateral contact, takes the y component off where it points
// into the wall (v_y > 0), first of v and then of v~ = v + dt f / m from
// the v it left (docs/scenario-reference.md, "boundaries"). Every other
// node keeps its free velocities.
TEST_P(GridUpdate, HoldsTheFacesConditions) {
    const int D = GetParam();
    PhaseParts c(D, ShapeKind::linear, 0);
    fill(c.grid, 12);
    const std::vector<double> before(c.grid.acc.begin(), c.grid.acc.end());
    c.conditions.faces[0].type = FaceType::fixed;  // x-
    c.conditions.faces[2].type = FaceType::roller; // y-
    c.conditions.faces[3].type = FaceType::slip;   // y+
    const talus::Boundary bc(c.scenario, c.conditions, c.grid, 0.0);
    const double dt = 1e-3;
    talus::grid_update(c.grid, bc, 0.0, dt);
    std::vector<char> on[4];
    for (int f = 0; f < 4; ++f) {
        on[f].assign(c.grid.n_nodes, 0);
        c.grid.face_nodes[static_cast<std::size_t>(f)].for_each_slot(
            c.grid.geo.extent, [&](std::size_t i) { on[f][i] = 1; });
    }
    long fixed = 0, rolling = 0, slipping = 0, leaving = 0;
    const std::size_t vs = node::velocity(D), ve = node::kEndVelocity;
    for (std::size_t i = 0; i < c.grid.n_nodes; ++i) {
        const double *r = &before[node::kRecord * i];
        const double m = r[node::kMass];
        const double inv = m > 0.0 ? 1.0 / m : 0.0;
        const double *v = &c.grid.vel[node::kRecord * i];
        for (std::size_t d = 0; d < static_cast<std::size_t>(D); ++d) {
            double v0 = r[node::kMomentum + d] * inv;
            const bool wall = on[0][i] || (d == 1 && on[2][i]);
            const bool slip = d == 1 && on[3][i] && !wall;
            if (wall || (slip && v0 > 0.0)) v0 = 0.0;
            double vt = wall ? 0.0 : v0 + dt * r[node::kForce + d] * inv;
            if (slip && vt > 0.0) vt = 0.0;
            EXPECT_NEAR(v[vs + d], v0, 1e-14 * (1.0 + std::abs(v0)))
                << "node " << i << " axis " << d;
            EXPECT_NEAR(v[ve + d], vt, 1e-14 * (1.0 + std::abs(vt)))
                << "node " << i << " axis " << d;
            if (slip && m > 0.0 && r[node::kMomentum + d] < 0.0) ++leaving;
        }
        fixed += on[0][i];
        rolling += on[2][i] && !on[0][i];
        slipping += on[3][i] && !on[0][i];
    }
    // Each kind of node is there, and the slip face has nodes moving off it.
    EXPECT_GT(fixed, 0);
    EXPECT_GT(rolling, 0);
    EXPECT_GT(slipping, 0);
    EXPECT_GT(leaving, 0);
}

// Told that nothing reads the accumulators after it, the update clears
// them as it goes, and each node's mass stays readable (Grid::node_mass).
TEST_P(GridUpdate, ClearsTheAccumulatorsItWasLastToRead) {
    const int D = GetParam();
    PhaseParts c(D, ShapeKind::bspline2, 0);
    fill(c.grid, 13);
    const std::vector<double> before(c.grid.acc.begin(), c.grid.acc.end());
    const talus::Boundary free(c.scenario, c.conditions, c.grid, 0.0);
    talus::grid_update(c.grid, free, 0.0, 1e-3, {}, talus::Accumulators::clear);
    for (std::size_t i = 0; i < c.grid.n_nodes; ++i) {
        EXPECT_EQ(c.grid.node_mass(i), before[node::kRecord * i + node::kMass]) << "node " << i;
        for (std::size_t k = 0; k < node::kRecord; ++k)
            EXPECT_EQ(c.grid.acc[node::kRecord * i + k], 0.0) << "node " << i << " slot " << k;
    }
}

INSTANTIATE_TEST_SUITE_P(Dimensions, GridUpdate, ::testing::Values(2, 3));

} // namespace
