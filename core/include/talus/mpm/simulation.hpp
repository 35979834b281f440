// The explicit MPM solver: particles, background grid and the grid cycle
// (seed 000, phases 1-4), in 2D plane strain and 3D. docs/theory.md walks
// through it equation by equation, docs/architecture.md through the files.
#pragma once

#include <talus/mpm/comm.hpp>
#include <talus/mpm/material_hook.hpp>
#include <talus/mpm/particles.hpp>
#include <talus/mpm/scenario.hpp>
#include <talus/mpm/snapshot.hpp>

#include <array>
#include <cstdint>
#include <memory>
#include <optional>
#include <string>
#include <vector>

namespace talus {

struct Diagnostics {
    long step = 0;
    double time = 0.0, dt = 0.0;
    double mass = 0.0;
    std::array<double, 3> momentum{0, 0, 0};
    double kinetic_energy = 0.0;
    // Accumulated stress work, sum over steps and particles of V sigma : d_eps
    // (trapezoidal in each step), J. Not a stored energy: for a hypoelastic
    // model under large rotations or an elastic-plastic one it is path
    // dependent and may be negative.
    double stress_work = 0.0;
    std::array<double, 3> angular_momentum{0, 0, 0}; // about the origin, z only in 2D
    std::size_t particles = 0;
    long removed = 0;   // particles removed after leaving the grid
    long cut_steps = 0; // plugin cut-step requests honoured by sub-stepping
    // Particle positions put back onto a closed face they had crossed (by
    // round-off, or a time step above the stability limit), summed over steps
    long held_at_faces = 0;
    double held_depth = 0.0; // the deepest such crossing, m
};

// What a scenario will need, from its input alone: checked before anything
// is allocated, so that a grid or a particle count that cannot fit is
// refused with numbers instead of failing inside the allocator.
struct ResourceEstimate {
    double particles = 0.0; // from the groups' areas (2D) or volumes (3D)
    double nodes = 0.0;     // including the ghost layers
    double bytes = 0.0;     // particle and grid arrays
};
ResourceEstimate estimate_resources(const Scenario &scenario);

// The most threads a run takes. OpenMP's team start (libgomp) keeps data
// for every thread on the starting thread's stack: 100,000 threads
// overflowed it (a crash inside GOMP_parallel), and far below that each
// step is already many times slower than on the cores there are.
inline constexpr int kMaxThreads = 4096;

struct SolverOptions {
    int threads = 0;      // 0: OpenMP's default; at most kMaxThreads
    int batch_size = 128; // points per plugin call
    // Particles are re-sorted by cell when more than this fraction is far
    // out of cell order (more than two rows or planes of cells below the
    // particle before it in memory; checked every step at no extra pass),
    // so that neighbours on the grid stay neighbours in memory; 0 disables
    // sorting.
    double sort_disorder = 0.01;
    // Each step resets and updates only the grid nodes its particles reach
    // (a box around their cells); false: every node, every step. The results
    // are the same bit for bit; the option is there to show it (tests) and
    // to measure what it saves (talus_bench).
    bool active_nodes_only = true;
    // The ranks the run is spread over (docs/mpi.md): each holds the
    // particles of its part of the grid. With more than one, step(),
    // diagnostics(), critical_dt(), kinetic_energy_ratio(),
    // particle_count() and grid_mass() are collective: every rank calls
    // them, in the same order; sets() are this rank's particles.
    Comm comm = Comm::serial();
    // Null, the default: every block goes to its plugin.
    MaterialBlockHook material_hook = nullptr;
};

// What one rank sent to the others, summed over the steps so far.
struct RankTraffic {
    std::size_t halo_bytes = 0;      // shared node records after each P2G
    std::size_t migration_bytes = 0; // particles moving to their cell's rank
    long migrated = 0;               // particles sent
    long rebalances = 0;
    std::size_t shared_nodes = 0; // nodes this rank holds with others
    int neighbours = 0;
    // The most particles this rank held before sending them to their
    // cells' ranks: its share of the generated (or restored) particles at
    // the start, of a group's when a stage adds it. No rank holds them all.
    std::size_t largest_share = 0;
};

// One plugin call that failed, as the plugin received it (ABI conventions:
// engineering shear, row-major F, Cauchy stress tension positive).
struct FailedCall {
    std::size_t material = 0; // index into Scenario::materials
    std::int64_t particle = -1;
    long step = 0;
    double time = 0.0, dt = 0.0, density = 0.0;
    std::array<double, 6> strain_increment{}, stress{};
    std::array<double, 9> F_start{}, F_end{};
    std::vector<double> state;
    bool cut_step = false; // still asking for a smaller step after the host's cuts
    std::string message;   // the plugin's
};

// Whether the stage being run is over, and why.
enum class StageEnd { running, duration, quiescent };

class Simulation {
  public:
    // Generates the particles of every group and the initial state; calls
    // each plugin once on the initial state to get wave speeds. The scenario
    // is read, never changed, and must outlive the simulation.
    Simulation(const Scenario &scenario, SolverOptions options = {});
    // Continues from a snapshot of a simulation of the same scenario (its
    // batch size and sort threshold replace those in `options`): no
    // particle is generated and no plugin called. Throws when the
    // snapshot's sets or columns do not fit the scenario. On several
    // ranks (collective): each rank's own part of a snapshot taken on as
    // many ranks, or on every rank the same snapshot of every particle,
    // which is split among the ranks as at the start (Snapshot::boxes).
    Simulation(const Scenario &scenario, SolverOptions options, const Snapshot &snapshot);
    ~Simulation();
    Simulation(const Simulation &) = delete;
    Simulation &operator=(const Simulation &) = delete;

