// The phases as the schemes call them: each times itself under its own
// name and hands its kernel the parts of the state it reads and writes.
#include "simulation_state.hpp"

#include "method/grid_update.hpp"
#include "profile/split_pass_clock.hpp"

#include <talus/material/cut_step.hpp>
#include <talus/material/plugin_loader.hpp>

#include <fmt/format.h>

namespace talus {

// On several ranks each P2G is followed by the sums of the nodes the ranks
// share (Halo), of the fields it wrote.
void Simulation::Impl::p2g_momentum() {
    {
        auto tm = timer(Phase::p2g);
        talus::p2g_momentum(p2g_sources(), grid.acc.data());
    }
    if (comm.distributed()) exchange(Halo::kMomentumFields);
}

void Simulation::Impl::p2g_forces() {
    {
        auto tm = timer(Phase::p2g);
        talus::p2g_forces(p2g_sources(), grid.acc.data());
    }
    if (comm.distributed()) exchange(Halo::kForceFields);
}

void Simulation::Impl::p2g_momentum_and_forces() {
    {
        auto tm = timer(Phase::p2g);
        talus::p2g_momentum_and_forces(p2g_sources(), grid.acc.data());
    }
    if (comm.distributed()) exchange(Halo::kAllFields);
}

void Simulation::Impl::p2g_remap() {
    {
        auto tm = timer(Phase::p2g);
        grid.clear_momentum();
        talus::p2g_remap(p2g_sources(), grid.acc.data());
    }
    if (comm.distributed()) exchange(Halo::kRemapFields);
}

void Simulation::Impl::grid_velocity(double t) {
    auto tm = timer(Phase::grid_update);
    talus::grid_velocity(grid, boundary, t);
}

void Simulation::Impl::grid_update(double t, double dt, Accumulators after) {
    auto tm = timer(Phase::grid_update);
    talus::grid_update(grid, boundary, t, dt, conditions().damping, after,
                       velocity_motion == Motion::mean_velocity ? StartVelocity::constrained
                                                                : StartVelocity::as_mapped);
}

void Simulation::Impl::remapped_velocity(double t_end) {
    auto tm = timer(Phase::grid_update);
    talus::remapped_velocity(grid, boundary, t_end, velocity_motion == Motion::mean_velocity);
}

void Simulation::Impl::g2p_velocity(double dt, bool store_gradient) {
    auto tm = timer(Phase::g2p);
    talus::g2p_velocity(g2p_targets(), grid.vel.data(), dt, velocity_motion, store_gradient);
}

namespace {

// The fused USL's hand-off of each block of points G2P has finished, while
// their data are in cache: first the kinematics and material update of the
// block from its velocity gradients, then the block's step end (positions,
// faces, the next dt's speed).
struct UpdateThenEnd {
    MaterialUpdate &materials;
    StepEndBlocks &ends;
    std::vector<ParticleSet> &sets;
    const Increment &inc;
    UpdateFailures &failures;

