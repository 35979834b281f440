// The same scenario on 1, 2, 3 and 4 ranks (docs/mpi.md): run under
// mpirun, every rank steps its part; rank 0 also runs the scenario alone
// (the serial solver, no MPI call) and compares every particle, by id.
//
// The reference is the serial run itself. The ranks differ from it only in
// how a shared node's contributions are added: each rank sums its own
// particles' into a partial, and the partials are added in rank order,
// where the serial P2G adds all particles' one by one. That changes a
// node's mass, momentum or force by a few ulps of its largest term
// (relative 1e-16 to 1e-15) in each step at the shared nodes, and the
// explicit step, stable under its CFL limit, carries such a perturbation
// on without growing it by more than the step count (elastic) or the
// return mapping's Lipschitz constant (plastic). Tolerances below are set
// from that and stated at each check.
#include "solver_helpers.hpp"

#include <talus/mpm/comm.hpp>

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <functional>
#include <map>

namespace {

using talus::Comm;

// Every particle's values as rank 0 sees them: id -> values (x, v, stress,
// then the plugin state).
using Particles = std::map<std::int64_t, std::vector<double>>;

std::vector<double> values_of(const talus::ParticleSet &s, std::size_t p, int dim) {
    std::vector<double> v;
    for (int d = 0; d < dim; ++d)
        v.push_back(s.x[static_cast<std::size_t>(d)][p]);
    for (int d = 0; d < dim; ++d)
        v.push_back(s.v[static_cast<std::size_t>(d)][p]);
    for (std::size_t c = 0; c < 6; ++c)
        v.push_back(s.stress[6 * p + c]);
    for (std::size_t c = 0; c < s.state_size; ++c)
        v.push_back(s.state[s.state_size * p + c]);
    return v;
}

Particles local(const talus::Simulation &sim, int dim) {
    Particles out;
    for (const talus::ParticleSet &s : sim.sets())
        for (std::size_t p = 0; p < s.n; ++p)
            out[s.id[p]] = values_of(s, p, dim);
    return out;
}

// All ranks' particles on rank 0 (empty elsewhere).
Particles gathered(const Comm &comm, const talus::Simulation &sim, int dim) {
    std::vector<std::byte> bytes;
    auto put = [&](const void *v, std::size_t n) {
        const std::size_t at = bytes.size();
        bytes.resize(at + n);
        std::memcpy(bytes.data() + at, v, n);
    };
    for (const auto &[id, v] : local(sim, dim)) {
        const std::uint64_t n = v.size();
        put(&id, sizeof id);
        put(&n, sizeof n);
        put(v.data(), n * sizeof(double));
    }
    Particles all;
    for (const std::vector<std::byte> &from : comm.gather(bytes)) {
        std::size_t at = 0;
        while (at < from.size()) {
            std::int64_t id = 0;
            std::uint64_t n = 0;
            std::memcpy(&id, from.data() + at, sizeof id);
            std::memcpy(&n, from.data() + at + sizeof id, sizeof n);
            at += sizeof id + sizeof n;
            std::vector<double> v(n);
            std::memcpy(v.data(), from.data() + at, n * sizeof(double));
            at += n * sizeof(double);
            EXPECT_TRUE(all.emplace(id, std::move(v)).second) << "particle " << id << " twice";
        }
    }
    return all;
}

struct Scales {
    double x, v, stress; // the tolerances' units: m, m/s, Pa
};

struct Outcome {
    long migrated = 0, rebalances = 0;
    std::size_t particles = 0;
    std::size_t largest_share = 0; // over the ranks
    double max_state = 0.0;        // the largest plugin state value (rank 0)
};

// Advances a simulation (the same way on the ranks and alone).
using Advance = std::function<void(talus::Simulation &)>;

Advance steps_of(int steps) {
    return [steps](talus::Simulation &sim) {
        for (int k = 0; k < steps; ++k)
            sim.step(1.0);
    };
}

// Runs `yaml` on all ranks and, on rank 0, alone, each advanced by
// `advance`; compares.
Outcome compare(const std::string &yaml, const Advance &advance, const Scales &tol) {
    const Comm comm = Comm::world();
    auto make = [&](const Comm &c) {
        auto s = talus::test::sim_from_text(yaml);
        talus::SolverOptions opt;
        opt.comm = c;
        s->sim = std::make_unique<talus::Simulation>(s->scenario, opt);
        return s;
    };
    auto ranks = make(comm);
    const int dim = ranks->scenario.dim;
    advance(*ranks->sim);
    const Particles all = gathered(comm, *ranks->sim, dim);
    Outcome o;
    o.migrated = comm.sum(ranks->sim->traffic().migrated);
    o.rebalances = ranks->sim->traffic().rebalances;
    o.particles = ranks->sim->particle_count();
    o.largest_share = static_cast<std::size_t>(
        comm.max(static_cast<double>(ranks->sim->traffic().largest_share)));
    const double t_ranks = ranks->sim->time();
    if (comm.rank() != 0) return o;
    auto alone = make(Comm::serial());
    advance(*alone->sim);
    EXPECT_EQ(ranks->sim->steps(), alone->sim->steps());
    // The same dt each step (from max(c + |v|), which moves by round-off):
    // the times agree to the steps' round-off.
    EXPECT_NEAR(t_ranks, alone->sim->time(), 1e-12 * alone->sim->time());
    const Particles ref = local(*alone->sim, dim);
    EXPECT_EQ(all.size(), ref.size());
    double worst[3] = {0, 0, 0};
    for (const auto &[id, r] : ref) {
        const auto it = all.find(id);
        if (it == all.end()) {
            ADD_FAILURE() << "particle " << id << " is on no rank";
            continue;
        }
        const std::vector<double> &v = it->second;
        for (std::size_t c = static_cast<std::size_t>(2 * dim + 6); c < r.size(); ++c)
            o.max_state = std::max(o.max_state, std::abs(r[c]));
        if (v.size() != r.size()) {
            ADD_FAILURE() << "particle " << id << " has " << v.size() << " values, not "
                          << r.size();
            continue;
        }
        for (std::size_t c = 0; c < r.size(); ++c) {
            const std::size_t kind = c < static_cast<std::size_t>(dim)       ? 0
                                     : c < static_cast<std::size_t>(2 * dim) ? 1
                                                                             : 2;
            worst[kind] = std::max(worst[kind], std::abs(v[c] - r[c]));
        }
    }
    std::printf("  %d ranks: max |dx| %.3g m, |dv| %.3g m/s, |dstress or state| %.3g\n",
                comm.size(), worst[0], worst[1], worst[2]);
    EXPECT_LE(worst[0], tol.x);
    EXPECT_LE(worst[1], tol.v);
    EXPECT_LE(worst[2], tol.stress);
    return o;
}

// An elastic disc thrown along x across every rank's cells, bouncing on a
// rough floor: the particles cross rank boundaries throughout.
std::string thrown_disc(const std::string &solver) {
    return "talus: 1\ndimension: 2\ngrid: {origin: [0, 0], size: [2, 1], cell: 0.025}\n"
           "materials:\n  m: {model: linear_elastic, density: 1000, youngs_modulus: 1.0e6, "
           "poisson_ratio: 0.3}\n"
           "groups:\n  a: {material: m, particles_per_cell: 2, velocity: [3, -0.4],\n"
           "      shape: {sphere: {center: [0.4, 0.4], radius: 0.25}}}\n"
           "boundaries: {y-: {friction: 0.3}, x+: {friction: 0}}\ngravity: [0, -9.81]\n"
           "solver: " +
           solver + "\ntime: {end: 1}\n";
}

} // namespace

