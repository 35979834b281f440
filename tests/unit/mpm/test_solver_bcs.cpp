// Boundary conditions, loads and initial states, each against a closed form.
#include "solver_helpers.hpp"

#include <fmt/format.h>
#include <gtest/gtest.h>
#include <map>

using talus::test::advance;
using talus::test::contains;
using talus::test::sim_from_text;
using talus::test::totals;

namespace {

const char *kHead = "talus: 1\ndimension: 2\n"
                    "materials:\n  m: {model: linear_elastic, density: 1000, youngs_modulus: "
                    "1.0e6, poisson_ratio: 0.3}\n";

std::string block(const std::string &extra,
                  const std::string &box = "{min: [0.2, 0.0], max: [0.6, 0.2]}",
                  const std::string &grid = "{origin: [0, 0], size: [4, 1], cell: 0.05}") {
    return std::string(kHead) + "grid: " + grid + "\n" +
           "groups:\n  b: {material: m, particles_per_cell: 2, shape: {box: " + box + "}}\n" +
           extra + "time: {end: 10.0}\n";
}

double mean_v(const talus::Simulation &sim, int d) {
    const auto t = totals(sim);
    return t.p[d] / t.mass;
}

} // namespace

// A block sliding on a slip floor keeps its horizontal velocity: the slip
// condition removes only the normal component (to round-off).
TEST(BoundaryConditions, SlipFloorKeepsTangentialVelocity) {
    auto s = sim_from_text(block("boundaries: {y-: slip}\ngravity: [0, -9.81]\n"));
    for (auto &set : s->sim->sets())
        for (std::size_t p = 0; p < set.n; ++p)
            set.v[0][p] = 1.0;
    advance(*s->sim, 0.5);
    // Nothing acts tangentially: only round-off of ~1000 steps of momentum
    // sums moves the mean (1e-12 of 1 m/s).
    EXPECT_NEAR(mean_v(*s->sim, 0), 1.0, 1e-12);
    // It rests on the floor, bouncing elastically: static compression
    // rho g H^2 / 2M = 1.5e-4 m at omega = pi c / 2H = 290 rad/s is a
    // vertical velocity amplitude of 0.04 m/s; falling through would be -5.
    EXPECT_NEAR(mean_v(*s->sim, 1), 0.0, 0.05);
}

// A block sliding on a Coulomb floor decelerates at mu g: v(t) = v0 - mu g t
// until it stops. The bottom layer of nodes carries the whole contact, and
// the block's own elastic bounce modulates the normal force, so the mean
// velocity follows the closed form to a few percent of v0; 5 % is the bound.
TEST(BoundaryConditions, CoulombFrictionDeceleratesAtMuG) {
    const double mu = 0.3, g = 9.81, v0 = 1.0;
    auto s = sim_from_text(
        block(fmt::format("boundaries: {{y-: {{friction: {}}}}}\ngravity: [0, -{}]\n", mu, g)));
    for (auto &set : s->sim->sets())
        for (std::size_t p = 0; p < set.n; ++p)
            set.v[0][p] = v0;
    for (double t : {0.1, 0.2, 0.3}) {
        advance(*s->sim, t);
        EXPECT_NEAR(mean_v(*s->sim, 0), v0 - mu * g * t, 0.05 * v0) << "t = " << t;
    }
    advance(*s->sim, 0.6); // stopped at t = v0 / (mu g) = 0.34 s, and stays
    EXPECT_NEAR(mean_v(*s->sim, 0), 0.0, 0.02 * v0);
}

// A fixed face stops the nodes on it: a block dropped on a fixed floor under
// gravity stays above it and comes to rest (mean vertical velocity about
// zero; the remaining elastic oscillation is a few cm/s).
TEST(BoundaryConditions, FixedFaceHoldsItsNodes) {
    auto s = sim_from_text(block("boundaries: {y-: fixed}\ngravity: [0, -9.81]\n"));
    advance(*s->sim, 0.3);
    EXPECT_NEAR(mean_v(*s->sim, 1), 0.0, 0.05);
    double lowest = 1e9;
    for (const auto &set : s->sim->sets())
        for (std::size_t p = 0; p < set.n; ++p)
            lowest = std::min(lowest, set.x[1][p]);
    EXPECT_GT(lowest, 0.0);
}

