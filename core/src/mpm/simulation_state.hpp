// What a Simulation holds between steps: the typed parts of the method
// (grid, particles, ordering, boundary, loads, material update), the run's
// choices made once at set-up, and the counters. The phases of the cycle
// are member functions that time themselves and hand each kernel the parts
// it reads and writes; the scheme functions (schemes.cpp) compose them.
#pragma once

#include "method/boundary.hpp"
#include "method/g2p.hpp"
#include "method/grid_update.hpp"
#include "method/kinematics.hpp"
#include "method/loads.hpp"
#include "method/material_update.hpp"
#include "method/move_particles.hpp"
#include "method/p2g.hpp"
#include "parallel/ordering.hpp"
#include "profile/phase_timer.hpp"
#include "ranks/decomposition.hpp"
#include "ranks/halo.hpp"
#include "state/grid.hpp"

#include <talus/mpm/simulation.hpp>

#include <array>
#include <exception>
#include <limits>
#include <memory>
#include <optional>
#include <string>
#include <vector>

namespace talus {

// The phases, in the order of a step; Simulation::phase_name gives each the
// name of the function that runs it.
enum class Phase {
    time_step,
    reorder,
    p2g,
    grid_update,
    g2p,
    dilation,
    material_update,
    move_particles,
    halo_exchange,
    migration
};

// A scheme's step as the run will take it, chosen once at set-up.
enum class StepVariant {
    usl,       // USL with cell-averaged dilation: the update after the dilation sums
    usl_fused, // USL: the kinematics and material update inside G2P, the particles moved there
    usf,
    musl,
    usavg
};

// The domain and its closed faces under a stage's conditions.
Domain domain_of(const Scenario &sc, const Conditions &c);

struct Simulation::Impl {
    const Scenario &sc;
    SolverOptions opt;
    const Comm &comm; // opt.comm
    // The cells each rank owns, and this rank's nodes shared with others
    // (one rank: all cells, nothing shared).
    Decomposition decomp;
    Halo halo;
    RankTraffic traffic;
    std::vector<StageSpec> stages;      // stages_of(sc)
    std::vector<std::int64_t> first_id; // per group: the id of this rank's share's first particle
    std::size_t stage = 0;
    double stage_start = 0.0;
    Vec3 gravity_before{0, 0, 0}; // the current stage's gravity ramp starts there
    // The stage's quiescence test (Quiescence): its hold time, since when
    // the ratio has stayed below the limit, and its last value.
    std::optional<double> hold, below_since;
    double ratio = std::numeric_limits<double>::quiet_NaN();
    Grid grid;
    Boundary boundary;
    std::vector<std::unique_ptr<MaterialInstance>> instances; // per material used, else null
    std::vector<ParticleSet> sets;
    Ordering order;
    Loads loads;
    Domain domain;
    StepEndBlocks step_ends; // the step's end pass, or its blocks in the fused USL pass
    Isa isa; // the kernels' instruction set (transfers, kinematics), the widest this CPU has
    MaterialUpdate materials;
    DilationCells dilation;
    StepVariant variant;
    Motion velocity_motion; // how g2p_velocity moves the particles
    std::vector<std::string> group_names;

    double time = 0.0, last_dt = 0.0;
    double step_end = 0.0; // the end time of the step being computed
    long step = 0, removed = 0, held_at_faces = 0;
    double held_depth = 0.0;
    double max_speed = -1.0; // max(c + |v|) from the last step; < 0: not known
    // The cells the particles are in after the last step (StepEnd); not
    // known at the start, after a restart or a stage's change of groups.
    std::optional<std::array<std::array<int, 3>, 2>> particle_cells;
    bool warned_dt = false;
    std::vector<std::string> warnings;
    std::optional<FailedCall> failed_call;
    std::array<double, Simulation::kPhases> phase_seconds{};

    // With `restore`, the state comes from it (no generation, no plugin
    // call).
    Impl(const Scenario &scenario, SolverOptions options, const Snapshot *restore);
    void restore_from(const Snapshot &snap);

