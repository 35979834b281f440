#include "method/material_update.hpp"

#include <talus/material/crash_report.hpp>
#include <talus/material/cut_step.hpp>

#include <algorithm>

namespace talus {

namespace {

// Row-major 3x3 determinant.
double det3(const double *F) {
    return F[0] * (F[4] * F[8] - F[5] * F[7]) - F[1] * (F[3] * F[8] - F[5] * F[6]) +
           F[2] * (F[3] * F[7] - F[4] * F[6]);
}

} // namespace

MaterialUpdate::MaterialUpdate(MaterialNames names, int batch_size, double characteristic_length,
                               Isa isa, MaterialBlockHook hook)
    : names_(std::move(names)), batch_(static_cast<std::size_t>(std::max(1, batch_size))),
      length_(characteristic_length), isa_(isa), hook_(hook) {}

void MaterialUpdate::prepare(const std::vector<ParticleSet> &sets) {
    // The thread count may have changed since the last call
    // (omp_set_num_threads between steps).
    if (scratch_.size() < static_cast<std::size_t>(par::max_threads()))
        scratch_.resize(static_cast<std::size_t>(par::max_threads()));
    std::size_t ns = 0;
    for (const ParticleSet &s : sets)
        ns = std::max<std::size_t>(ns, s.state_size);
    const std::size_t B = batch_;
    for (Scratch &scr : scratch_) {
        if (scr.L.size() == 9 * B && scr.state.size() >= ns * B) continue;
        scr.L.assign(9 * B, 0.0);
        scr.F_start.resize(9 * B);
        scr.F_end.resize(9 * B);
        scr.rotation.resize(9 * B);
        scr.length.assign(B, length_);
        scr.de.resize(6 * B);
        scr.rho.resize(B);
        scr.work_start.resize(B);
        scr.stress_start.resize(6 * B);
        scr.state.resize(ns * B);
    }
}

void MaterialUpdate::run(std::vector<ParticleSet> &sets, const Increment &inc, bool stored_L,
                         UpdateFailures &failures) {
    prepare(sets);
    static const double zero_L[9] = {};
    for (std::size_t si = 0; si < sets.size(); ++si) {
        ParticleSet &s = sets[si];
        const std::size_t B = batch_;
        par::for_each_block((s.n + B - 1) / B, [&](std::size_t b) {
            const std::size_t begin = b * B, count = std::min(B, s.n - begin);
            const Gradients L =
                stored_L ? Gradients::rows(&s.L[9 * begin]) : Gradients::same(zero_L);
            block(s, si, begin, count, L, inc, failures);
        });
    }
}

void MaterialUpdate::start(std::vector<ParticleSet> &sets, std::size_t set, std::size_t begin,
                           std::size_t count, double t, UpdateFailures &failures) {
    prepare(sets);
    static const double zero_L[9] = {};
    const Increment inc{.t = t};
    const std::size_t B = batch_;
    par::for_each_block((count + B - 1) / B, [&](std::size_t b) {
        const std::size_t first = begin + b * B;
        block(sets[set], set, first, std::min(B, begin + count - first), Gradients::same(zero_L),
              inc, failures);
    });
}

double *MaterialUpdate::gradient_buffer() {
    return scratch_[static_cast<std::size_t>(par::thread_index())].L.data();
}

void MaterialUpdate::collect() {
    for (Scratch &scr : scratch_) {
        cut_steps_ += scr.cuts;
        scr.cuts = 0;
    }
}

void MaterialUpdate::block(ParticleSet &s, std::size_t set, std::size_t begin, std::size_t count,
                           const Gradients &L, const Increment &inc, UpdateFailures &failures) {
    Scratch &scr = scratch_[static_cast<std::size_t>(par::thread_index())];
    bool finite = true;
    const std::size_t done = kinematics_block(
        s, begin, count, L, inc.dt,
        {scr.F_start.data(), s.dim == 2 ? scr.F_end.data() : nullptr, scr.stress_start.data(),
         scr.de.data(), scr.rho.data(), scr.work_start.data(), &finite},
        isa_);
    if (done < count) {
        // A failed step leaves the block's F as it found it (the
        // kinematics wrote F at the end over it).
        restore_F(s, begin, done, scr.F_start.data());
        failures.inverted.record({set, begin + done});
        return;
    }
    if (inc.dilation)
        for (std::size_t k = 0; k < count; ++k) {
            // Eq. 52: each point's dilation becomes its cell's mean.
            const double corr = dilation_correction(*inc.dilation, *inc.geo, s, begin + k, inc.dt);
            for (int d = 0; d < s.dim; ++d)
                scr.de[6 * k + static_cast<std::size_t>(d)] += corr;
            // The kinematics' start work was on the increment before this.
            scr.work_start[k] = stress_work(&scr.stress_start[6 * k], &scr.de[6 * k]);
        }
    // The model reads the start stress from the kinematics' scratch and
    // writes the end stress over the particle's; the state goes to scratch
    // and is committed after the call. The inputs of any retry stay.
    // The increment's rotation for a model that rotates tensor state itself
    // (UMAT's DROT): the Hughes-Winget rotation the host gave the stress.
    if (s.wants_rotation)
        for (std::size_t k = 0; k < count; ++k) {
            double Lk[9];
            L.copy(k, Lk);
            hughes_winget_rotation(Lk, inc.dt, &scr.rotation[9 * k]);
        }
    const std::size_t ns = s.state_size;
    const Inputs in{scr.stress_start.data(), ns ? &s.state[ns * begin] : nullptr,
                    scr.F_start.data(), s.dim == 2 ? scr.F_end.data() : &s.F[9 * begin],
                    scr.de.data(), scr.rho.data(), s.wants_rotation ? scr.rotation.data() : nullptr,
                    // Not on the set-up call, whose initial stress and state
                    // are the scenario's, nor where cell averaging changed
                    // the increment after the kinematics tested it.
                    finite && inc.step > 0 && !inc.dilation};
    const Outputs out{&s.stress[6 * begin], ns ? scr.state.data() : nullptr};
    MaterialFailure failure;
    // One branch a block when no hook is installed.
    const bool inlined =
        hook_ && hook_(*s.instance, count, in.stress, in.de, in.rho, out.stress, &s.c[begin]);
    if (!inlined &&
        !advance(s, set, begin, count, inc.t, inc.dt, inc.step, 1.0, 0, in, out, scr, failure)) {
        // The step failed: the block's F and stress as the plugin found
        // them (the stress as turned for it, as the points before a
        // failure elsewhere keep it).
        restore_F(s, begin, count, scr.F_start.data());
        std::copy_n(scr.stress_start.data(), 6 * count, &s.stress[6 * begin]);
        failures.material.record(failure);
        return;
    }
    // The stress work over the step (trapezoidal: the rotated start stress
    // and the end stress on the increment; the first from the kinematics).
    stress_work_block(s, begin, count, scr.de.data(), scr.work_start.data(), isa_);
    if (ns) std::copy_n(scr.state.data(), ns * count, &s.state[ns * begin]);
}

void MaterialUpdate::restore_F(ParticleSet &s, std::size_t begin, std::size_t count,
                               const double *F_start) {
    for (std::size_t k = 0; k < count; ++k)
        s.set_F(begin + k, F_start + 9 * k);
}

// Advances points [begin, begin + count) of set s over [t, t + dt] from
// `in` to `out` (which never alias). A cut-step request is honoured by
// splitting the increment (strain, and F linearly between start and end)
// into parts (cut_step.hpp), each advanced the same way one level deeper,
// the parts' results alternating between the level's two buffers and the
// last one written to `out`. `fraction`: this increment's share of the
// step's.
bool MaterialUpdate::advance(ParticleSet &s, std::size_t set, std::size_t begin, std::size_t count,
                             double t, double dt, long step, double fraction, std::size_t depth,
                             const Inputs &in, const Outputs &out, Scratch &scr,
                             MaterialFailure &failure) {
    const std::size_t ns = s.state_size;
    talus_batch b{};
    b.flags = TALUS_BATCH_WANT_WAVE_SPEED | (in.finite ? TALUS_BATCH_INPUTS_FINITE : 0u);
    b.n_points = count;
    b.time = t;
    b.dt = dt;
    b.strain_increment = in.de;
    b.F_start = in.F_start;
    b.F_end = in.F_end;
    b.density = in.rho;
    b.stress_start = in.stress;
    b.stress_end = out.stress;
    b.state_start = ns ? in.state : nullptr;
    b.state_end = ns ? out.state : nullptr;
    b.wave_speed = &s.c[begin];
    b.step = step;
    b.point_id = &s.id[begin];
    b.characteristic_length = scr.length.data();
    b.rotation = in.rotation;
    // Whom to blame if the plugin crashes (crash_report.hpp).
    const MaterialInstance::AloneCall alone{s.instance, &b, step == 0};
    const crash::Task task{.material = names_.material[set],
                           .step = step,
                           .group_names = names_.group.data(),
                           .group = &s.group[begin],
                           .ids = &s.id[begin],
                           .count = count,
                           .run_alone = &MaterialInstance::run_alone,
                           .alone_context = &alone};
    const crash::TaskScope blame(&task);
    // Step 0 is the set-up call (the plugin's init_state when it has one).
    MaterialInstance::Result r = step == 0 ? s.instance->start(b) : s.instance->update(b);
    if (r.ok()) return true;
    const long parts =
        r.status == TALUS_STATUS_CUT_STEP ? cut_step::parts(r.cut_factor, fraction) : 0;
    if (parts > 0) {
        if (scr.levels.size() <= depth) scr.levels.resize(depth + 1);
        Level &lv = scr.levels[depth];
        lv.F_start.resize(9 * count);
        lv.F_end.resize(9 * count);
        lv.de.resize(6 * count);
        lv.rho.resize(count);
        for (auto *buf : {&lv.stress[0], &lv.stress[1]})
            buf->resize(6 * count);
        for (auto *buf : {&lv.state[0], &lv.state[1]})
            buf->resize(ns * count);
        if (in.rotation && lv.identity.size() < 9 * count) {
            lv.identity.assign(9 * count, 0.0);
            for (std::size_t p = 0; p < count; ++p)
                lv.identity[9 * p] = lv.identity[9 * p + 4] = lv.identity[9 * p + 8] = 1.0;
        }
        const double k = static_cast<double>(parts);
        for (std::size_t p = 0; p < count; ++p)
            for (std::size_t c = 0; c < 6; ++c)
                lv.de[6 * p + c] = in.de[6 * p + c] / k;
        Inputs part = in;
        part.finite = false;
        for (long j = 1; j <= parts; ++j) {
            const double a0 = static_cast<double>(j - 1) / k, a1 = static_cast<double>(j) / k;
            for (std::size_t p = 0; p < count; ++p) {
                for (std::size_t c = 0; c < 9; ++c) {
                    const double A = in.F_start[9 * p + c], Bc = in.F_end[9 * p + c];
                    lv.F_start[9 * p + c] = A + a0 * (Bc - A);
                    lv.F_end[9 * p + c] = A + a1 * (Bc - A);
                }
                lv.rho[p] = s.rho0 / det3(&lv.F_end[9 * p]);
            }
            // The start stress was rotated once, before the first part: the
            // later parts turn by nothing more.
            if (j > 1 && in.rotation) part.rotation = lv.identity.data();
            part.F_start = lv.F_start.data();
            part.F_end = lv.F_end.data();
            part.de = lv.de.data();
            part.rho = lv.rho.data();
            const std::size_t buf = static_cast<std::size_t>(j % 2);
            const Outputs to =
                j == parts ? out
                           : Outputs{lv.stress[buf].data(), ns ? lv.state[buf].data() : nullptr};
            if (!advance(s, set, begin, count, t + a0 * dt, dt / k, step, fraction / k, depth + 1,
                         part, to, scr, failure))
                return false;
            part.stress = to.stress;
            part.state = to.state;
        }
        ++scr.cuts;
        return true;
    }
    failure.set = set;
    failure.begin = begin;
    failure.count = count;
    failure.t = t;
    failure.dt = dt;
    if (r.point >= 0 && static_cast<std::size_t>(r.point) < count) {
        const std::size_t k = static_cast<std::size_t>(r.point);
        std::copy_n(in.stress + 6 * k, 6, failure.stress_in.begin());
        std::copy_n(in.de + 6 * k, 6, failure.strain_increment.begin());
        std::copy_n(in.F_start + 9 * k, 9, failure.F_start.begin());
        std::copy_n(in.F_end + 9 * k, 9, failure.F_end.begin());
        failure.density = in.rho[k];
        if (ns) failure.state_in.assign(in.state + ns * k, in.state + ns * (k + 1));
    }
    failure.result = std::move(r);
    return false;
}

} // namespace talus