// Prescribed nodal velocity on every node the block touches: the block moves
// rigidly with it, v = 0.5 t (a ramp), exactly.
TEST(BoundaryConditions, PrescribedNodalVelocityDrivesTheBlock) {
    auto s = sim_from_text(block("nodal_velocities:\n  - {box: {min: [0, 0], max: [4, 1]}, "
                                 "velocity: {x: [[0, 0], [1, 0.5]]}}\n",
                                 "{min: [1.0, 0.4], max: [1.4, 0.6]}"));
    advance(*s->sim, 0.4);
    // Every node the particles see is prescribed: PIC/FLIP interpolation of a
    // uniform field is exact (partition of unity), so round-off only.
    for (const auto &set : s->sim->sets())
        for (std::size_t p = 0; p < set.n; ++p) {
            ASSERT_NEAR(set.v[0][p], 0.5 * 0.4, 1e-12);
            ASSERT_NEAR(set.v[1][p], 0.0, 1e-12);
        }
}

// A particle velocity fixity holds the group's velocity and moves it by the
// integral of the prescribed function (trapezoidal, exact for linear).
TEST(BoundaryConditions, ParticleVelocityFixity) {
    auto s = sim_from_text(
        block("particle_velocities:\n  - {group: b, velocity: {x: [[0, 0], [1, 1.0]], y: 0.25}}\n",
              "{min: [1.0, 0.4], max: [1.4, 0.6]}"));
    advance(*s->sim, 0.5);
    // Set, not computed: round-off of the summed steps only.
    for (const auto &set : s->sim->sets())
        for (std::size_t p = 0; p < set.n; ++p) {
            ASSERT_NEAR(set.v[0][p], 0.5, 1e-12);
            ASSERT_NEAR(set.x[0][p] - set.x0[0][p], 0.5 * 0.5 * 0.5, 1e-12);
            ASSERT_NEAR(set.x[1][p] - set.x0[1][p], 0.25 * 0.5, 1e-12);
        }
}

// Loads on a free block without gravity: a point load F on every particle
// accelerates it at F/m; a traction t on every particle at t V0^(1/2) / m in
// 2D. Uniform loads keep the block stress-free, so these are exact.
TEST(Loads, PointLoadAndTractionAccelerateAsNewtonSays) {
    for (const char *kind : {"point", "traction"}) {
        auto s = sim_from_text(
            block(fmt::format("loads:\n  - {{group: b, {}: [2.0, [[0, 0], [1, -1.0]]]}}\n", kind),
                  "{min: [1.0, 0.4], max: [1.4, 0.6]}"));
        const auto &set0 = s->sim->sets()[0];
        const double m = set0.mass[0], V0 = set0.vol0[0];
        const double scale = std::string(kind) == "traction" ? std::sqrt(V0) : 1.0;
        advance(*s->sim, 0.2);
        // Forces act at the start of each step: v = sum F(t_k) dt / m. The
        // constant x-component integrates exactly (1e-9 allows round-off of
        // ~100 steps); the y-ramp -t is sampled at step starts.
        const double ax = 2.0 * scale / m;
        EXPECT_NEAR(mean_v(*s->sim, 0), ax * 0.2, 1e-9 * ax) << kind;
        // The ramp is sampled at the step starts: between -t^2/2 (exact
        // integral) and that minus one step's worth.
        const double ay_exact = -scale / m * 0.5 * 0.2 * 0.2;
        EXPECT_LE(mean_v(*s->sim, 1), ay_exact * 0.9) << kind;
        EXPECT_GE(mean_v(*s->sim, 1), ay_exact * 1.1) << kind;
    }
}

// Gravity with a ramp: g(t) = g min(1, t / T); v(t) = g t^2 / (2T) before T.
// Gravity is sampled at step starts (forward Euler on a linear ramp), which
// undershoots by g dt t / (2T): 2 % at the test's resolution.
TEST(Loads, GravityRamp) {
    auto s = sim_from_text(block("gravity: {value: [0, -10], ramp: 1.0}\n",
                                 "{min: [1.0, 0.4], max: [1.4, 0.6]}",
                                 "{origin: [0, -10], size: [4, 11], cell: 0.05}"));
    advance(*s->sim, 0.5);
    EXPECT_NEAR(mean_v(*s->sim, 1), -10.0 * 0.25 / 2.0, 0.02 * 1.25);
    advance(*s->sim, 1.2);
    EXPECT_NEAR(mean_v(*s->sim, 1), -10.0 * 0.5 - 10.0 * 0.2, 0.02 * 7.0);
}

