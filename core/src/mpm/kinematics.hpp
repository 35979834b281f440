// The kinematics of a material point over one step, from its velocity
// gradient: F (seed 000 eq. 39), J, density (eq. 41), the strain increment
// (eq. 42), div v, and the objective rotation of the start stress.
#pragma once

#include "grid.hpp"
#include "parallel.hpp"

#include <talus/mpm/particles.hpp>
#include <talus/mpm/stress_rotation.hpp>

#include <cstddef>
#include <optional>
#include <vector>

namespace talus {

inline double stress_work(const double *sig, const double *de) {
    return sig[0] * de[0] + sig[1] * de[1] + sig[2] * de[2] + sig[3] * de[3] + sig[4] * de[4] +
           sig[5] * de[5];
}

// A particle whose J fell to zero or below: the run cannot go on.
struct Inversion {
    std::size_t set = 0, particle = 0;
    bool before(const Inversion &o) const {
        return set != o.set ? set < o.set : particle < o.particle;
    }
};

// F at the end of the step, F1 = (I + dt L) F0 (eq. 39), and its
// determinant J. L is row-major 3x3; in plane strain only the in-plane
// block of F changes.
template <int D>
[[gnu::always_inline]] inline double deformation_point(const double *F0, const double *L, double dt,
                                                       double *F1) {
    if constexpr (D == 2) {
        const double a00 = 1.0 + dt * L[0], a01 = dt * L[1], a10 = dt * L[3], a11 = 1.0 + dt * L[4];
        F1[0] = a00 * F0[0] + a01 * F0[3];
        F1[1] = a00 * F0[1] + a01 * F0[4];
        F1[3] = a10 * F0[0] + a11 * F0[3];
        F1[4] = a10 * F0[1] + a11 * F0[4];
        F1[2] = F1[5] = F1[6] = F1[7] = 0.0;
        F1[8] = F0[8];
        return (F1[0] * F1[4] - F1[1] * F1[3]) * F1[8];
    } else {
        for (int i = 0; i < 3; ++i)
            for (int j = 0; j < 3; ++j)
                F1[3 * i + j] = F0[3 * i + j] + dt * (L[3 * i] * F0[j] + L[3 * i + 1] * F0[3 + j] +
                                                      L[3 * i + 2] * F0[6 + j]);
        return F1[0] * (F1[4] * F1[8] - F1[5] * F1[7]) - F1[1] * (F1[3] * F1[8] - F1[5] * F1[6]) +
               F1[2] * (F1[3] * F1[7] - F1[4] * F1[6]);
    }
}

inline double deformation_point(const double *F0, const double *L, double dt, int dim, double *F1) {
    return dim == 2 ? deformation_point<2>(F0, L, dt, F1) : deformation_point<3>(F0, L, dt, F1);
}

// Where a block's kinematics go: the material update's per-thread block
// scratch (nothing of it persists past the step), per point k at 9 k, 6 k
// and k.
struct BlockIncrement {
    double *F_end; // 9 per point, row-major
    double *de;    // 6 per point, Voigt with engineering shears
    double *rho;
};

// Points [begin, begin + count) of s from their velocity gradients L
// (row-major 3x3, L_stride apart): F at the end of the step, J (kept in the
// particle), rho (eq. 41), the strain increment (eq. 42), div v and the
// rotated start stress. Returns the block index of the first point that
// inverted (J <= 0), or count. The stress work is the caller's: it needs
// the end stress too. One loop per dimension and rotation, with no
// per-point call; the one option left inside (div v kept or not) is a
// loop-invariant test.
template <int D, bool Rotate>
inline std::size_t kinematics_block_impl(ParticleSet &s, std::size_t begin, std::size_t count,
                                         const double *L, std::size_t L_stride, double dt,
                                         const BlockIncrement &out) {
    const double rho0 = s.rho0;
    double *divv = s.has_divv ? &s.divv[begin] : nullptr;
    for (std::size_t k = 0; k < count; ++k) {
        const std::size_t p = begin + k;
        const double *Lp = L + L_stride * k;
        const double J = deformation_point<D>(&s.F[9 * p], Lp, dt, out.F_end + 9 * k);
        // A failing J is kept too: the error message and the failure
        // output show the value that failed, not the last valid one.
        s.J[p] = J;
        if (!(J > 0.0)) [[unlikely]]
            return k;
        out.rho[k] = rho0 / J;
        double *de = out.de + 6 * k;
        de[0] = dt * Lp[0];
        de[1] = dt * Lp[4];
        de[2] = dt * Lp[8];
        de[3] = dt * (Lp[1] + Lp[3]);
        de[4] = dt * (Lp[5] + Lp[7]);
        de[5] = dt * (Lp[2] + Lp[6]);
        if (divv) divv[k] = Lp[0] + Lp[4] + Lp[8];
        if constexpr (Rotate) hughes_winget(Lp, dt, &s.stress[6 * p]);
    }
    return count;
}

inline std::size_t kinematics_block(ParticleSet &s, std::size_t begin, std::size_t count,
                                    const double *L, std::size_t L_stride, double dt,
                                    const BlockIncrement &out) {
    // Strain-increment models get the objectively rotated start stress;
    // finite-strain models own their objectivity (material_abi.h).
    const bool rotate = !s.finite_strain;
    if (s.dim == 2)
        return rotate ? kinematics_block_impl<2, true>(s, begin, count, L, L_stride, dt, out)
                      : kinematics_block_impl<2, false>(s, begin, count, L, L_stride, dt, out);
    return rotate ? kinematics_block_impl<3, true>(s, begin, count, L, L_stride, dt, out)
                  : kinematics_block_impl<3, false>(s, begin, count, L, L_stride, dt, out);
}

// Cell-averaged dilation (seed 000 eqs. 47-53): sums per cell, kept between
// steps to avoid reallocating them.
struct DilationCells {
    std::vector<double> div, vol;
};

inline std::size_t cell_of(const GridGeometry &geo, const ParticleSet &s, std::size_t p) {
    const double x[3] = {s.x[0][p], s.x[1][p], geo.dim == 3 ? s.x[2][p] : 0.0};
    return geo.owned_cell_index(x);
}

// The first part of cell-averaged dilation: every point's J at the end of
// the step and div v from its stored L, then each cell's volume-weighted
// sums of div v (eq. 53; the cell is the one containing the point). The
// material update then replaces each point's dilation by its cell's mean
// (dilation_correction). Returns the first inverted point, if any.
std::optional<Inversion> dilation_sums(std::vector<ParticleSet> &sets, const GridGeometry &geo,
                                       double dt, DilationCells &cells);

// Eq. 52: what each normal strain increment in the dim in-plane directions
// gains so that the point's dilation becomes its cell's mean.
inline double dilation_correction(const DilationCells &cells, const GridGeometry &geo,
                                  const ParticleSet &s, std::size_t p, double dt) {
    const std::size_t c = cell_of(geo, s, p);
    return dt * (cells.div[c] / cells.vol[c] - s.divv[p]) / geo.dim;
}

} // namespace talus