// 200 steps of ~1.6e-3 s: the disc travels 1 m, over the cuts of 2-4 ranks.
// Elastic: a perturbation of 1e-15 relative per step, carried 200 steps,
// leaves 2e-13 of the scales (1 m, 3 m/s, the impact stress rho v c ~
// 1e5 Pa); the tolerances allow ten times that (the stress's a tenth).
TEST(Mpi, AnElasticDiscAcrossTheRanksMatchesOneRank) {
    const char *solvers[] = {"{}",
                             "{transfer: apic}",
                             "{scheme: musl}",
                             "{scheme: usf}",
                             "{scheme: usavg, transfer: tpic}",
                             "{cell_averaged_dilation: true}",
                             "{shape: gimp}",
                             "{shape: bspline3, transfer: {type: flip, alpha: 0.95}}"};
    for (const char *solver : solvers) {
        SCOPED_TRACE(solver);
        const Outcome o = compare(thrown_disc(solver), steps_of(200), {2e-12, 6e-12, 2e-8});
        if (Comm::world().size() > 1) {
            EXPECT_GT(o.migrated, 100) << "no particle crossed";
        }
    }
}

namespace {

// A Mohr-Coulomb column collapsing on a rough floor: the flow carries the
// particles (and their plastic state) out over the ranks' cells, and the
// ranks that started with the column's cells lose them, so the cells are
// shared anew on the way.
std::string collapsing_column(int dim) {
    const std::string mat =
        "materials:\n  sand: {model: mohr_coulomb, density: 1800, youngs_modulus: 2.0e5, "
        "poisson_ratio: 0.3, friction_angle: 30, dilation_angle: 0, cohesion: 0}\n";
    if (dim == 2)
        return "talus: 1\ndimension: 2\ngrid: {origin: [0, 0], size: [1.0, 0.35], cell: 0.025}\n" +
               mat +
               "groups:\n  column: {material: sand, particles_per_cell: 2,\n"
               "      shape: {box: {min: [0, 0], max: [0.15, 0.3]}},\n"
               "      initial_stress: {geostatic: {k0: 0.5}}}\n"
               "boundaries: {x-: {friction: 0.4}, y-: {friction: 0.4}}\ngravity: [0, -9.81]\n"
               "solver: {transfer: apic, load_balance: {imbalance: 1.1, every: 5}}\n"
               "time: {end: 1}\n";
    return "talus: 1\ndimension: 3\ngrid: {origin: [0, 0, 0], size: [0.8, 0.3, 0.45], cell: "
           "0.05}\n" +
           mat +
           "groups:\n  column: {material: sand, particles_per_cell: 2,\n"
           "      shape: {box: {min: [0, 0, 0], max: [0.2, 0.3, 0.3]}},\n"
           "      initial_stress: {geostatic: {k0: 0.5}}}\n"
           "boundaries: {x-: {friction: 0.4}, y-: {friction: 0}, y+: {friction: 0}, z-: "
           "{friction: 0.4}}\ngravity: [0, 0, -9.81]\n"
           "solver: {load_balance: {imbalance: 1.1, every: 5}}\ntime: {end: 1}\n";
}

} // namespace