// Geostatic initial stress: sigma_v = rho g (surface - y), sigma_h = K0
// sigma_v (xx and zz in plane strain), no shear, exactly at t = 0.
TEST(InitialState, GeostaticStress) {
    auto s = sim_from_text(std::string(kHead) +
                           "grid: {origin: [0, 0], size: [2, 2], cell: 0.1}\n"
                           "groups:\n  soil: {material: m, particles_per_cell: 2, shape: {box: "
                           "{min: [0, 0], max: [2, 1.5]}},\n"
                           "         initial_stress: {geostatic: {k0: 0.4}}}\n"
                           "boundaries: {y-: fixed}\ngravity: [0, -9.81]\ntime: {end: 1}\n");
    // Evaluated from the same formula: round-off of the largest stress,
    // 1.5e4 Pa, to 1e-9 relative.
    const auto &set = s->sim->sets()[0];
    for (std::size_t p = 0; p < set.n; ++p) {
        const double sv = -1000.0 * 9.81 * (1.5 - set.x[1][p]);
        ASSERT_NEAR(set.stress[6 * p + 1], sv, 1e-9 * 15000);
        ASSERT_NEAR(set.stress[6 * p + 0], 0.4 * sv, 1e-9 * 15000);
        ASSERT_NEAR(set.stress[6 * p + 2], 0.4 * sv, 1e-9 * 15000);
        ASSERT_EQ(set.stress[6 * p + 3], 0.0);
    }
}

// Leaving the grid: "stop" names the particles; "remove" deletes and counts.
TEST(LeavingGrid, StopNamesTheParticlesRemoveCountsThem) {
    const std::string base =
        std::string(kHead) +
        "grid: {origin: [0, 0], size: [1, 1], cell: 0.1}\n"
        "groups:\n  fast: {material: m, particles_per_cell: 1, velocity: [5, 0],\n"
        "         shape: {box: {min: [0.7, 0.4], max: [0.9, 0.6]}}}\n"
        "time: {end: 1}\n";
    auto stop = sim_from_text(base);
    try {
        advance(*stop->sim, 0.2);
        FAIL() << "expected the particles to leave";
    } catch (const talus::Error &e) {
        EXPECT_TRUE(
            contains(e.what(), "particle(s) left the grid (policy solver.leaving_grid: stop"))
            << e.what();
        EXPECT_TRUE(contains(e.what(), "of group 'fast' at (1.")) << e.what();
    }
    auto rm = sim_from_text(base + "solver: {leaving_grid: remove}\n");
    advance(*rm->sim, 0.2);
    EXPECT_EQ(rm->sim->particle_count(), 0u);
    EXPECT_EQ(rm->sim->diagnostics().removed, 4);
}

// A material that fails stops the run with plugin, group, particle and step.
TEST(MaterialFailure, NamesPluginGroupParticleAndStep) {
    try {
        auto s =
            sim_from_text("talus: 1\ndimension: 2\nplugins: [fixture_throws_sdk]\n"
                          "grid: {origin: [0, 0], size: [1, 1], cell: 0.1}\n"
                          "materials:\n  bad: {model: thrower, density: 1000, stiffness: 1.0e6}\n"
                          "groups:\n  lump: {material: bad, particles_per_cell: 1, shape: {box: "
                          "{min: [0.4, 0.4], max: [0.6, 0.6]}}}\n"
                          "time: {end: 1}\n",
                          {talus::test::fixture_dir()});
        FAIL() << "expected a failure";
    } catch (const talus::Error &e) {
        const std::string m = e.what();
        EXPECT_TRUE(contains(m, "material 'bad' (model 'thrower',")) << m;
        EXPECT_TRUE(contains(m, "fixture_throws_sdk.so) failed at particle 0 of group 'lump'"))
            << m;
        EXPECT_TRUE(contains(m, "step 1")) << m;
        EXPECT_TRUE(contains(m, "the model gave up on purpose")) << m;
    }
}

