// The Simulation: set-up, and the step that picks dt, readies the grid and
// the particle order, and runs the scheme (schemes.cpp).
#include "simulation_state.hpp"

#include "parallel/parallel.hpp"
#include "ranks/migration.hpp"
#include "state/particle_generation.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <exception>
#include <limits>

namespace talus {

namespace {

const Scenario &checked(const Scenario &sc) {
    for (const StageSpec &st : stages_of(sc))
        if (st.conditions.loads.size() > kMaxLoads ||
            st.conditions.particle_velocities.size() > kMaxLoads)
            throw Error(fmt::format("{}: at most {} loads and {} particle_velocities entries",
                                    sc.file, kMaxLoads, kMaxLoads));
    return sc;
}

StepVariant variant_of(const SolverSpec &sv) {
    switch (sv.scheme) {
    case Scheme::usl: return sv.cell_averaged_dilation ? StepVariant::usl : StepVariant::usl_fused;
    case Scheme::usf: return StepVariant::usf;
    case Scheme::musl: return StepVariant::musl;
    case Scheme::usavg: return StepVariant::usavg;
    }
    return StepVariant::usl;
}

// How each scheme moves its particles (docs/theory.md, "Kinematic
// consistency"): USL and USAVG in the velocity pass, by v~ or by the mean
// (v + v~) / 2; USF and MUSL in the gradient pass of their own field, where
// MUSL's second order takes the mean of the remapped field with v.
Motion velocity_motion_of(const SolverSpec &sv) {
    const bool mean =
        sv.scheme == Scheme::usavg || (sv.second_order_position && sv.scheme != Scheme::usf);
    if (sv.scheme == Scheme::usf) return Motion::none;
    if (sv.scheme == Scheme::musl) return mean ? Motion::mean_velocity : Motion::none;
    return mean ? Motion::mean_velocity : Motion::end_velocity;
}

ColumnsInUse columns_of(const SolverSpec &sv) {
    const bool fused = variant_of(sv) == StepVariant::usl_fused;
    return {.L = !fused,
            .dx = !fused,
            .C = sv.transfer != Transfer::flip,
            .divv = sv.cell_averaged_dilation,
            .lp = sv.shape == ShapeKind::gimp};
}

MaterialNames names_of(const Scenario &sc, const std::vector<ParticleSet> &sets) {
    MaterialNames n;
    for (const ParticleSet &s : sets)
        n.material.push_back(sc.materials[s.material].name.c_str());
    for (const GroupSpec &g : sc.groups)
        n.group.push_back(g.name.c_str());
    return n;
}

// The plugin instance of every material some group uses or some stage
// switches a group to; a parameter set the plugin refuses is reported at
// the material's place in the file.
std::vector<std::unique_ptr<MaterialInstance>> make_instances(const Scenario &sc) {
    std::vector<std::unique_ptr<MaterialInstance>> out(sc.materials.size());
    for (std::size_t k : materials_in_use(sc)) {
        const NamedMaterial &m = sc.materials[k];
        try {
            out[k] = instantiate(m.spec);
        } catch (const Error &e) {
            throw Error(m.origin.error(e.what()));
        }
    }
    return out;
}

// The particles at t = 0 (this rank's share on several ranks): the groups
// present from the start, with the first stage's loads and fixities
// selected.
std::vector<ParticleSet>
initial_particles(const Scenario &sc, const std::vector<StageSpec> &stages,
                  const std::vector<std::int64_t> &first_id,
                  const std::vector<std::unique_ptr<MaterialInstance>> &instances,
                  const Comm &comm) {
    std::vector<ParticleSet> sets = make_sets(sc, columns_of(sc.solver), instances);
    const std::vector<std::size_t> first_stage = first_stage_of_groups(sc);
    for (std::size_t g = 0; g < sc.groups.size(); ++g)
        if (first_stage[g] == 0)
            add_group(sc, g, stages[0].conditions.gravity, first_id[g], sets, comm);
    select_particles(sc, stages[0].conditions, sets, "at t = 0", comm);
    return sets;
}

// Cells of the whole domain per axis (as the grid counts them).
std::array<int, 3> domain_cells(const Scenario &sc) {
    std::array<int, 3> n{1, 1, 1};
    for (std::size_t d = 0; d < static_cast<std::size_t>(sc.dim); ++d)
        n[d] = static_cast<int>(std::lround(sc.size[d] / sc.cell));
    return n;
}

// The grid this rank starts with: the whole domain on one rank; on several
// a placeholder of one cell's nodes until distribute() knows its box.
Grid initial_grid(const Scenario &sc, const Comm &comm) {
    if (!comm.distributed()) return Grid(sc.dim, sc.origin, sc.size, sc.cell, sc.solver.shape);
    return Grid(sc.dim, sc.origin, sc.size, sc.cell, sc.solver.shape, {0, 0, 0}, {0, 0, 0});
}

} // namespace

Domain domain_of(const Scenario &sc, const Conditions &c) {
    Domain dom;
    for (std::size_t d = 0; d < static_cast<std::size_t>(sc.dim); ++d) {
        dom.lo[d] = sc.origin[d];
        dom.hi[d] = sc.origin[d] + sc.size[d];
        dom.closed_lo[d] = c.faces[2 * d].type != FaceType::free;
        dom.closed_hi[d] = c.faces[2 * d + 1].type != FaceType::free;
    }
    return dom;
}

Simulation::Impl::Impl(const Scenario &scenario, SolverOptions options, const Snapshot *restore)
    : sc(checked(scenario)), opt(options), comm(opt.comm), decomp(sc.dim, domain_cells(sc)),
      stages(stages_of(sc)), first_id(group_ids(sc, comm).share_first),
      grid(initial_grid(sc, comm)),
      boundary(comm.distributed() ? Boundary() : Boundary(sc, stages[0].conditions, grid, 0.0)),
      instances(make_instances(sc)),
      sets(restore ? make_sets(sc, columns_of(sc.solver), instances)
                   : initial_particles(sc, stages, first_id, instances, comm)),
      order(grid.geo, sets.size()), loads(sc, stages[0].conditions, Vec3{0, 0, 0}, 0.0),
      domain(domain_of(sc, stages[0].conditions)), isa(talus::kernel_isa()),
      materials(names_of(sc, sets), opt.batch_size, sc.cell, isa, opt.material_hook),
      variant(variant_of(sc.solver)), velocity_motion(velocity_motion_of(sc.solver)) {
    for (const GroupSpec &g : sc.groups)
        group_names.push_back(g.name);
    // A snapshot read on another number of ranks than wrote it (this
    // rank's share of its files) is spread over the ranks like generated
    // particles; one of this rank's part of a run on as many ranks takes
    // that rank's box back.
    const bool whole = !restore || restore->boxes.empty();
    if (comm.distributed()) {
        if (!whole) {
            if (restore->boxes.size() != static_cast<std::size_t>(comm.size()) ||
                restore->rank != comm.rank())
                throw Error(fmt::format("internal error: rank {} of {} given the snapshot of "
                                        "rank {} of {}",
                                        comm.rank(), comm.size(), restore->rank,
                                        restore->boxes.size()));
            std::vector<CellBox> boxes;
            for (const auto &b : restore->boxes)
                boxes.push_back(CellBox{{b[0], b[1], b[2]}, {b[3], b[4], b[5]}});
            try { // the same boxes on every rank (read_checkpoint_for)
                decomp = Decomposition::from_boxes(sc.dim, domain_cells(sc), boxes);
            } catch (const Error &e) {
                fail_together(comm, e.what());
            }
            take_box();
        } else if (!restore) {
            distribute();
        }
    } else if (!whole) {
        throw Error(fmt::format("internal error: one rank given the snapshot of rank {} of {}",
                                restore->rank, restore->boxes.size()));
    }
    if (sc.solver.cell_averaged_dilation) {
        dilation.div.assign(grid.n_cells, 0.0);
        dilation.vol.assign(grid.n_cells, 0.0);
    }
    if (restore) {
        // A snapshot that does not fit (a damaged file) may be one rank's.
        std::exception_ptr error;
        try {
            restore_from(*restore);
        } catch (...) {
            error = std::current_exception();
        }
        agree(error);
        if (comm.distributed() && whole) {
            // This rank's share of the snapshot's particles (its files'
            // share, read_checkpoint_for) to their cells' ranks; its cut
            // steps are its files', and the run's count is the sum.
            distribute(); // this rank's box, boundary and a new particle order
            order.sort(sets);
        }
        return;
    }
    // The plugins see the initial state once (zero increment, so no stress
    // work) and report their wave speeds; a material that rejects its
    // initial state stops here.
    UpdateFailures failures;
    materials.run(sets, Increment{}, /*stored_L=*/false, failures);
    materials.collect();
    std::exception_ptr error;
    try {
        if (const MaterialFailure *f = failures.material.first()) material_failed(*f, 0);
    } catch (...) {
        error = std::current_exception();
    }
    failed_call.reset(); // the constructor throws: nobody to replay for
    agree(error);
    order.sort(sets);
    arm_quiescence();
}

namespace {

// The count asked for, or OpenMP's default (OMP_NUM_THREADS), within
// kMaxThreads; checked before any parallel loop starts a team of them.
void set_thread_count(int threads) {
    if (threads > kMaxThreads)
        throw Error(fmt::format("{} threads asked for: at most {} (this process may run on {} "
                                "processor(s))",
                                threads, kMaxThreads, par::processors()));
    par::set_threads(threads);
    if (par::max_threads() > kMaxThreads)
        throw Error(fmt::format("OMP_NUM_THREADS asks for {} threads: at most {} (this process may "
                                "run on {} processor(s))",
                                par::max_threads(), kMaxThreads, par::processors()));
}

} // namespace

Simulation::Simulation(const Scenario &scenario, SolverOptions options) {
    set_thread_count(options.threads);
    impl_ = std::make_unique<Impl>(scenario, options, nullptr);
}

Simulation::Simulation(const Scenario &scenario, SolverOptions options, const Snapshot &snapshot) {
    set_thread_count(options.threads);
    options.batch_size = snapshot.batch_size;
    options.sort_disorder = snapshot.sort_disorder;
    impl_ = std::make_unique<Impl>(scenario, options, &snapshot);
}

Simulation::~Simulation() = default;

void Simulation::step(double max_dt) {
    Impl &g = *impl_;
    double dt = std::min(g.time_step(), max_dt);
    if (!(dt > 0.0))
        fail_together(g.comm, fmt::format("step {}: time step {} is not positive", g.step + 1, dt));
    const double t = g.time;
    g.step_end = t + dt;
    g.loads.evaluate(t, dt);
    {
        auto tm = g.timer(Phase::reorder);
        g.order.prepare(g.sets, g.opt.sort_disorder);
        const bool reach = g.opt.active_nodes_only && g.particle_cells && !g.comm.distributed();
        g.grid.reset(reach ? g.grid.reach((*g.particle_cells)[0], (*g.particle_cells)[1])
                           : g.grid.all());
    }
    switch (g.variant) {
    case StepVariant::usl: g.usl(t, dt); break;
    case StepVariant::usl_fused: g.usl_fused(t, dt); break;
    case StepVariant::usf: g.usf(t, dt); break;
    case StepVariant::musl: g.musl(t, dt); break;
    case StepVariant::usavg: g.usavg(t, dt); break;
    }
    g.time = t + dt;
    g.last_dt = dt;
    ++g.step;
    g.watch_quiescence();
}

// dt = cfl h / max(c_p + |v_p|) (seed 000 eq. 45), from the last pass of the
// previous step; a fixed dt as given, refused above the stability limit
// and warned about (once) above the cfl margin.
double Simulation::Impl::time_step() {
    auto tm = timer(Phase::time_step);
    const double dt_crit = max_speed >= 0.0
                               ? (max_speed > 0.0 ? sc.solver.cfl * sc.cell / max_speed
                                                  : std::numeric_limits<double>::infinity())
                               : critical_dt();
    // No particle left to limit the step (every one left the grid or was
    // removed): the last step's length, so that the outputs due go on
    // coming one per output time rather than one for the rest of the stage.
    if (!sc.solver.dt) return std::isfinite(dt_crit) || !(last_dt > 0.0) ? dt_crit : last_dt;
    const double dt = *sc.solver.dt;
    // Above h / max(c + |v|) (a Courant number of 1) the explicit step is
    // unstable and the result is noise: refuse. Between the cfl margin and
    // that it is the user's call: warn once.
    check_fixed_dt(dt_crit);
    if (dt > dt_crit && !warned_dt) {
        warned_dt = true;
        warnings.push_back(fmt::format(
            "step {} (t = {:.6g} s): the fixed dt {:.4g} s exceeds cfl h / max(c + |v|) = {:.4g} "
            "s (below the stability limit, without the cfl margin)",
            step + 1, time, dt, dt_crit));
    }
    return dt;
}

double Simulation::Impl::critical_dt() const {
    struct Max {
        double v = 0.0;
        void merge(const Max &o) { v = std::max(v, o.v); }
    };
    double worst = 0.0;
    for (const ParticleSet &s : sets) {
        const Max m = par::reduce<Max>(s.n, [&](std::size_t p, Max &r) {
            double v2 = 0.0;
            for (std::size_t d = 0; d < static_cast<std::size_t>(sc.dim); ++d)
                v2 += s.v[d][p] * s.v[d][p];
            r.v = std::max(r.v, s.c[p] + std::sqrt(v2));
        });
        worst = std::max(worst, m.v);
    }
    worst = comm.max(worst);
    return worst > 0.0 ? sc.solver.cfl * sc.cell / worst : std::numeric_limits<double>::infinity();
}

void Simulation::Impl::check_fixed_dt(double dt_crit) const {
    if (sc.solver.dt && *sc.solver.dt > dt_crit / sc.solver.cfl)
        fail_together(
            comm, sc.solver.dt_origin.error(fmt::format(
                      "{}: the fixed dt {:.4g} s is above the stability limit h / max(c + |v|) = "
                      "{:.4g} s, "
                      "where the explicit step is unstable; lower solver.dt below cfl times that "
                      "({:.4g} s), or remove it to let cfl choose each step",
                      step == 0 ? std::string("at t = 0")
                                : fmt::format("step {} (t = {:.6g} s)", step + 1, time),
                      *sc.solver.dt, dt_crit / sc.solver.cfl, dt_crit)));
}

double Simulation::time() const { return impl_->time; }
long Simulation::steps() const { return impl_->step; }
double Simulation::last_dt() const { return impl_->last_dt; }
double Simulation::critical_dt() const { return impl_->critical_dt(); }
void Simulation::check_fixed_dt(double dt_crit) const { impl_->check_fixed_dt(dt_crit); }
void Simulation::fixed_dt_warning_given() { impl_->warned_dt = true; }
const std::vector<ParticleSet> &Simulation::sets() const { return impl_->sets; }
std::vector<ParticleSet> &Simulation::sets() {
    impl_->particle_cells.reset();
    impl_->order.invalidate(); // the slabs too: P2G's colours rely on them
    return impl_->sets;
}
const Scenario &Simulation::scenario() const { return impl_->sc; }
const std::vector<std::string> &Simulation::warnings() const { return impl_->warnings; }
const std::optional<FailedCall> &Simulation::failed_call() const { return impl_->failed_call; }
double Simulation::grid_mass() const {
    const Impl &g = *impl_;
    if (!g.comm.distributed()) return g.grid.mass();
    // Each node once: on the rank that owns it.
    double m = 0.0;
    for (std::size_t i = 0; i < g.grid.n_nodes; ++i)
        if (g.decomp.node_owner(g.grid.geo.global(i)) == g.comm.rank()) m += g.grid.node_mass(i);
    return g.comm.sum(m);
}
std::size_t Simulation::active_nodes() const { return impl_->grid.active().nodes(); }
std::size_t Simulation::grid_nodes() const { return impl_->grid.n_nodes; }
int Simulation::max_threads() { return par::max_threads(); }
int Simulation::processors() { return par::processors(); }
void Simulation::set_threads(int threads) { set_thread_count(threads); }
const char *Simulation::kernel_isa() const { return isa_name(impl_->isa); }
long Simulation::parallel_regions() { return par::regions(); }

std::size_t Simulation::particle_count() const {
    long n = 0;
    for (const ParticleSet &s : impl_->sets)
        n += static_cast<long>(s.n);
    return static_cast<std::size_t>(impl_->comm.sum(n));
}

RankTraffic Simulation::traffic() const { return impl_->traffic; }
int Simulation::rank() const { return impl_->comm.rank(); }
const Comm &Simulation::comm() const { return impl_->comm; }

std::array<int, 6> Simulation::cell_box() const {
    const CellBox &b = impl_->decomp.box(impl_->comm.rank());
    return {b.lo[0], b.lo[1], b.lo[2], b.hi[0], b.hi[1], b.hi[2]};
}

std::array<double, Simulation::kPhases> Simulation::phase_seconds() const {
    return impl_->phase_seconds;
}

const char *Simulation::phase_name(int k) {
    static const char *names[kPhases] = {
        "time_step",       "reorder",        "p2g",           "grid_update", "g2p", "dilation",
        "material_update", "move_particles", "halo_exchange", "migration"};
    return names[k];
}

} // namespace talus
