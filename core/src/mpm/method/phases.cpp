// The phases as the schemes call them: each times itself under its own
// name and hands its kernel the parts of the state it reads and writes.
#include "simulation_state.hpp"

#include "grid_update.hpp"
#include "ticks.hpp"

#include <talus/material/cut_step.hpp>
#include <talus/material/plugin_loader.hpp>

#include <fmt/format.h>

#include <chrono>
#include <cstdint>

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
    talus::grid_update(grid, boundary, t, dt, conditions().damping, after);
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

// The fused G2P's blocks go straight into the material update, then to the
// step's end. The time each thread spends in the two is kept apart (one
// cache line each) so that the phases' shares stay those of the split
// pipeline: three reads a block of the processor's cycle counter (ticks.hpp),
// the middle one shared, turned into seconds by the pass's own rate of ticks
// to seconds. (Three reads of the system's clock a block of 128 points were
// 1 % of a 2D step: a call each, and under a hypervisor a slow one.)
class MaterialBlocks final : public GradientBlocks {
  public:
    MaterialBlocks(MaterialUpdate &m, StepEndBlocks &ends, std::vector<ParticleSet> &sets,
                   const Increment &inc, UpdateFailures &failures)
        : m_(m), ends_(ends), sets_(sets), inc_(inc), failures_(failures),
          ticks_(static_cast<std::size_t>(par::max_threads())) {}
    std::size_t block_size() const override { return m_.block_size(); }
    double *buffer() override { return m_.gradient_buffer(); }
    void take(std::size_t set, std::size_t begin, std::size_t count) override {
        const std::uint64_t t0 = ticks();
        m_.block(sets_[set], set, begin, count,
                 Gradients::columns(m_.gradient_buffer(), m_.block_size()), inc_, failures_);
        const std::uint64_t t1 = ticks();
        ends_.block(set, begin, count);
        const std::uint64_t t2 = ticks();
        Ticks &mine = ticks_[static_cast<std::size_t>(par::thread_index())];
        mine.material += ticks_between(t0, t1);
        mine.end += ticks_between(t1, t2);
    }
    // The material blocks' and the end blocks' ticks, per thread on average.
    double material_ticks() const { return average(&Ticks::material); }
    double end_ticks() const { return average(&Ticks::end); }

  private:
    struct alignas(64) Ticks {
        std::uint64_t material = 0, end = 0;
    };
    double average(std::uint64_t Ticks::*part) const {
        double sum = 0.0;
        for (const Ticks &t : ticks_)
            sum += static_cast<double>(t.*part);
        return sum / static_cast<double>(ticks_.size());
    }
    MaterialUpdate &m_;
    StepEndBlocks &ends_;
    std::vector<ParticleSet> &sets_;
    const Increment &inc_;
    UpdateFailures &failures_;
    std::vector<Ticks> ticks_;
};

} // namespace

void Simulation::Impl::g2p_velocity_and_update(double t, double dt) {
    UpdateFailures failures;
    materials.prepare(sets);
    step_ends.begin(sets, grid.geo, domain, order, PositionStep::already_moved,
                    materials.block_size(), isa);
    const Increment inc{t, dt, step + 1, nullptr, nullptr};
    MaterialBlocks blocks(materials, step_ends, sets, inc, failures);
    const auto s0 = std::chrono::steady_clock::now();
    const std::uint64_t t0 = ticks();
    talus::g2p_velocity_and_update(g2p_targets(), grid.vel.data(), dt, velocity_motion, blocks);
    const std::uint64_t t1 = ticks();
    const double pass =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - s0).count();
    // The material update's and the step end's shares of the fused pass, as
    // their own phases.
    materials.collect();
    const std::uint64_t pass_ticks = ticks_between(t0, t1);
    const double per_tick = pass_ticks > 0 ? pass / static_cast<double>(pass_ticks) : 0.0;
    const double in_blocks = blocks.material_ticks() * per_tick,
                 in_ends = blocks.end_ticks() * per_tick;
    auto &ph = phase_seconds;
    ph[static_cast<std::size_t>(Phase::g2p)] += pass - in_blocks - in_ends;
    ph[static_cast<std::size_t>(Phase::material_update)] += in_blocks;
    ph[static_cast<std::size_t>(Phase::move_particles)] += in_ends;
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
        if (left > 0 && remove) removed += left;
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