    // One step of each variant (schemes.cpp).
    void usl(double t, double dt);
    void usl_fused(double t, double dt);
    void usf(double t, double dt);
    void musl(double t, double dt);
    void usavg(double t, double dt);

    // The phases, each on the parts it needs.
    void p2g_momentum();
    void p2g_forces();
    void p2g_momentum_and_forces();
    void p2g_remap();
    void grid_velocity(double t);
    // `after`: Accumulators::clear where the scheme's step reads Grid::acc
    // no more (grid_update.hpp).
    void grid_update(double t, double dt, Accumulators after = Accumulators::keep);
    void remapped_velocity(double t_end);
    void g2p_velocity(double dt, bool store_gradient);
    // Fused USL: G2P, kinematics, material update and the step's end, block
    // by block.
    void g2p_velocity_and_update(double t, double dt);
    void g2p_gradient(const double *field, std::size_t offset, std::size_t move_offset,
                      double move_dt);
    // Kinematics and material update from the stored L (after the dilation
    // sums, with cell-averaged dilation).
    void material_update(double t, double dt);
    void move_particles(PositionStep step);
    // What follows either: the next dt's speed, the faces' counts, the
    // particles that left the grid, and those that go to another rank.
    void step_ended(const StepEnd &end);

    // Several ranks (docs/mpi.md). Splits the cells among the ranks by the
    // particles each holds (a share of the generated ones, or of a
    // snapshot's), sends them to their cells' ranks and puts each set in
    // id order.
    void distribute();
    // Points [begin, n) of set `set`, just generated (this rank's share of a
    // new group), go to their cells' ranks and arrive in id order at
    // [begin, n) (collective; the other particles are in their cells).
    void arrive(std::size_t set, std::size_t begin);
    // The shared nodes' `fields` (Halo) summed over the ranks, after a P2G.
    void exchange(unsigned fields);
    // Particles to the rank owning their cell.
    void migrate();
    // Every solver.load_balance.every steps: the cells shared anew by the
    // particles' current places if the ranks' counts are too uneven, the
    // grid, boundary, halo and ordering remade for the new boxes and the
    // particles moved to their new ranks.
    void rebalance_if_uneven();
    // This rank's grid, boundary, halo and ordering for decomp.
    void take_box();
    // Every rank learns whether one failed: `error` (this rank's, if any)
    // is rethrown on the lowest failed rank, the others throw its message.
    void agree(std::exception_ptr error) const;

    const Conditions &conditions() const { return stages[stage].conditions; }
    // The changes a stage makes when it begins (stages.cpp).
    void begin_stage(std::size_t k);
    void add_groups(const std::vector<std::size_t> &groups, const Vec3 &gravity);
    void remove_groups(const std::vector<std::size_t> &groups);
    void switch_material(const MaterialSwitch &sw);
    // The set-up call for points [begin, s.n) of set `set` (they appeared,
    // or changed material); throws as a material failure would.
    void start_points(std::size_t set, std::size_t begin);
    double kinetic_energy_ratio() const;
    double default_hold() const;
    void arm_quiescence();   // at a stage's start
    void watch_quiescence(); // after each step

    double time_step();
    void check_fixed_dt(double dt_crit) const;
    double critical_dt() const;
    // Reports the first failure of a material update as talus::Error.
    [[noreturn]] void material_failed(const MaterialFailure &f, long step_number);
    [[noreturn]] void inverted(const Inversion &inv, double t) const;
    // Reports the first failure of an update pass, if any.
    void update_failed(const UpdateFailures &f, double t);

    P2gSources p2g_sources() const {
        return {grid.geo, sets, order, loads, sc.solver.shape, sc.solver.transfer != Transfer::flip,
                isa};
    }
    G2pTargets g2p_targets() {
        return {grid.geo,
                sets,
                loads,
                sc.solver.shape,
                sc.solver.transfer,
                sc.solver.transfer == Transfer::flip ? sc.solver.alpha : 0.0,
                isa};
    }

    double &seconds_of(Phase p) { return phase_seconds[static_cast<std::size_t>(p)]; }
    PhaseTimer timer(Phase p) { return PhaseTimer(seconds_of(p)); }
};

} // namespace talus