// 500 steps in 2D (0.3 s) and 300 in 3D (0.4 s): the column has slumped and
// spread. As for the disc, 1e-15 relative per step leaves 5e-13 of the
// scales (0.3 m, 1 m/s, rho g H = 5e3 Pa; the plastic strains are below
// 1): the tolerances allow ten times that. The return mapping, Lipschitz
// in the trial stress, does not make more of a round-off difference than
// the elastic step does.
TEST(Mpi, AMohrCoulombColumnCollapsingAcrossTheRanksMatchesOneRank) {
    for (int dim : {2, 3}) {
        SCOPED_TRACE(dim);
        const Outcome o =
            compare(collapsing_column(dim), steps_of(dim == 2 ? 500 : 300), {2e-12, 5e-12, 3e-8});
        const int P = Comm::world().size();
        if (P > 1) {
            EXPECT_GT(o.migrated, 100) << "no particle crossed";
            EXPECT_GE(o.rebalances, 1) << "the cells were never shared anew";
            // Each rank generated its share of the column's lattice rows
            // (lines of points along x), not the whole column: at most
            // ceil(rows / P) rows. The lattice spans the column and one
            // spacing more each side: in 2D 24 + 2 rows of 12 points, in 3D
            // (12 + 2)^2 rows of 8.
            const std::size_t rows = dim == 2 ? 26 : 14 * 14, per_row = dim == 2 ? 12 : 8;
            const std::size_t R = static_cast<std::size_t>(P);
            if (Comm::world().rank() == 0)
                std::printf("  largest share %zu of %zu particles\n", o.largest_share, o.particles);
            EXPECT_LE(o.largest_share, (rows + R - 1) / R * per_row);
        }
        if (Comm::world().rank() == 0) {
            // Mohr-Coulomb's state includes the plastic strain: the column
            // yielded (this is a plastic test).
            EXPECT_GT(o.max_state, 0.01);
        }
    }
}

