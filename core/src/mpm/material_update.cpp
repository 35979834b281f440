#include "material_update.hpp"

#include "kinematics.hpp"
#include "parallel.hpp"

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

MaterialUpdate::MaterialUpdate(MaterialNames names, int batch_size)
    : names_(std::move(names)), batch_(static_cast<std::size_t>(std::max(1, batch_size))) {}

std::optional<MaterialFailure> MaterialUpdate::run(std::vector<ParticleSet> &sets, double t,
                                                   double dt, long step) {
    // One scratch per thread; the thread count may have changed since the
    // last call (omp_set_num_threads between steps).
    if (scratch_.size() < static_cast<std::size_t>(par::max_threads()))
        scratch_.resize(static_cast<std::size_t>(par::max_threads()));
    par::FirstFailure<MaterialFailure> failed;
    for (std::size_t si = 0; si < sets.size(); ++si) {
        ParticleSet &s = sets[si];
        const std::size_t B = batch_;
        par::for_each_block((s.n + B - 1) / B, [&](std::size_t b) {
            Scratch &scr = scratch_[static_cast<std::size_t>(par::thread_index())];
            const std::size_t begin = b * B, count = std::min(B, s.n - begin);
            MaterialFailure failure;
            if (!call(s, si, begin, count, t, dt, step, 1.0, scr, failure)) {
                failed.record(failure);
                return;
            }
            for (std::size_t p = begin; p < begin + count; ++p)
                s.work[p] += 0.5 * s.J[p] * s.vol0[p] * stress_work(&s.stress[6 * p], &s.de[6 * p]);
        });
        const MaterialFailure *first = failed.first();
        for (Scratch &scr : scratch_) {
            cut_steps_ += scr.cuts;
            scr.cuts = 0;
        }
        if (first) return *first;
        std::swap(s.F, s.F_new);
    }
    return std::nullopt;
}

// One plugin call for points [begin, begin + count) of set s, in place. A
// cut-step request is honoured by splitting the increment (strain, and F
// linearly between start and end) into parts (cut_step.hpp). `fraction`:
// this increment's share of the step's.
bool MaterialUpdate::call(ParticleSet &s, std::size_t set, std::size_t begin, std::size_t count,
                          double t, double dt, long step, double fraction, Scratch &scr,
                          MaterialFailure &failure) {
    const std::size_t ns = s.state_size;
    scr.stress0.assign(s.stress.data() + 6 * begin, s.stress.data() + 6 * (begin + count));
    scr.state0.assign(s.state.data() + ns * begin, s.state.data() + ns * (begin + count));
    talus_batch b{};
    b.flags = TALUS_BATCH_WANT_WAVE_SPEED;
    b.n_points = count;
    b.time = t;
    b.dt = dt;
    b.strain_increment = &s.de[6 * begin];
    b.F_start = &s.F[9 * begin];
    b.F_end = &s.F_new[9 * begin];
    b.density = &s.rho[begin];
    b.stress_start = &s.stress[6 * begin];
    b.stress_end = &s.stress[6 * begin];
    b.state_start = ns ? &s.state[ns * begin] : nullptr;
    b.state_end = ns ? &s.state[ns * begin] : nullptr;
    b.wave_speed = &s.c[begin];
    // Whom to blame if the plugin crashes (crash_report.hpp).
    const crash::Task task{names_.material[set],
                           names_.group[static_cast<std::size_t>(s.group[begin])], step,
                           s.id[begin], s.id[begin + count - 1]};
    const crash::TaskScope blame(&task);
    MaterialInstance::Result r = s.instance->update(b);
    if (r.ok()) return true;
    const long parts =
        r.status == TALUS_STATUS_CUT_STEP ? cut_step::parts(r.cut_factor, fraction) : 0;
    if (parts > 0) {
        // Restore the inputs and sub-step this batch.
        std::copy(scr.stress0.begin(), scr.stress0.end(), s.stress.data() + 6 * begin);
        std::copy(scr.state0.begin(), scr.state0.end(), s.state.data() + ns * begin);
        const std::vector<double> de(s.de.data() + 6 * begin, s.de.data() + 6 * (begin + count));
        const std::vector<double> Fa(s.F.data() + 9 * begin, s.F.data() + 9 * (begin + count));
        const std::vector<double> Fb(s.F_new.data() + 9 * begin,
                                     s.F_new.data() + 9 * (begin + count));
        const std::vector<double> rho(s.rho.data() + begin, s.rho.data() + begin + count);
        const double k = static_cast<double>(parts);
        for (long j = 1; j <= parts; ++j) {
            const double a0 = static_cast<double>(j - 1) / k, a1 = static_cast<double>(j) / k;
            for (std::size_t p = 0; p < count; ++p) {
                for (std::size_t c = 0; c < 6; ++c)
                    s.de[6 * (begin + p) + c] = de[6 * p + c] / k;
                for (std::size_t c = 0; c < 9; ++c) {
                    const double A = Fa[9 * p + c], Bc = Fb[9 * p + c];
                    s.F[9 * (begin + p) + c] = A + a0 * (Bc - A);
                    s.F_new[9 * (begin + p) + c] = A + a1 * (Bc - A);
                }
                s.rho[begin + p] = s.rho0 / det3(&s.F_new[9 * (begin + p)]);
            }
            if (!call(s, set, begin, count, t + a0 * dt, dt / k, step, fraction / k, scr, failure))
                return false;
        }
        // Leave F, F_new, de and rho as they were for the caller.
        std::copy(de.begin(), de.end(), s.de.data() + 6 * begin);
        std::copy(Fa.begin(), Fa.end(), s.F.data() + 9 * begin);
        std::copy(Fb.begin(), Fb.end(), s.F_new.data() + 9 * begin);
        std::copy(rho.begin(), rho.end(), s.rho.data() + begin);
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
        std::copy_n(scr.stress0.begin() + static_cast<std::ptrdiff_t>(6 * k), 6,
                    failure.stress_in.begin());
        failure.state_in.assign(scr.state0.begin() + static_cast<std::ptrdiff_t>(ns * k),
                                scr.state0.begin() + static_cast<std::ptrdiff_t>(ns * (k + 1)));
    }
    failure.result = std::move(r);
    return false;
}

} // namespace talus