// Cut-step requests are honoured by sub-stepping the material: the picky
// fixture is linear elasticity refusing increments above 2e-4, so a run
// with it must match the same run with linear_elastic (sub-stepping a linear
// law is exact up to round-off: 1e-9 of the stress). The block starts one
// cell (0.05 m) above the fixed floor at 3 m/s and hits it at t = 0.0167 s;
// the impact stress is about rho c v = 1e5 Pa.
TEST(MaterialFailure, CutStepIsSubSteppedAndExact) {
    auto run = [](const std::string &model, const std::string &plugins) {
        auto s = sim_from_text(
            "talus: 1\ndimension: 2\n" + plugins +
                "grid: {origin: [0, 0], size: [1, 1], cell: 0.05}\n"
                "materials:\n  m: {model: " +
                model +
                ", density: 1000, youngs_modulus: 1.0e6, poisson_ratio: 0.3}\n"
                "groups:\n  b: {material: m, particles_per_cell: 2, velocity: [0, -3],\n"
                "      shape: {box: {min: [0.3, 0.05], max: [0.7, 0.3]}}}\n"
                "boundaries: {y-: fixed}\nsolver: {dt: 1.0e-4}\ntime: {end: 1}\n",
            {talus::test::fixture_dir()});
        advance(*s->sim, 0.025);
        return s;
    };
    auto a = run("linear_elastic", "");
    auto b = run("picky_elastic", "plugins: [fixture_cut_step]\n");
    EXPECT_GT(b->sim->diagnostics().cut_steps, 0);
    const auto &sa = a->sim->sets()[0];
    const auto &sb = b->sim->sets()[0];
    ASSERT_EQ(sa.n, sb.n);
    double smax = 0, diff = 0;
    for (std::size_t i = 0; i < 6 * sa.n; ++i) {
        smax = std::max(smax, std::abs(sa.stress[i]));
        diff = std::max(diff, std::abs(sa.stress[i] - sb.stress[i]));
    }
    EXPECT_GT(smax, 1e3);
    EXPECT_LT(diff, 1e-9 * smax);
}

// Particle generation keeps exactly the lattice points inside the shape:
// counted here independently (triangle by barycentric sign tests, cylinder
// by its equation) on the same lattice, (i + 1/2) h / ppc.
TEST(Generation, PolygonAndCylinderHoldTheirLatticePoints) {
    auto tri = sim_from_text(std::string(kHead) +
                             "grid: {origin: [0, 0], size: [2, 2], cell: 0.1}\n"
                             "groups:\n  t: {material: m, particles_per_cell: 2,\n"
                             "      shape: {polygon: [[0.1, 0.1], [1.9, 0.3], [0.7, 1.7]]}}\n"
                             "time: {end: 1}\n");
    auto side = [](double ax, double ay, double bx, double by, double px, double py) {
        return (bx - ax) * (py - ay) - (by - ay) * (px - ax);
    };
    // Points within round-off of an edge may fall either way (the solver's
    // even-odd rule and this sign test round differently): count them apart.
    std::size_t expect = 0, on_edge = 0;
    for (int i = 0; i < 40; ++i)
        for (int j = 0; j < 40; ++j) {
            const double x = (i + 0.5) * 0.05, y = (j + 0.5) * 0.05;
            const double a = side(0.1, 0.1, 1.9, 0.3, x, y), b = side(1.9, 0.3, 0.7, 1.7, x, y),
                         c = side(0.7, 1.7, 0.1, 0.1, x, y);
            if (std::min({std::abs(a), std::abs(b), std::abs(c)}) < 1e-12)
                ++on_edge;
            else if ((a > 0 && b > 0 && c > 0) || (a < 0 && b < 0 && c < 0))
                ++expect;
        }
    EXPECT_GE(tri->sim->particle_count(), expect);
    EXPECT_LE(tri->sim->particle_count(), expect + on_edge);
    // The particles' volume approaches the triangle's area (1.5) as the
    // lattice refines: within the boundary cells' share, 10 %.
    EXPECT_NEAR(static_cast<double>(expect) * 0.05 * 0.05, 1.5, 0.15);

    auto cyl = sim_from_text(
        "talus: 1\ndimension: 3\n"
        "materials:\n  m: {model: linear_elastic, density: 1000, youngs_modulus: 1.0e6, "
        "poisson_ratio: 0.3}\n"
        "grid: {origin: [0, 0, 0], size: [1, 1, 1], cell: 0.1}\n"
        "groups:\n  c: {material: m, particles_per_cell: 2,\n"
        "      shape: {cylinder: {center: [0.5, 0.5, 0.5], radius: 0.3, axis: y, length: 0.6}}}\n"
        "time: {end: 1}\n");
    std::size_t n = 0;
    for (int i = 0; i < 20; ++i)
        for (int j = 0; j < 20; ++j)
            for (int k = 0; k < 20; ++k) {
                const double x = (i + 0.5) * 0.05, y = (j + 0.5) * 0.05, z = (k + 0.5) * 0.05;
                if ((x - 0.5) * (x - 0.5) + (z - 0.5) * (z - 0.5) <= 0.09 && y >= 0.2 && y <= 0.8)
                    ++n;
            }
    EXPECT_EQ(cyl->sim->particle_count(), n);
}