namespace {

// An analysis in two stages whose changes fall on several ranks' cells: a
// soil column held by a prop settles under gravity on a firm base with
// local damping until it is at rest (the default hold, from the body's
// extent over all ranks); then the prop is removed, the column turns from
// elastic to Mohr-Coulomb (its set-up call sees the settled stress), a
// fill appears at the far end (each rank keeps its part) under a point
// load on a corner of it that lies on one rank's cells, displacements
// and velocities are reset, and the column collapses.
const char *const staged_collapse =
    "talus: 1\ndimension: 2\ngrid: {origin: [0, 0], size: [0.6, 0.4], cell: 0.025}\n"
    "materials:\n"
    "  firm: {model: linear_elastic, density: 1800, youngs_modulus: 5.0e5, poisson_ratio: 0.3}\n"
    "  sand: {model: mohr_coulomb, density: 1800, youngs_modulus: 5.0e5, poisson_ratio: 0.3,\n"
    "         friction_angle: 30, dilation_angle: 0, cohesion: 0}\n"
    "groups:\n"
    "  base: {material: firm, particles_per_cell: 2, shape: {box: {min: [0, 0], max: [0.6, "
    "0.1]}},\n"
    "         initial_stress: {geostatic: {k0: 0.5}}}\n"
    "  column: {material: firm, particles_per_cell: 2,\n"
    "           shape: {box: {min: [0, 0.1], max: [0.15, 0.35]}},\n"
    "           initial_stress: {geostatic: {k0: 0.5}}}\n"
    "  prop: {material: firm, particles_per_cell: 2,\n"
    "         shape: {box: {min: [0.15, 0.1], max: [0.2, 0.35]}}}\n"
    "  fill: {material: sand, particles_per_cell: 2,\n"
    "         shape: {box: {min: [0.45, 0.1], max: [0.6, 0.2]}},\n"
    "         initial_stress: {geostatic: {k0: 0.5}}}\n"
    "boundaries: {x-: {friction: 0.4}, x+: roller, y-: fixed}\ngravity: [0, -9.81]\n"
    "solver: {transfer: apic, load_balance: {imbalance: 1.1, every: 5}}\n"
    "stages:\n"
    "  - name: settle\n"
    "    duration: 0.5\n"
    "    damping: {type: local, coefficient: 0.7}\n"
    "    until: {kinetic_energy_ratio: 1.0e-3, otherwise: continue}\n"
    "  - name: collapse\n"
    "    duration: 0.25\n"
    "    damping: none\n"
    "    remove: [prop]\n"
    "    activate: [fill]\n"
    "    set_material: {column: sand}\n"
    "    reset: [displacement, velocity]\n"
    "    loads: [{point: [0, -0.5], group: fill, box: {min: [0.55, 0.15], max: [0.6, 0.2]}}]\n";

} // namespace

