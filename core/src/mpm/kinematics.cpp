#include "kinematics.hpp"

#include <algorithm>

namespace talus {

namespace {

std::size_t cell_of(const GridGeometry &geo, const ParticleSet &s, std::size_t p) {
    const double x[3] = {s.x[0][p], s.x[1][p], geo.dim == 3 ? s.x[2][p] : 0.0};
    return geo.cell_index(x);
}

// Volume-weighted mean of div v over the points in each cell (eq. 53; the
// cell is the one containing the point), then eq. 52 on the normal strain
// increments of the dim in-plane directions, then the first half of the
// stress work with the averaged increment.
void average_dilation(std::vector<ParticleSet> &sets, const GridGeometry &geo, double dt,
                      DilationCells &cells) {
    std::fill(cells.div.begin(), cells.div.end(), 0.0);
    std::fill(cells.vol.begin(), cells.vol.end(), 0.0);
    for (auto &s : sets)
        for (std::size_t p = 0; p < s.n; ++p) {
            const std::size_t c = cell_of(geo, s, p);
            const double V = s.J[p] * s.vol0[p];
            cells.div[c] += s.divv[p] * V;
            cells.vol[c] += V;
        }
    const int dim = geo.dim;
    for (auto &s : sets)
        par::for_each(s.n, [&](std::size_t p) {
            const std::size_t c = cell_of(geo, s, p);
            const double corr = dt * (cells.div[c] / cells.vol[c] - s.divv[p]) / dim;
            for (int d = 0; d < dim; ++d)
                s.de[6 * p + static_cast<std::size_t>(d)] += corr;
            s.work[p] += 0.5 * s.J[p] * s.vol0[p] * stress_work(&s.stress[6 * p], &s.de[6 * p]);
        });
}

} // namespace

std::optional<Inversion> kinematics(std::vector<ParticleSet> &sets, const GridGeometry &geo,
                                    double dt, DilationCells *dilation) {
    par::FirstFailure<Inversion> inverted;
    const int dim = geo.dim;
    const bool defer = dilation != nullptr;
    for (std::size_t si = 0; si < sets.size(); ++si) {
        ParticleSet &s = sets[si];
        par::for_each(s.n, [&](std::size_t p) {
            if (!kinematics_point<3>(s, p, &s.L[9 * p], dt, dim, defer)) inverted.record({si, p});
        });
    }
    if (const Inversion *first = inverted.first()) return *first;
    if (dilation) average_dilation(sets, geo, dt, *dilation);
    return std::nullopt;
}

} // namespace talus
