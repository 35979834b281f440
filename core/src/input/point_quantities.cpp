// The quantities of a driver row (talus/input/point_case.hpp): the
// components, the geotechnical invariants (compression positive) and the
// state variables, by the names of the driver's CSV columns.
#include <talus/input/point_case.hpp>

#include <talus/sdk/voigt.hpp>

#include <fmt/format.h>

#include <cmath>

namespace talus {

using Vec6 = PointVec6;

namespace {

// Deviatoric-strain invariant sqrt(2/3 e:e) of a tensor-component vector.
double shear_strain_invariant(const Vec6 &e) {
    const double m = (e[0] + e[1] + e[2]) / 3.0;
    const double d0 = e[0] - m, d1 = e[1] - m, d2 = e[2] - m;
    return std::sqrt(
        2.0 / 3.0 *
        (d0 * d0 + d1 * d1 + d2 * d2 + 2.0 * (e[3] * e[3] + e[4] * e[4] + e[5] * e[5])));
}

} // namespace

std::optional<double> point_quantity(const PointRow &r, const MaterialInstance &material, int axis,
                                     const std::string &name) {
    for (std::size_t c = 0; c < 6; ++c) {
        if (name == fmt::format("eps_{}", kVoigtNames[c])) return r.strain[static_cast<int>(c)];
        if (name == fmt::format("sig_{}", kVoigtNames[c])) return r.stress[static_cast<int>(c)];
    }
    const int l1 = (axis + 1) % 3, l2 = (axis + 2) % 3;
    if (name == "time") return r.time;
    if (name == "stage") return r.stage;
    // 0.0 - x: a negated zero prints as 0, not -0.
    if (name == "p") return 0.0 - (r.stress[0] + r.stress[1] + r.stress[2]) / 3.0;
    if (name == "q") return sdk::von_mises(r.stress);
    if (name == "eps_v") return 0.0 - (r.strain[0] + r.strain[1] + r.strain[2]);
    if (name == "eps_q") return shear_strain_invariant(r.strain);
    if (name == "eps_a") return 0.0 - r.strain[axis];
    if (name == "sig_a") return 0.0 - r.stress[axis];
    if (name == "sig_r") return 0.0 - 0.5 * (r.stress[l1] + r.stress[l2]);
    if (name == "q_a") return 0.5 * (r.stress[l1] + r.stress[l2]) - r.stress[axis];
    if (name == "eta") {
        const double p = sdk::mean_pressure(r.stress);
        return p != 0.0 ? sdk::von_mises(r.stress) / p : 0.0;
    }
    std::size_t k = 0;
    for (const StateInfo &s : material.state().vars) {
        for (std::uint32_t j = 0; j < s.size; ++j, ++k) {
            const std::string col = s.size == 1 ? s.name : fmt::format("{}_{}", s.name, j);
            if (name == col && k < r.state.size()) return r.state[k];
        }
    }
    return std::nullopt;
}

} // namespace talus