// 0.5 s of settling (the rest test ends it earlier when met) and 0.25 s of
// collapse at dt ~ 3.9e-4 s: at most ~1,900 steps. 1e-15 relative per step
// over them leaves 2e-12 of the scales (0.35 m, 1 m/s, rho g H = 6e3 Pa);
// the tolerances allow ten times that. Both runs must end the first stage
// at the same step: the rest test's ratio and hold are global sums and
// extents, and differ from one rank's only by round-off.
TEST(Mpi, AnAnalysisInStagesAcrossTheRanksMatchesOneRank) {
    // Each run's stage ends (step, why): the ranks' run, then (rank 0) the
    // one-rank run.
    std::vector<std::vector<std::pair<long, talus::StageEnd>>> runs;
    const Advance all_stages = [&runs](talus::Simulation &sim) {
        auto &ends = runs.emplace_back();
        for (;;) {
            talus::StageEnd why;
            while ((why = sim.stage_end_reached()) == talus::StageEnd::running)
                sim.step(sim.stage_end() - sim.time());
            ends.emplace_back(sim.steps(), why);
            if (sim.stage() + 1 == sim.stages().size()) return;
            sim.begin_next_stage();
        }
    };
    const Outcome o = compare(staged_collapse, all_stages, {2e-11, 5e-11, 6e-7});
    if (Comm::world().rank() == 0) {
        ASSERT_EQ(runs.size(), 2u);
        ASSERT_EQ(runs[0].size(), 2u);
        std::printf("  stage ends at steps %ld (%s) and %ld\n", runs[0][0].first,
                    runs[0][0].second == talus::StageEnd::quiescent ? "at rest" : "duration",
                    runs[0][1].first);
        EXPECT_EQ(runs[0], runs[1]) << "the ranks ended a stage at another step";
        // The settling stage came to rest: the rest test ran on every rank.
        EXPECT_EQ(runs[0][0].second, talus::StageEnd::quiescent);
        // The column yielded once it was sand.
        EXPECT_GT(o.max_state, 0.01);
    }
    if (Comm::world().size() > 1) {
        EXPECT_GT(o.migrated, 10) << "no particle crossed";
    }
}

// Particles leaving through a free face on one rank's side stop every rank
// with the same report (no rank left waiting in an exchange), naming the
// particles as one rank would.
TEST(Mpi, ParticlesLeavingTheGridStopEveryRankWithOneReport) {
    const std::string yaml =
        "talus: 1\ndimension: 2\ngrid: {origin: [0, 0], size: [1, 0.5], cell: 0.025}\n"
        "materials:\n  m: {model: linear_elastic, density: 1000, youngs_modulus: 1.0e6, "
        "poisson_ratio: 0.3}\n"
        "groups:\n  a: {material: m, particles_per_cell: 2, velocity: [4, 0],\n"
        "      shape: {box: {min: [0.1, 0.1], max: [0.9, 0.3]}}}\n"
        "boundaries: {y-: slip}\ngravity: [0, -9.81]\ntime: {end: 1}\n";
    const Comm comm = Comm::world();
    auto s = talus::test::sim_from_text(yaml);
    talus::SolverOptions opt;
    opt.comm = comm;
    s->sim = std::make_unique<talus::Simulation>(s->scenario, opt);
    std::string message;
    try {
        for (int k = 0; k < 400; ++k)
            s->sim->step(1.0);
    } catch (const talus::Error &e) {
        message = e.what();
    }
    EXPECT_NE(message.find("left the grid"), std::string::npos) << message;
    if (comm.rank() == 0) std::printf("  %d ranks: %s\n", comm.size(), message.c_str());
    // Every rank stopped at the same step with the same text.
    std::vector<std::byte> mine(message.size());
    std::memcpy(mine.data(), message.data(), message.size());
    const auto all = comm.gather(mine);
    for (const auto &m : all)
        EXPECT_EQ(std::string(reinterpret_cast<const char *>(m.data()), m.size()), message);
}
