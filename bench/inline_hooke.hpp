// linear_elastic's update done by the host, with no plugin call, SDK loop
// or host screen: talus_bench installs it (--material-path inline_hooke) as
// the solver's material hook (talus/mpm/material_hook.hpp), so that an A/B
// against the plugin path measures what that path costs (bench/README.md,
// "Plugin overhead").
#pragma once

#include <talus/material/plugin_loader.hpp>

#include <cmath>
#include <cstddef>

namespace talus::bench {

// For an instance of linear_elastic: the stress (and wave speed) of
// `count` points, with the plugin's own arithmetic
// (plugins/linear_elastic), so the results are the same to the bit
// (tests/unit/mpm/test_material_hook.cpp). Returns false, doing nothing,
// for any other model. The model check and the moduli are per call, i.e.
// per block of 128 points: tens of nanoseconds against the block's
// microseconds, so they do not bias the A/B.
inline bool inline_hooke(const MaterialInstance &m, std::size_t count, const double *stress_in,
                         const double *de, const double *rho, double *stress_out, double *c) {
    if (m.model().id() != "linear_elastic") return false;
    const double E = m.parameters()[0].scalar, nu = m.parameters()[1].scalar;
    const double shear = E / (2.0 * (1.0 + nu));
    const double lambda = E * nu / ((1.0 + nu) * (1.0 - 2.0 * nu));
    const double p_wave = lambda + 2.0 * shear;
    for (std::size_t k = 0; k < count; ++k) {
        const double *e = de + 6 * k;
        const double *s0 = stress_in + 6 * k;
        double *s1 = stress_out + 6 * k;
        const double lam_tr = lambda * (e[0] + e[1] + e[2]);
        for (int i = 0; i < 3; ++i) {
            s1[i] = s0[i] + (lam_tr + 2.0 * shear * e[i]);
            s1[i + 3] = s0[i + 3] + shear * e[i + 3];
        }
        c[k] = std::sqrt(p_wave / rho[k]);
    }
    return true;
}

} // namespace talus::bench