    std::size_t block_size() const { return materials.block_size(); }
    double *buffer() { return materials.gradient_buffer(); }
    void first(std::size_t set, std::size_t begin, std::size_t count) {
        materials.block(sets[set], set, begin, count,
                        Gradients::columns(materials.gradient_buffer(), materials.block_size()),
                        inc, failures);
    }
    void second(std::size_t set, std::size_t begin, std::size_t count) {
        ends.block(set, begin, count);
    }
};

} // namespace

void Simulation::Impl::g2p_velocity_and_update(double t, double dt) {
    UpdateFailures failures;
    materials.prepare(sets);
    step_ends.begin(sets, grid.geo, domain, order, PositionStep::already_moved,
                    materials.block_size(), isa);
    const Increment inc{t, dt, step + 1, nullptr, nullptr};
    UpdateThenEnd hand_off{materials, step_ends, sets, inc, failures};
    // G2P gives each block it finishes to hand_off: first() runs the
    // material update (MaterialUpdate::block, material_update.cpp), second()
    // the step's end (move_particles.cpp). The pass's time split into G2P's, the material update's
    // and the step end's, as the split pipeline would report them.
    SplitPassClock clock(hand_off);
    clock.run(
        [&](GradientBlocks &blocks) {
            talus::g2p_velocity_and_update(g2p_targets(), grid.vel.data(), dt, velocity_motion,
                                           blocks);
        },
        seconds_of(Phase::g2p), seconds_of(Phase::material_update),
        seconds_of(Phase::move_particles));
    materials.collect();
    update_failed(failures, t);
    auto tm = timer(Phase::move_particles);
    step_ended(step_ends.finish());
}

void Simulation::Impl::g2p_gradient(const double *field, std::size_t offset,
                                    std::size_t move_offset, double move_dt) {
    auto tm = timer(Phase::g2p);
    talus::g2p_gradient(g2p_targets(), field, offset, move_offset, move_dt);
}

void Simulation::Impl::material_update(double t, double dt) {
    const bool averaged = sc.solver.cell_averaged_dilation;
    if (averaged) {
        std::optional<Inversion> inv;
        {
            auto tm = timer(Phase::dilation);
            inv = dilation_sums(sets, grid.geo, dt, dilation);
        }
        std::exception_ptr error;
        try {
            if (inv) inverted(*inv, t);
        } catch (...) {
            error = std::current_exception();
        }
        agree(error);
    }
    UpdateFailures failures;
    {
        auto tm = timer(Phase::material_update);
        const Increment inc{t, dt, step + 1, averaged ? &dilation : nullptr, &grid.geo};
        materials.run(sets, inc, /*stored_L=*/true, failures);
        materials.collect();
    }
    update_failed(failures, t);
}

void Simulation::Impl::update_failed(const UpdateFailures &f, double t) {
    std::exception_ptr error;
    try {
        if (const Inversion *inv = f.inverted.first()) inverted(*inv, t);
        if (const MaterialFailure *m = f.material.first()) material_failed(*m, step + 1);
    } catch (...) {
        error = std::current_exception();
    }
    agree(error); // on several ranks, every rank learns of a failure on one
}

void Simulation::Impl::move_particles(PositionStep how) {
    auto tm = timer(Phase::move_particles);
    step_ended(talus::move_particles(sets, grid.geo, domain, order, how, step_ends, isa));
}

void Simulation::Impl::step_ended(const StepEnd &mine) {
    // Over all ranks: the next dt's speed and the counts.
    StepEnd end = mine;
    if (comm.distributed()) {
        double peak[2] = {end.max_speed, end.held_depth};
        long counts[2] = {end.held, end.outside};
        comm.max(peak, 2);
        comm.sum(counts, 2);
        end = StepEnd{peak[0], counts[0], peak[1], counts[1]};
    }
    max_speed = end.max_speed;
    // This rank's cells (a removal below only shrinks them). On several
    // ranks the halo sums land on nodes beyond a rank's particles and
    // migration brings particles from elsewhere: every node then.
    if (!comm.distributed()) particle_cells = {{mine.cell_lo, mine.cell_hi}};
    held_at_faces += end.held;
    held_depth = std::max(held_depth, end.held_depth);
    if (end.outside > 0) {
        const bool remove = sc.solver.leave == LeavePolicy::remove;
        const Leaving out = collect_leaving(sets, domain, sc.dim, remove, group_names);
        order.invalidate(); // indices moved
        const long left = comm.sum(out.count);
        if (left > 0 && remove) {
            if (removed == 0)
                warnings.push_back(fmt::format(
                    "step {} (t = {:.6g} s): {} particle(s) left the grid and were removed "
                    "(solver.leaving_grid: remove); the column 'removed' of diagnostics.csv "
                    "counts them from here on",
                    step + 1, step_end, left));
            removed += left;
        }
        if (left > 0 && !remove) {
            // The first rank's list with them (each lists at most ten).
            std::string list;
            for (const std::string &r : out.first)
                list.append("\n  ").append(r);
            if (out.count > static_cast<long>(out.first.size()))
                list.append(fmt::format("\n  ... and {} more{}",
                                        out.count - static_cast<long>(out.first.size()),
                                        comm.distributed() ? " on this rank" : ""));
            const auto first = comm.first_failure(out.count > 0 ? &list : nullptr);
            fail_together(
                comm, fmt::format("step {} (t = {:.6g} s): {} particle(s) left the grid (policy "
                                  "solver.leaving_grid: stop; use 'remove' to delete them "
                                  "instead):{}",
                                  step + 1, step_end, left, first ? first->message : ""));
        }
    }
    if (comm.distributed()) {
        migrate();
        rebalance_if_uneven();
    }
}

[[noreturn]] void Simulation::Impl::inverted(const Inversion &inv, double t) const {
    const ParticleSet &s = sets[inv.set];
    const std::size_t p = inv.particle;
    throw Error(fmt::format(
        "step {} (t = {:.6g} s): particle {} of group '{}' inverted (J = {:.3g} <= 0): the "
        "deformation in one step is too large; reduce cfl or dt",
        step + 1, t, s.id[p], group_names[static_cast<std::size_t>(s.group[p])], s.J[p]));
}

[[noreturn]] void Simulation::Impl::material_failed(const MaterialFailure &f, long step_number) {
    const ParticleSet &s = sets[f.set];
    const MaterialInstance::Result &r = f.result;
    const bool at_point = r.point >= 0 && static_cast<std::size_t>(r.point) < f.count;
    const std::size_t p = f.begin + (at_point ? static_cast<std::size_t>(r.point) : 0);
    const bool cut = r.status == TALUS_STATUS_CUT_STEP;
    if (at_point) {
        // The failing point's inputs, those of the failing part of a cut
        // step.
        FailedCall fc;
        fc.material = s.material;
        fc.particle = s.id[p];
        fc.step = step_number;
        fc.time = f.t;
        fc.dt = f.dt;
        fc.density = f.density;
        for (std::size_t c = 0; c < 6; ++c)
            fc.strain_increment[c] = f.strain_increment[c];
        fc.stress = f.stress_in;
        for (std::size_t c = 0; c < 9; ++c) {
            fc.F_start[c] = f.F_start[c];
            fc.F_end[c] = f.F_end[c];
        }
        fc.state = f.state_in;
        fc.cut_step = cut;
        fc.message = r.message;
        failed_call = std::move(fc);
    }
    const NamedMaterial &mat = sc.materials[s.material];
    const std::string where =
        at_point
            ? fmt::format("particle {} of group '{}' at ({:.6g}, {:.6g}{})", s.id[p],
                          group_names[static_cast<std::size_t>(s.group[p])], s.x[0][p], s.x[1][p],
                          sc.dim == 3 ? fmt::format(", {:.6g}", s.x[2][p]) : std::string())
            : fmt::format("a batch of {} particles", f.count);
    throw Error(fmt::format(
        "{}step {} (t = {:.6g} s): material '{}' (model '{}', {}) failed at {}: {}{}",
        step_number == 0 ? "initial state: " : "", step + 1, f.t, mat.name, mat.spec.model->id(),
        mat.spec.model->library().path().string(), where, r.message,
        cut ? fmt::format(" (still asking for a smaller step with the increment cut to {:g} of "
                          "the step's)",
                          cut_step::kSmallestPart)
            : std::string()));
}

} // namespace talus
