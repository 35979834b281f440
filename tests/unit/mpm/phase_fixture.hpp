// A grid and a set of particles for the phases' unit tests (test_p2g,
// test_grid_update, test_g2p, test_material_update): the parts a phase
// reads and writes, built by hand, without a Simulation.
#pragma once

#include "method/loads.hpp"
#include "parallel/ordering.hpp"
#include "state/grid.hpp"

#include <talus/mpm/particles.hpp>
#include <talus/mpm/scenario.hpp>

#include <array>
#include <cstddef>
#include <ostream>
#include <random>
#include <vector>

namespace talus {

// The shape's name in the tests' parameter lists.
inline void PrintTo(ShapeKind k, std::ostream *os) {
    constexpr const char *names[] = {"linear", "gimp", "bspline2", "bspline3"};
    *os << names[static_cast<int>(k)];
}

} // namespace talus

namespace talus::test {

struct PhaseParts {
    Scenario scenario;
    Conditions conditions;
    Grid grid;
    std::vector<ParticleSet> sets;
    Ordering order;
    Loads loads;

    // A domain of 1.2 x 0.8 (x 0.6) m in cells of 0.05 m from (-0.3, 0.2,
    // 0.1), and n particles with random masses, velocities, stresses and
    // volumes, placed at random at least three cells from every face (where
    // every shape is its interior form: a partition of unity that
    // reproduces linear fields).
    PhaseParts(int dim, ShapeKind shape, std::size_t n, const Vec3 &gravity = {0, 0, 0},
               std::uint32_t seed = 7)
        : scenario(scenario_of(dim)), conditions(conditions_of(gravity)),
          grid(dim, {-0.3, 0.2, 0.1}, {1.2, 0.8, 0.6}, 0.05, shape), sets(1), order(grid.geo, 1),
          loads(scenario, conditions, gravity, 0.0) {
        ParticleSet &s = sets[0];
        s.dim = dim;
        s.has_divv = false;
        s.has_lp = shape == ShapeKind::gimp;
        s.resize(n);
        std::mt19937 rng(seed);
        std::uniform_real_distribution<double> u(0.0, 1.0), sym(-1.0, 1.0);
        const GridGeometry &g = grid.geo;
        for (std::size_t p = 0; p < n; ++p) {
            for (int d = 0; d < dim; ++d) {
                const std::size_t dd = static_cast<std::size_t>(d);
                const double lo = g.origin[dd] + 3.0 * g.h;
                const double hi = g.origin[dd] + (g.cells[dd] - 3) * g.h;
                s.x[dd][p] = lo + (hi - lo) * u(rng);
                s.x0[dd][p] = s.x[dd][p];
                s.v[dd][p] = sym(rng);
            }
            s.id[p] = static_cast<std::int64_t>(p);
            s.mass[p] = 0.5 + u(rng);
            s.vol0[p] = (0.5 + u(rng)) * 1e-4;
            s.J[p] = 0.9 + 0.2 * u(rng);
            for (std::size_t c = 0; c < 6; ++c)
                s.stress[6 * p + c] = 1e3 * sym(rng);
            if (s.has_lp) s.lp[p] = 0.25;
            const double I[9] = {1, 0, 0, 0, 1, 0, 0, 0, 1};
            s.set_F(p, I);
        }
        order.prepare(sets, 0.01);
        loads.evaluate(0.0, 1e-3);
    }

  private:
    static Scenario scenario_of(int dim) {
        Scenario sc;
        sc.dim = dim;
        sc.cell = 0.05;
        return sc;
    }
    static Conditions conditions_of(const Vec3 &gravity) {
        Conditions c;
        c.gravity = gravity;
        return c;
    }
};

} // namespace talus::test
