#include "kinematics.hpp"

#include <algorithm>

namespace talus {

std::optional<Inversion> dilation_sums(std::vector<ParticleSet> &sets, const GridGeometry &geo,
                                       double dt, DilationCells &cells) {
    par::FirstFailure<Inversion> inverted;
    const int dim = geo.dim;
    for (std::size_t si = 0; si < sets.size(); ++si) {
        ParticleSet &s = sets[si];
        par::for_each(s.n, [&](std::size_t p) {
            double F_end[9];
            const double *L = &s.L[9 * p];
            // The same arithmetic as the material update's kinematics_block,
            // which recomputes J: both see the same value.
            s.J[p] = deformation_point(&s.F[9 * p], L, dt, dim, F_end);
            if (!(s.J[p] > 0.0)) inverted.record({si, p});
            s.divv[p] = L[0] + L[4] + L[8];
        });
    }
    if (const Inversion *first = inverted.first()) return *first;
    std::fill(cells.div.begin(), cells.div.end(), 0.0);
    std::fill(cells.vol.begin(), cells.vol.end(), 0.0);
    for (auto &s : sets)
        for (std::size_t p = 0; p < s.n; ++p) {
            const std::size_t c = cell_of(geo, s, p);
            const double V = s.J[p] * s.vol0[p];
            cells.div[c] += s.divv[p] * V;
            cells.vol[c] += V;
        }
    return std::nullopt;
}

} // namespace talus