// A uniform initial stress is set as given on every particle.
TEST(InitialState, UniformStress) {
    auto s = sim_from_text(
        std::string(kHead) +
        "grid: {origin: [0, 0], size: [1, 1], cell: 0.1}\n"
        "groups:\n  g: {material: m, shape: {box: {min: [0.2, 0.2], max: [0.6, 0.6]}},\n"
        "      initial_stress: {uniform: [-1, -2, -3, 4, 0, 0]}}\n"
        "time: {end: 1}\n");
    const auto &set = s->sim->sets()[0];
    const double given[6] = {-1, -2, -3, 4, 0, 0};
    for (std::size_t p = 0; p < set.n; ++p)
        for (std::size_t c = 0; c < 6; ++c)
            ASSERT_EQ(set.stress[6 * p + c], given[c]);
}

// Fields given as expressions of position (docs/scenario-reference.md,
// "Expressions"): each particle's stress, velocity and initial state equal
// the expression's closed form at its initial position. The expression and
// the test evaluate the same formula in double precision, in a different
// order: 1e-12 of each field's largest value bounds the round-off.
TEST(InitialState, FieldsGivenAsExpressionsOfPosition) {
    auto s = sim_from_text(
        "talus: 1\ndimension: 2\nconstants: {H: 1.5, rho: 2000, g: 9.81, w: 0.4}\n"
        "materials:\n  m: {model: mohr_coulomb, density: 2000, youngs_modulus: 5.0e7, "
        "poisson_ratio: 0.3, friction_angle: 30, cohesion: 1.0e5}\n"
        "grid: {origin: [0, 0], size: [2, 2], cell: 0.1}\n"
        "groups:\n  soil:\n    material: m\n"
        "    shape: {box: {min: [0, 0], max: [2, 1.5]}}\n"
        "    velocity: [\"w*y\", \"-w*x\"]\n"
        "    initial_stress: {field: {yy: \"-rho*g*(H - y)\", xx: \"-0.5*rho*g*(H - y)\", "
        "xy: \"100*sin(pi*x)\"}}\n"
        "    initial_state: {plastic_deviatoric_strain: \"y < x ? 0.01*x : 0\"}\n"
        "time: {end: 1}\n");
    const auto &set = s->sim->sets()[0];
    ASSERT_EQ(set.n, 1200u);
    const std::size_t eps = 0; // plastic_deviatoric_strain: the first variable
    ASSERT_EQ(set.state_size > 0, true);
    int band = 0;
    for (std::size_t p = 0; p < set.n; ++p) {
        const double x = set.x[0][p], y = set.x[1][p];
        const double sv = -2000.0 * 9.81 * (1.5 - y);
        ASSERT_NEAR(set.v[0][p], 0.4 * y, 1e-12 * 0.8);
        ASSERT_NEAR(set.v[1][p], -0.4 * x, 1e-12 * 0.8);
        ASSERT_NEAR(set.stress[6 * p + 1], sv, 1e-12 * 3e4);
        ASSERT_NEAR(set.stress[6 * p + 0], 0.5 * sv, 1e-12 * 3e4);
        ASSERT_EQ(set.stress[6 * p + 2], 0.0);
        ASSERT_NEAR(set.stress[6 * p + 3], 100.0 * std::sin(M_PI * x), 1e-12 * 100.0);
        const double q = set.state[p * set.state_size + eps];
        ASSERT_NEAR(q, y < x ? 0.01 * x : 0.0, 1e-12 * 0.02);
        band += q > 0.0;
    }
    EXPECT_GT(band, 100); // the conditional took both branches
    EXPECT_LT(band, 1100);
}

