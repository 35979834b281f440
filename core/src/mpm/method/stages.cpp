// Stages (docs/theory.md, "Stages"): what changes when a stage begins (its
// conditions, groups that appear or go, a group's new material, reset
// displacements or velocities) and how the run knows the stage is over (its
// duration, or the motion died out).
#include "simulation_state.hpp"

#include "parallel/parallel.hpp"
#include "state/particle_generation.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <limits>

namespace talus {

void Simulation::Impl::start_points(std::size_t set, std::size_t begin) {
    if (sets[set].n == begin) return;
    UpdateFailures failures;
    materials.start(sets, set, begin, sets[set].n - begin, time, failures);
    materials.collect();
    if (const MaterialFailure *f = failures.material.first()) material_failed(*f, 0);
}

// On several ranks each generates its share of a group's rows (as at the
// start), and the particles go to their cells' ranks before their set-up
// call.
void Simulation::Impl::add_groups(const std::vector<std::size_t> &groups, const Vec3 &gravity) {
    for (std::size_t g : groups) {
        const std::size_t set = set_of_material(sets, sc.groups[g].material);
        const std::size_t begin = sets[set].n;
        together(comm, [&] { add_group(sc, g, gravity, first_id[g], sets, comm); });
        if (comm.distributed()) arrive(set, begin);
        together(comm, [&] { start_points(set, begin); });
    }
}

void Simulation::Impl::remove_groups(const std::vector<std::size_t> &groups) {
    for (ParticleSet &s : sets) {
        std::size_t keep = 0;
        for (std::size_t p = 0; p < s.n; ++p)
            if (std::find(groups.begin(), groups.end(), static_cast<std::size_t>(s.group[p])) ==
                groups.end())
                s.move(p, keep++);
        s.resize(keep);
    }
}

// The group's particles keep their motion, deformation and stress, and
// start the new material's state from its initial values; the new plugin's
// set-up call then sees the stress (and may return it to its yield
// surface, saying so, as at t = 0).
void Simulation::Impl::switch_material(const MaterialSwitch &sw) {
    const std::size_t to = set_of_material(sets, sw.material);
    ParticleSet &dst = sets[to];
    const std::size_t begin = dst.n;
    const std::vector<double> &q_init = sc.materials[sw.material].spec.initial_state;
    for (std::size_t si = 0; si < sets.size(); ++si) {
        if (si == to) continue;
        ParticleSet &src = sets[si];
        const auto of_group = [&](std::size_t p) {
            return static_cast<std::size_t>(src.group[p]) == sw.group;
        };
        std::size_t moving = 0;
        for (std::size_t p = 0; p < src.n; ++p)
            moving += of_group(p) ? 1 : 0;
        if (moving == 0) continue;
        std::size_t q = dst.n, keep = 0;
        dst.resize(q + moving);
        for (std::size_t p = 0; p < src.n; ++p) {
            if (!of_group(p)) {
                src.move(p, keep++);
                continue;
            }
            dst.copy_point(src, p, q);
            std::copy(q_init.begin(), q_init.end(), dst.state.data() + q * dst.state_size);
            ++q;
        }
        src.resize(keep);
    }
    start_points(to, begin);
}

void Simulation::Impl::begin_stage(std::size_t k) {
    gravity_before = loads.gravity_at(time);
    stage = k;
    stage_start = time;
    const StageSpec &st = stages[k];
    // Each rank changes its own particles; a plugin refusing a point's
    // state on one rank stops every rank before the next collective.
    together(comm, [&] {
        remove_groups(st.remove);
        for (const MaterialSwitch &sw : st.set_material)
            switch_material(sw);
    });
    add_groups(st.activate, st.conditions.gravity);
    for (ParticleSet &s : sets)
        for (std::size_t p = 0; p < s.n; ++p) {
            for (std::size_t d = 0; d < static_cast<std::size_t>(sc.dim); ++d) {
                if (st.reset_displacement) s.x0[d][p] = s.x[d][p];
                if (st.reset_velocity) s.v[d][p] = 0.0;
            }
            if (st.reset_velocity && s.has_C) std::fill_n(&s.C[9 * p], 9, 0.0);
        }
    boundary = Boundary(sc, st.conditions, grid, time, comm);
    loads = Loads(sc, st.conditions, gravity_before, time);
    domain = domain_of(sc, st.conditions);
    select_particles(sc, st.conditions, sets,
                     fmt::format("at the start of stage '{}' (t = {:.6g} s)", st.name, time), comm);
    order.sort(sets);
    max_speed = -1.0; // new particles, new velocities: the next step measures afresh
    particle_cells.reset();
    arm_quiescence();
}

// sum 1/2 m v^2 over sum V sigma:sigma / (2 rho c^2): the kinetic energy
// over an estimate of the strain energy that needs no elastic constants
// but the plugins' wave speeds (exact for a uniaxial strain of a linear
// elastic material, where rho c^2 is the constrained modulus).
double Simulation::Impl::kinetic_energy_ratio() const {
    struct Sum {
        double kinetic = 0.0, strain = 0.0;
        void merge(const Sum &o) {
            kinetic += o.kinetic;
            strain += o.strain;
        }
    };
    Sum total;
    const std::size_t D = static_cast<std::size_t>(sc.dim);
    for (const ParticleSet &s : sets) {
        const double inv_rho0 = 1.0 / s.rho0;
        const Sum part = par::reduce<Sum>(s.n, [&](std::size_t p, Sum &r) {
            double v2 = 0.0;
            for (std::size_t d = 0; d < D; ++d)
                v2 += s.v[d][p] * s.v[d][p];
            r.kinetic += 0.5 * s.mass[p] * v2;
            const double *sig = &s.stress[6 * p];
            const double ss = sig[0] * sig[0] + sig[1] * sig[1] + sig[2] * sig[2] +
                              2.0 * (sig[3] * sig[3] + sig[4] * sig[4] + sig[5] * sig[5]);
            const double c = s.c[p];
            // V / rho = m J^2 / rho0^2.
            if (c > 0.0)
                r.strain += 0.5 * s.mass[p] * s.J[p] * s.J[p] * inv_rho0 * inv_rho0 * ss / (c * c);
        });
        total.merge(part);
    }
    if (comm.distributed()) {
        double both[2] = {total.kinetic, total.strain};
        comm.sum(both, 2);
        total.kinetic = both[0];
        total.strain = both[1];
    }
    if (total.kinetic == 0.0) return 0.0;
    return total.strain > 0.0 ? total.kinetic / total.strain
                              : std::numeric_limits<double>::infinity();
}

// Default hold: 8 P-wave transits of the present material's largest extent
// at its fastest wave speed: at least one period of the slowest shear mode
// of a body standing on its base (4 H / c_s, with c_s about c_p / 2).
double Simulation::Impl::default_hold() const {
    double lo[3] = {1e300, 1e300, 1e300}, hi[3] = {-1e300, -1e300, -1e300}, c = 0.0;
    for (const ParticleSet &s : sets)
        for (std::size_t p = 0; p < s.n; ++p) {
            for (std::size_t d = 0; d < static_cast<std::size_t>(sc.dim); ++d) {
                lo[d] = std::min(lo[d], s.x[d][p]);
                hi[d] = std::max(hi[d], s.x[d][p]);
            }
            c = std::max(c, s.c[p]);
        }
    if (comm.distributed()) { // the body's extent and speed over all ranks
        comm.min(lo, 3);
        comm.max(hi, 3);
        c = comm.max(c);
    }
    double extent = 0.0;
    for (int d = 0; d < sc.dim; ++d)
        extent = std::max(extent, hi[d] - lo[d] + sc.cell);
    return c > 0.0 ? 8.0 * extent / c : 0.0;
}

void Simulation::Impl::arm_quiescence() {
    below_since.reset();
    hold.reset();
    ratio = std::numeric_limits<double>::quiet_NaN();
    if (const auto &u = stages[stage].until) hold = u->hold ? *u->hold : default_hold();
}

void Simulation::Impl::watch_quiescence() {
    const StageSpec &st = stages[stage];
    if (!st.until) return;
    ratio = kinetic_energy_ratio();
    if (ratio < st.until->kinetic_energy_ratio) {
        if (!below_since) below_since = time - last_dt;
    } else {
        below_since.reset();
    }
}

StageEnd Simulation::stage_end_reached() const {
    const Impl &g = *impl_;
    const StageSpec &st = g.stages[g.stage];
    if (st.until && g.below_since && g.hold && g.time - *g.below_since >= *g.hold * (1.0 - 1e-12))
        return StageEnd::quiescent;
    if (g.time >= stage_end() * (1.0 - 1e-12)) return StageEnd::duration;
    return StageEnd::running;
}

void Simulation::begin_next_stage() {
    Impl &g = *impl_;
    if (g.stage + 1 >= g.stages.size()) throw std::logic_error("begin_next_stage: no next stage");
    g.begin_stage(g.stage + 1);
}

double Simulation::kinetic_energy_ratio() const { return impl_->kinetic_energy_ratio(); }
std::size_t Simulation::stage() const { return impl_->stage; }
double Simulation::stage_start() const { return impl_->stage_start; }
double Simulation::stage_end() const {
    return impl_->stage_start + impl_->stages[impl_->stage].duration;
}
const std::vector<StageSpec> &Simulation::stages() const { return impl_->stages; }
double Simulation::last_kinetic_energy_ratio() const { return impl_->ratio; }
std::optional<double> Simulation::quiet_since() const { return impl_->below_since; }

} // namespace talus