    // Advances one explicit step of at most `max_dt` (also limited by the
    // CFL condition or the fixed dt). Throws talus::Error, naming plugin,
    // group, particle and step, when a material fails, a particle inverts,
    // or particles leave the grid under the "stop" policy.
    void step(double max_dt);

    double time() const;
    long steps() const;
    // Everything needed to continue from here (restore with the
    // constructor above).
    Snapshot snapshot() const;

    // Stages (Scenario::stages; a scenario without them is one stage).
    const std::vector<StageSpec> &stages() const;
    std::size_t stage() const;  // the one being run
    double stage_start() const; // s
    double stage_end() const;   // its start plus its duration, s
    // Whether the stage has run its duration or (with `until`) has been
    // quiescent for its hold time; step() keeps the test up to date.
    StageEnd stage_end_reached() const;
    // Begins the next stage at the current time: its conditions replace
    // the current ones, its groups are removed, switched to their new
    // material (whose plugin's set-up call sees their stress) and added,
    // then displacements and velocities are reset as it says. Throws,
    // located in the file, when a load or fixity selects no particle or a
    // plugin refuses a point's state.
    void begin_next_stage();
    // Kinetic energy over the strain energy estimate sum V sigma:sigma /
    // (2 rho c^2), from the current particles (0 at rest).
    double kinetic_energy_ratio() const;
    // The ratio after the last step, in a stage with `until` (NaN
    // otherwise), and since when it has stayed below the stage's limit.
    double last_kinetic_energy_ratio() const;
    std::optional<double> quiet_since() const;
    double last_dt() const;
    // dt = cfl h / max(c_p + |v_p|) for the current state (seed 000 eq. 45).
    double critical_dt() const;
    // Throws (located at solver.dt) if a fixed dt is above the stability
    // limit h / max(c + |v|), i.e. critical_dt() / cfl: an unstable step.
    // step() checks this every step; with no argument, for the current state.
    void check_fixed_dt(double dt_crit) const;
    void check_fixed_dt() const { check_fixed_dt(critical_dt()); }
    // The caller has told the user that the fixed dt exceeds the cfl margin
    // (talus run's plan): step() does not warn again.
    void fixed_dt_warning_given();
    Diagnostics diagnostics() const;
    const std::vector<ParticleSet> &sets() const;
    // For a caller that changes the particles between steps (a test that
    // sets an initial field): the next step then takes nothing from the
    // last one's record of where they were. It bins them into slabs afresh
    // (two threads' slabs of one colour must not share a node) and resets
    // and updates every grid node, not only those around the cells the
    // last step saw them in (SolverOptions::active_nodes_only).
    std::vector<ParticleSet> &sets();
    const Scenario &scenario() const;
    std::size_t particle_count() const;
    // Total nodal mass of the last step's P2G (equals the particle mass by
    // partition of unity).
    double grid_mass() const;
    // Grid nodes the last step reset and updated (SolverOptions::
    // active_nodes_only), and all the grid's nodes, on this rank.
    std::size_t active_nodes() const;
    std::size_t grid_nodes() const;
    // Wall time spent in each phase of the cycle so far (for profiling),
    // named as the functions the scheme calls (docs/theory.md).
    static constexpr int kPhases = 10;
    std::array<double, kPhases> phase_seconds() const;
    static const char *phase_name(int k);
    // This rank's messages (zero on one rank).
    RankTraffic traffic() const;
    // The ranks the run is spread over, this rank and its box of cells,
    // [lo, hi) per axis.
    const Comm &comm() const;
    int rank() const;
    std::array<int, 6> cell_box() const;
    // Threads the solver's parallel loops use.
    static int max_threads();
    // Processors this process may run on (its affinity mask).
    static int processors();
    // The threads of the solver's parallel loops from the next step on
    // (1 to kMaxThreads; 0: OpenMP's default): the results do not depend on
    // the count, bit for bit (docs/theory.md, "Parallel execution"), so it
    // may change between any two steps. Process-wide, like OpenMP's.
    static void set_threads(int threads);
    // The instruction set of the transfer kernels this run uses (generic,
    // avx2, avx512): the widest the CPU has, or TALUS_KERNEL_ISA.
    const char *kernel_isa() const;
    // Parallel regions (each ending in a barrier) started by all runs of
    // this process so far.
    static long parallel_regions();

    // Warnings issued so far (fixed dt above the limit, ...), for the log.
    const std::vector<std::string> &warnings() const;
    // The inputs of the plugin call that failed at one particle, when a step
    // threw because a plugin failed (or kept asking for smaller steps):
    // enough for `talus point` to replay the call (point_driver.hpp).
    const std::optional<FailedCall> &failed_call() const;

    struct Impl;

  private:
    std::unique_ptr<Impl> impl_;
};

} // namespace talus