// Cell-averaged dilation (eqs. 52-53): after one step every point of a cell
// has the same volumetric strain increment, equal to the volume-weighted
// mean of the increments the points would have had without averaging (the
// run without the option); the deviatoric part is untouched. A block with a
// non-uniform velocity field gives non-trivial dilation. The increments are
// read back from the stress: from zero stress, one linear elastic step in
// plane strain gives sxx + syy = 2 (lambda + mu) (dexx + deyy),
// sxx - syy = 2 mu (dexx - deyy) and sxy = mu gxy. Round-off: 1e-12 of the
// increments (a few operations on each side).
TEST(CellAveragedDilation, EachCellGetsItsVolumeWeightedMeanDilation) {
    const std::string yaml = std::string(kHead) +
                             "grid: {origin: [0, 0], size: [1, 1], cell: 0.1}\n"
                             "groups:\n  g: {material: m, particles_per_cell: 3, shape: {box: "
                             "{min: [0.2, 0.2], max: [0.8, 0.8]}}}\n"
                             "time: {end: 1}\n";
    auto plain = sim_from_text(yaml + "solver: {scheme: musl, dt: 1.0e-4}\n");
    auto avg =
        sim_from_text(yaml + "solver: {scheme: musl, dt: 1.0e-4, cell_averaged_dilation: true}\n");
    for (auto *sim : {plain->sim.get(), avg->sim.get()})
        for (auto &set : sim->sets())
            for (std::size_t p = 0; p < set.n; ++p) {
                const double x = set.x[0][p], y = set.x[1][p];
                set.v[0][p] = std::sin(7.0 * x) * std::cos(3.0 * y);
                set.v[1][p] = 0.5 * std::cos(5.0 * x * y);
            }
    plain->sim->step(1.0);
    avg->sim->step(1.0);
    const auto &a = plain->sim->sets()[0];
    const auto &b = avg->sim->sets()[0];
    const double E = 1.0e6, nu = 0.3; // kHead's material
    const double lambda = E * nu / ((1.0 + nu) * (1.0 - 2.0 * nu)), mu = E / (2.0 * (1.0 + nu));
    auto volumetric = [&](const talus::ParticleSet &s, std::size_t p) {
        return (s.stress[6 * p] + s.stress[6 * p + 1]) / (2.0 * (lambda + mu));
    };
    auto deviatoric = [&](const talus::ParticleSet &s, std::size_t p) {
        return (s.stress[6 * p] - s.stress[6 * p + 1]) / (2.0 * mu);
    };
    auto shear = [&](const talus::ParticleSet &s, std::size_t p) {
        return s.stress[6 * p + 3] / mu;
    };
    // Group by the cell that held the point at the start of the step.
    std::map<int, std::vector<std::size_t>> cells;
    for (std::size_t p = 0; p < a.n; ++p) {
        const int cx = static_cast<int>(std::floor((a.x[0][p] - a.dx[0][p]) / 0.1));
        const int cy = static_cast<int>(std::floor((a.x[1][p] - a.dx[1][p]) / 0.1));
        cells[cx + 100 * cy].push_back(p);
    }
    double worst = 0.0, scale = 0.0, spread = 0.0;
    for (const auto &[key, pts] : cells) {
        double num = 0.0, den = 0.0;
        for (std::size_t p : pts) {
            num += volumetric(a, p) * a.J[p] * a.vol0[p];
            den += a.J[p] * a.vol0[p];
        }
        const double mean = num / den;
        for (std::size_t p : pts) {
            worst = std::max(worst, std::abs(volumetric(b, p) - mean));
            scale = std::max(scale, std::abs(volumetric(a, p)));
            spread = std::max(spread, std::abs(volumetric(a, p) - mean));
            // Deviatoric parts unchanged: the difference of the normal
            // components and the shear.
            ASSERT_NEAR(deviatoric(b, p), deviatoric(a, p), 1e-12 * scale + 1e-300);
            ASSERT_NEAR(shear(b, p), shear(a, p), 1e-12 * scale + 1e-300);
        }
    }
    EXPECT_GT(spread, 1e-3 * scale) << "the test field must vary within cells";
    EXPECT_LT(worst, 1e-12 * scale);
}

