// A step resets and updates only the grid nodes its particles reach: a box
// around the cells the last step left them in (Grid::reach,
// SolverOptions::active_nodes_only). Were a stencil to reach past that box,
// a particle would scatter into a node the step never clears or updates
// and read back a velocity from an earlier step: a wrong result nobody
// would see. The reference is the same run over every node, which must
// give the same bits, in every scheme, shape and condition that writes to
// the grid; each run must also have worked on far fewer nodes than the
// grid holds, or the comparison would show nothing.
#include "method/boundary.hpp"
#include "method/grid_update.hpp"
#include "solver_helpers.hpp"
#include "state/grid.hpp"

#include <talus/mpm/shape_functions.hpp>

#include <gtest/gtest.h>

#include <omp.h>

#include <algorithm>
#include <cstdint>
#include <functional>
#include <limits>
#include <memory>
#include <random>
#include <string>

namespace {

// Every node of every kernel's stencil, from any position in a cell and on
// the far face, lies in the box Grid::reach gives for that cell.
template <class S>
void expect_stencils_in_reach(const talus::Grid &grid, double lp) {
    const int n = grid.geo.cells[0];
    for (int k = 0; k <= 64 * n; ++k) {
        const double xi = k / 64.0; // 0, 1/64, ..., n: every part of a cell, both faces
        int base = 0;
        double w[4], dw[4], g[4];
        S::eval_bounded(xi, lp, n, base, w, dw, g);
        const int c = talus::GridGeometry::clamped_cell(xi, n);
        const talus::SlotBox box = grid.reach({c, 0, 0}, {c, 0, 0});
        const int first = base - grid.geo.first[0], last = first + S::width - 1;
        EXPECT_GE(first, box.lo[0]) << "xi " << xi;
        EXPECT_LT(last, box.hi[0]) << "xi " << xi;
    }
}

TEST(ActiveNodes, ReachHoldsEveryKernelsStencil) {
    using talus::ShapeKind;
    for (const ShapeKind kind :
         {ShapeKind::linear, ShapeKind::gimp, ShapeKind::bspline2, ShapeKind::bspline3}) {
        const talus::Grid grid(2, {0.0, 0.0, 0.0}, {1.2, 1.2, 0.0}, 0.1, kind);
        SCOPED_TRACE(std::string(talus::shape_name(kind)));
        switch (kind) {
        case ShapeKind::linear: expect_stencils_in_reach<talus::LinearShape>(grid, 0.0); break;
        case ShapeKind::gimp:
            // lp up to half a cell (one particle per cell).
            for (const double lp : {0.5, 0.25, 1.0 / 6.0})
                expect_stencils_in_reach<talus::GimpShape>(grid, lp);
            break;
        case ShapeKind::bspline2: expect_stencils_in_reach<talus::BSpline2Shape>(grid, 0.0); break;
        case ShapeKind::bspline3: expect_stencils_in_reach<talus::BSpline3Shape>(grid, 0.0); break;
        }
    }
}

TEST(ActiveNodes, ReachIsCutToTheHeldNodesAndEmptyWithoutParticles) {
    const talus::Grid grid(3, {0.0, 0.0, 0.0}, {1.0, 0.5, 0.3}, 0.1, talus::ShapeKind::bspline2);
    const talus::SlotBox all = grid.reach({0, 0, 0}, {9, 4, 2});
    EXPECT_EQ(all.nodes(), grid.n_nodes); // particles in every cell: every node
    const int none = std::numeric_limits<int>::max();
    EXPECT_TRUE(grid.reach({none, none, none}, {-1, -1, -1}).empty());
    EXPECT_EQ(grid.reach({none, none, none}, {-1, -1, -1}).nodes(), 0u);
}

// The reset clears where the last step's particles reached, not where the
// next step's will: a step after a smaller or moved box must find every
// accumulator zero (Simulation::grid_mass sums them all).
TEST(ActiveNodes, ResetClearsWhereTheLastStepWrote) {
    talus::Grid grid(2, {0.0, 0.0, 0.0}, {2.0, 1.0, 0.0}, 0.1, talus::ShapeKind::bspline2);
    const talus::SlotBox a = grid.reach({2, 2, 0}, {5, 4, 0}),
                         b = grid.reach({14, 5, 0}, {16, 7, 0});
    ASSERT_TRUE(a.cut(b).empty());
    grid.reset(a);
    for (std::size_t r = 0; r < a.rows(); ++r)
        for (std::size_t i = a.row_begin(r, grid.geo.extent);
             i < a.row_begin(r, grid.geo.extent) + a.row_length(); ++i)
            for (std::size_t f = 0; f < talus::node::kRecord; ++f)
                grid.acc[talus::node::kRecord * i + f] = 1.0; // as a P2G would
    EXPECT_EQ(grid.mass(), static_cast<double>(a.nodes()));
    grid.reset(b);
    EXPECT_TRUE(std::all_of(grid.acc.begin(), grid.acc.end(), [](double v) { return v == 0.0; }));
    EXPECT_EQ(grid.active().nodes(), b.nodes());
}

// A grid update after which the step reads the accumulators no more
// (Accumulators::clear) clears them as it reads them, so that the next
// reset has nothing to do. The reference is the same update keeping them:
// the velocities must come out the same bits (a node cleared before a
// condition read its mass or force would differ), the accumulators must be
// zero everywhere afterwards and each node's mass found where the update
// left it. With prescribed velocities or fixities the pass cannot tell
// their nodes, and must leave the accumulators as they are.
void expect_clearing_update_as_keeping(const std::string &conditions, int dim, bool faces_only,
                                       const talus::DampingSpec &damping = {}) {
    SCOPED_TRACE(conditions);
    const std::string yaml =
        "talus: 1\ndimension: " + std::to_string(dim) + "\n" +
        (dim == 2 ? "grid: {origin: [0, 0], size: [1, 0.6], cell: 0.05}\n"
                  : "grid: {origin: [0, 0, 0], size: [0.5, 0.4, 0.3], cell: 0.05}\n") +
        "materials:\n  m: {model: linear_elastic, density: 1000, youngs_modulus: 1.0e4, "
        "poisson_ratio: 0.3}\n"
        "groups:\n  a: {material: m, shape: {box: {min: [0.1, 0.1" +
        (dim == 3 ? ", 0.1" : "") + "], max: [0.3, 0.3" + (dim == 3 ? ", 0.2" : "") + "]}}}\n" +
        conditions + "time: {end: 1}\n";
    talus::PluginRegistry registry;
    const talus::Scenario sc =
        talus::read_scenario(talus::yaml::load_string(yaml, "t.yaml"), registry);
    talus::Grid grid(dim, sc.origin, sc.size, sc.cell, sc.solver.shape);
    const talus::Boundary bc(sc, sc.conditions, grid, 0.0);
    ASSERT_EQ(bc.faces_only(), faces_only);
    const int last = dim == 2 ? 19 : 9;
    // The whole grid (every face layer), a box on the low faces, one inside.
    for (const talus::SlotBox &box :
         {grid.all(), grid.reach({0, 0, 0}, {4, 3, dim == 3 ? 2 : 0}),
          grid.reach({4, 4, dim == 3 ? 2 : 0}, {last - 4, 6, dim == 3 ? 3 : 0})}) {
        grid.reset(box);
        std::mt19937 rng(7);
        std::uniform_real_distribution<double> u(-1.0, 1.0);
        box.for_each_slot(grid.geo.extent, [&](std::size_t i) {
            double *a = &grid.acc[talus::node::kRecord * i];
            for (std::size_t f = 0; f < talus::node::kRecord; ++f)
                a[f] = u(rng);
            // A node no particle weighs on may still carry a gradient's force.
            a[talus::node::kMass] =
                a[talus::node::kMass] < -0.5 ? 0.0 : 1.0 + a[talus::node::kMass];
            // Fixity bits as a P2G leaves them: none without fixities.
            a[talus::node::kFixity] = faces_only ? 0.0 : static_cast<double>(i % 4);
        });
        talus::Grid keep = grid;
        talus::grid_update(keep, bc, 0.1, 1e-3, damping, talus::Accumulators::keep);
        talus::grid_update(grid, bc, 0.1, 1e-3, damping, talus::Accumulators::clear);
        const std::size_t vs = talus::node::velocity(dim);
        std::size_t differ = 0;
        box.for_each_slot(grid.geo.extent, [&](std::size_t i) {
            for (std::size_t d = 0; d < static_cast<std::size_t>(dim); ++d)
                for (std::size_t at : {talus::node::kEndVelocity + d, vs + d}) {
                    const std::size_t k = talus::node::kRecord * i + at;
                    differ += grid.vel[k] != keep.vel[k];
                }
        });
        EXPECT_EQ(differ, 0u);
        for (std::size_t i = 0; i < grid.n_nodes; ++i)
            ASSERT_EQ(grid.node_mass(i), keep.acc[talus::node::kRecord * i + talus::node::kMass])
                << "node " << i;
        EXPECT_EQ(grid.mass(), keep.mass());
        if (faces_only)
            EXPECT_TRUE(
                std::all_of(grid.acc.begin(), grid.acc.end(), [](double v) { return v == 0.0; }));
        else
            EXPECT_TRUE(grid.acc == keep.acc);
    }
}

TEST(ActiveNodes, AClearingGridUpdateGivesTheSameVelocities) {
    expect_clearing_update_as_keeping("", 2, true);
    expect_clearing_update_as_keeping("boundaries: {x-: fixed, x+: slip, y-: {friction: 0.3}}\n", 2,
                                      true, {talus::DampingKind::local, 0.1});
    expect_clearing_update_as_keeping(
        "boundaries: {x-: slip, x+: fixed, y-: {friction: 0.5}, y+: slip, z-: fixed, z+: "
        "{friction: 0.2}}\nsolver: {shape: bspline3}\n",
        3, true, {talus::DampingKind::viscous, 2.0});
    expect_clearing_update_as_keeping(
        "boundaries: {y-: fixed}\nsolver: {shape: linear}\n"
        "nodal_velocities: [{box: {min: [0.6, 0.2], max: [0.7, 0.3]}, velocity: {x: 1.0}}]\n",
        2, false);
    expect_clearing_update_as_keeping(
        "boundaries: {y-: fixed}\nparticle_velocities:\n  - {group: a, velocity: {y: 0.2}}\n", 2,
        false);
}

struct Run {
    std::unique_ptr<talus::test::Sim> s;
    std::size_t fewest = std::numeric_limits<std::size_t>::max(); // active nodes, fewest in a step
};

// Steps to `end` (through its stages, if it has any), on two threads.
// `each` after every step.
Run run(const std::string &yaml, bool active_only, double end,
        const std::function<void(talus::Simulation &)> &each) {
    Run r;
    r.s = talus::test::sim_from_text(yaml);
    talus::SolverOptions opt;
    opt.threads = 2;
    opt.active_nodes_only = active_only;
    r.s->sim = std::make_unique<talus::Simulation>(r.s->scenario, opt);
    talus::Simulation &sim = *r.s->sim;
    while (sim.time() < end * (1.0 - 1e-12)) {
        if (sim.stage_end_reached() != talus::StageEnd::running) sim.begin_next_stage();
        sim.step(std::min(end, sim.stage_end()) - sim.time());
        r.fewest = std::min(r.fewest, sim.active_nodes());
        if (each) each(sim);
    }
    return r;
}

void expect_same_bits(const std::string &yaml, double end,
                      const std::function<void(talus::Simulation &)> &each = {}) {
    const int before = omp_get_max_threads();
    const Run all = run(yaml, false, end, each);
    const Run active = run(yaml, true, end, each);
    omp_set_num_threads(before);
    const talus::Simulation &a = *all.s->sim, &b = *active.s->sim;
    // The reference worked on every node; the other on at most a third of
    // them at some step (the bodies below fill a small part of their grid).
    EXPECT_EQ(all.fewest, a.grid_nodes());
    EXPECT_LT(3 * active.fewest, b.grid_nodes());
    ASSERT_GT(a.steps(), 50);
    EXPECT_EQ(a.steps(), b.steps());
    EXPECT_EQ(a.time(), b.time());
    // Summed over every node in the same order: equal only if the
    // accumulators outside the last active box are zero, as the reset
    // keeps them.
    EXPECT_EQ(a.grid_mass(), b.grid_mass());
    ASSERT_EQ(a.sets().size(), b.sets().size());
    for (std::size_t k = 0; k < a.sets().size(); ++k) {
        const talus::ParticleSet &p = a.sets()[k], &q = b.sets()[k];
        ASSERT_EQ(p.n, q.n);
        ASSERT_GT(p.n, 0u);
        EXPECT_TRUE(p.id == q.id);
        for (std::size_t d = 0; d < 3; ++d) {
            EXPECT_TRUE(p.x[d] == q.x[d]) << "x, axis " << d;
            EXPECT_TRUE(p.v[d] == q.v[d]) << "v, axis " << d;
        }
        EXPECT_TRUE(p.stress == q.stress);
        EXPECT_TRUE(p.F == q.F);
        EXPECT_TRUE(p.C == q.C);
        EXPECT_TRUE(p.work == q.work);
    }
}

// A soft disk thrown across a wide grid onto a rough floor: it crosses 20
// cells and its box moves with it. The prescribed nodal velocity's box
// lies where the disk arrives late in the run (its nodes join the active
// box then, after steps in which the condition was not applied to them).
TEST(ActiveNodes, UslFlipDiskThrownAcrossTheGrid) {
    expect_same_bits(
        "talus: 1\ndimension: 2\ngrid: {origin: [0, 0], size: [2, 1], cell: 0.025}\n"
        "materials:\n  m: {model: linear_elastic, density: 1000, youngs_modulus: 1.0e4, "
        "poisson_ratio: 0.3}\n"
        "groups:\n  a: {material: m, velocity: [2.0, -1.0],\n"
        "      shape: {sphere: {center: [0.4, 0.5], radius: 0.15}}}\n"
        "boundaries: {y-: {friction: 0.3}, x+: slip}\ngravity: [0, -9.81]\n"
        "nodal_velocities:\n  - {box: {min: [0.95, 0], max: [1.1, 0.2]}, velocity: {y: 0.1}}\n"
        "solver: {transfer: {type: flip, alpha: 0.95}}\ntime: {end: 1}\n",
        0.3);
}

// MUSL remaps the particle momentum to the grid and applies the conditions
// to that velocity too, kept in the P2G accumulators. The first stage
// prescribes a nodal velocity ahead of the body, the second none; the body
// reaches those nodes in the second stage (after about 0.13 s). APIC,
// linear tents, viscous damping and a particle fixity (of the vertical
// velocity alone).
TEST(ActiveNodes, MuslApicWithFixityAndDamping) {
    expect_same_bits(
        "talus: 1\ndimension: 2\ngrid: {origin: [0, 0], size: [2, 1], cell: 0.025}\n"
        "materials:\n  m: {model: linear_elastic, density: 1000, youngs_modulus: 1.0e4, "
        "poisson_ratio: 0.3}\n"
        "groups:\n  a: {material: m, velocity: [1.5, 0.5],\n"
        "      shape: {box: {min: [0.2, 0.3], max: [0.5, 0.5]}}}\n"
        "particle_velocities:\n  - {group: a, velocity: {y: 0.2}}\n"
        "boundaries: {y-: slip, y+: fixed}\n"
        "damping: {type: viscous, coefficient: 2}\n"
        "solver: {scheme: musl, transfer: apic, shape: linear}\n"
        "stages:\n"
        "  - name: prescribed\n    duration: 0.08\n"
        "    nodal_velocities: [{box: {min: [0.75, 0.3], max: [0.85, 0.5]}, velocity: {x: 1.0}}]\n"
        "  - {name: free, duration: 0.17, nodal_velocities: []}\n",
        0.25);
}

// USF and USAVG (their grid velocity before the forces), with GIMP and the
// cubic B-spline; local damping.
TEST(ActiveNodes, UsfGimpAndUsavgCubic) {
    for (const char *solver : {"{scheme: usf, shape: gimp}", "{scheme: usavg, shape: bspline3}"}) {
        SCOPED_TRACE(solver);
        expect_same_bits(
            std::string("talus: 1\ndimension: 2\ngrid: {origin: [0, 0], size: [2, 1], cell: "
                        "0.025}\n"
                        "materials:\n  m: {model: linear_elastic, density: 1000, youngs_modulus: "
                        "1.0e4, poisson_ratio: 0.3}\n"
                        "groups:\n  a: {material: m, velocity: [-2.0, -0.5],\n"
                        "      shape: {sphere: {center: [1.5, 0.4], radius: 0.12}}}\n"
                        "boundaries: {y-: {friction: 0.5}, x-: fixed}\ngravity: [0, -9.81]\n"
                        "damping: {type: local, coefficient: 0.05}\n"
                        "solver: ") +
                solver + "\ntime: {end: 1}\n",
            0.2);
    }
}

// 3D: a sphere thrown along a long grid onto a rough floor.
TEST(ActiveNodes, UslSphereIn3D) {
    expect_same_bits(
        "talus: 1\ndimension: 3\ngrid: {origin: [0, 0, 0], size: [1.6, 0.6, 0.6], cell: 0.05}\n"
        "materials:\n  m: {model: linear_elastic, density: 1000, youngs_modulus: 1.0e4, "
        "poisson_ratio: 0.3}\n"
        "groups:\n  a: {material: m, velocity: [2.0, 0.3, -0.5],\n"
        "      shape: {sphere: {center: [0.3, 0.3, 0.25], radius: 0.12}}}\n"
        "boundaries: {z-: {friction: 0.3}}\ngravity: [0, 0, -9.81]\n"
        "solver: {transfer: apic}\ntime: {end: 1}\n",
        0.25);
}

// A stage that activates a group far from the first: the next step's box
// is not the last step's (the stage forgets it), and the run over every
// node agrees.
TEST(ActiveNodes, AStageActivatesAGroupElsewhere) {
    expect_same_bits(
        "talus: 1\ndimension: 2\ngrid: {origin: [0, 0], size: [2, 1], cell: 0.025}\n"
        "materials:\n  m: {model: linear_elastic, density: 1000, youngs_modulus: 1.0e4, "
        "poisson_ratio: 0.3}\n"
        "groups:\n  a: {material: m, shape: {box: {min: [0.1, 0], max: [0.4, 0.2]}}}\n"
        "  b: {material: m, velocity: [-1, 0], shape: {box: {min: [1.5, 0], max: [1.8, 0.2]}}}\n"
        "boundaries: {y-: fixed}\ngravity: [0, -9.81]\n"
        "stages:\n  - {name: first, duration: 0.05}\n  - {name: second, duration: 0.1, "
        "activate: [b]}\n",
        0.15);
}

// A caller that moves the particles between steps (through the
// non-const sets()) moves them away from the cells the last step saw: the
// next step must not take its nodes from those.
TEST(ActiveNodes, ParticlesMovedBetweenSteps) {
    expect_same_bits(
        "talus: 1\ndimension: 2\ngrid: {origin: [0, 0], size: [2, 1], cell: 0.025}\n"
        "materials:\n  m: {model: linear_elastic, density: 1000, youngs_modulus: 1.0e4, "
        "poisson_ratio: 0.3}\n"
        "groups:\n  a: {material: m, velocity: [0.5, 0], shape: {box: {min: [0.1, 0.1], max: "
        "[0.4, 0.3]}}}\n"
        "solver: {transfer: {type: flip, alpha: 0.95}}\ntime: {end: 1}\n",
        0.1, [](talus::Simulation &sim) {
            if (sim.steps() != 20) return;
            for (talus::ParticleSet &s : sim.sets()) // 1 m to the right, 40 cells
                for (std::size_t p = 0; p < s.n; ++p)
                    s.x[0][p] += 1.0;
        });
}

} // namespace