// The stress work (trapezoidal: the rotated start stress and the end
// stress on the step's strain increment), with and without cell-averaged
// dilation, which changes the increment after the kinematics. For linear
// elasticity the increment is C^-1 (s_end - R s_start), so a step's work is
// J V (s_end + R s_start) . C^-1 (s_end - R s_start) / 2 = J V (phi(s_end)
// - phi(s_start)) / 2 with phi(s) = s . C^-1 s, which a rotation does not
// change (isotropy; Hughes-Winget's R is orthogonal). Two steps from zero
// stress, so that the start stress of the second is not zero. Round-off:
// 1e-10 of the work, a few dozen operations on values of one sign (phi).
TEST(CellAveragedDilation, StressWorkIsTheElasticEnergyOfTheCorrectedIncrement) {
    const std::string yaml = std::string(kHead) +
                             "grid: {origin: [0, 0], size: [1, 1], cell: 0.1}\n"
                             "groups:\n  g: {material: m, particles_per_cell: 3, shape: {box: "
                             "{min: [0.2, 0.2], max: [0.8, 0.8]}}}\n"
                             "time: {end: 1}\n";
    const double E = 1.0e6, nu = 0.3, mu = E / (2.0 * (1.0 + nu)); // kHead's material
    auto phi = [&](const double *s) {
        const double exx = (s[0] - nu * (s[1] + s[2])) / E, eyy = (s[1] - nu * (s[0] + s[2])) / E,
                     ezz = (s[2] - nu * (s[0] + s[1])) / E;
        return s[0] * exx + s[1] * eyy + s[2] * ezz +
               (s[3] * s[3] + s[4] * s[4] + s[5] * s[5]) / mu;
    };
    for (const bool averaged : {false, true}) {
        auto run = sim_from_text(yaml + "solver: {scheme: musl, dt: 1.0e-4" +
                                 (averaged ? ", cell_averaged_dilation: true" : "") + "}\n");
        auto &set = run->sim->sets()[0];
        for (std::size_t p = 0; p < set.n; ++p) {
            const double x = set.x[0][p], y = set.x[1][p];
            set.v[0][p] = std::sin(7.0 * x) * std::cos(3.0 * y);
            set.v[1][p] = 0.5 * std::cos(5.0 * x * y);
        }
        std::vector<double> expected(set.n), phi1(set.n);
        run->sim->step(1.0);
        for (std::size_t p = 0; p < set.n; ++p) {
            phi1[p] = phi(&set.stress[6 * p]);
            expected[p] = 0.5 * set.J[p] * set.vol0[p] * phi1[p];
        }
        run->sim->step(1.0);
        double worst = 0.0, scale = 0.0;
        for (std::size_t p = 0; p < set.n; ++p) {
            expected[p] += 0.5 * set.J[p] * set.vol0[p] * (phi(&set.stress[6 * p]) - phi1[p]);
            worst = std::max(worst, std::abs(set.work[p] - expected[p]));
            scale = std::max(scale, std::abs(expected[p]));
        }
        EXPECT_GT(scale, 0.0);
        EXPECT_LT(worst, 1e-10 * scale) << (averaged ? "averaged dilation" : "plain");
    }
}

// The inversion message names the failing Jacobian, not the last valid one:
// a block resting on a fixed floor and thrown into it at 200 m/s (the
// crushing is faster than any step can follow) inverts a particle; the J
// printed must be <= 0.
TEST(MaterialFailure, InversionReportsTheFailingJacobian) {
    auto s = sim_from_text(std::string(kHead) +
                           "grid: {origin: [0, 0], size: [1, 1], cell: 0.05}\n"
                           "groups:\n  b: {material: m, particles_per_cell: 2, velocity: [0, "
                           "-200], shape: {box: {min: [0.3, 0.0], max: [0.7, 0.2]}}}\n"
                           "boundaries: {y-: fixed}\ntime: {end: 1}\n");
    std::string msg;
    try {
        advance(*s->sim, 0.05);
    } catch (const talus::Error &e) {
        msg = e.what();
    }
    ASSERT_TRUE(contains(msg, "inverted (J = ")) << msg;
    const double J = std::stod(msg.substr(msg.find("(J = ") + 5));
    EXPECT_LE(J, 0.0) << msg;
}

// A particle fixity holds the body it belongs to: a plate whose left column
// of particles is fixed (away from any grid face) and whose right end is
// pulled by a suddenly applied traction sigma must oscillate about its
// static elongation, not tear off and drift. Before the fixity acted on the
// grid, the tip moved 0.23 m in 0.3 s and the plate's centre of mass left at
// 1.8 m/s. Reference: a bar fixed at one end under a step end load; the end
// displacement oscillates between 0 and 2 sigma L / E (dynamic factor 2,
// undamped); measured 0.0009 .. 0.0186 m in every scheme. The clamped zone
// reaches one kernel support (up to 1.5 cells) past the fixed column, so the
// free length L is between 1 - 0.025 - 2 h and 1 m: that range, not a fitted
// number, is the tolerance on the peak.
TEST(ParticleFixity, HoldsTheBodyAgainstALoad) {
    for (const char *scheme : {"usl", "usf", "musl"}) {
        auto s = sim_from_text(
            std::string("talus: 1\ndimension: 2\n"
                        "grid: {origin: [0, 0], size: [1.6, 0.4], cell: 0.05}\n"
                        "materials:\n  m: {model: linear_elastic, density: 1000, youngs_modulus: "
                        "1.0e6, poisson_ratio: 0.0}\n"
                        "groups:\n  plate: {material: m, shape: {box: {min: [0.3, 0.15], max: "
                        "[1.3, 0.25]}}}\n"
                        "particle_velocities:\n  - {group: plate, box: {min: [0.3, 0], max: "
                        "[0.325, 1]}, velocity: {x: 0, y: 0}}\n"
                        "loads:\n  - {group: plate, box: {min: [1.275, 0], max: [1.3, 1]}, "
                        "traction: [1.0e4, 0]}\n"
                        "solver: {scheme: ") +
            scheme + "}\ntime: {end: 1}\n");
        const auto &set = s->sim->sets()[0];
        std::vector<std::size_t> tip;
        for (std::size_t p = 0; p < set.n; ++p)
            if (set.x[0][p] > 1.275) tip.push_back(p);
        ASSERT_FALSE(tip.empty());
        const std::int64_t tip_id = set.id[tip[0]];
        const double x0 = set.x[0][tip[0]];
        // hi: the largest tip displacement; lo: the smallest after the
        // first period 4 L / c = 0.127 s (c = sqrt(E / rho) = 31.6 m/s).
        double lo = 1.0, hi = 0.0;
        // 0.3 s: two and a half periods of the fixed-free bar.
        advance(*s->sim, 0.3, [&] {
            const auto &st = s->sim->sets()[0];
            for (std::size_t p = 0; p < st.n; ++p)
                if (st.id[p] == tip_id) {
                    hi = std::max(hi, st.x[0][p] - x0);
                    if (s->sim->time() > 0.13) lo = std::min(lo, st.x[0][p] - x0);
                }
        });
        const double sL_E = 1.0e4 / 1.0e6; // sigma L / E for L = 1 m
        EXPECT_GT(hi, 2.0 * sL_E * (1.0 - 0.025 - 2 * 0.05)) << scheme;
        EXPECT_LT(hi, 2.0 * sL_E) << scheme;
        // Held, not drifting: after a period the tip comes back towards its
        // start. The exact minimum is 0; the bound is a quarter of the
        // amplitude, so it passes with the wave's dispersion on this coarse
        // grid (the peak is smeared) and fails for any drift of more than
        // half the static elongation.
        EXPECT_LT(lo, 0.25 * 2.0 * sL_E) << scheme;
    }
}
