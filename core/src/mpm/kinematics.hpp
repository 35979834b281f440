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

// One point: F, J, rho, the strain increment, div v, the rotated start
// stress and (unless deferred) the first half of the stress work. Returns
// false if the point inverted (J <= 0). L is a row-major 3x3 (Stride 3) or
// D x D (Stride D). Not inlined: in the fused G2P its ~150 flops are better
// as a call than as more live registers in the stencil loop (inlined, the
// 3D USL step was 4 to 8 % slower in talus_bench).
template <int Stride>
[[gnu::noinline]] bool kinematics_point(ParticleSet &s, std::size_t p, const double *Lg, double dt,
                                        int dim, bool defer_work) {
    double L[9] = {0, 0, 0, 0, 0, 0, 0, 0, 0};
    for (int r = 0; r < (Stride == 3 ? 3 : Stride); ++r)
        for (int c = 0; c < (Stride == 3 ? 3 : Stride); ++c)
            L[3 * r + c] = Lg[Stride * r + c];
    const double *F0 = &s.F[9 * p];
    double *F1 = &s.F_new[9 * p];
    double J;
    if (dim == 2) {
        // Plane strain: only the in-plane block of F changes.
        const double a00 = 1.0 + dt * L[0], a01 = dt * L[1], a10 = dt * L[3], a11 = 1.0 + dt * L[4];
        F1[0] = a00 * F0[0] + a01 * F0[3];
        F1[1] = a00 * F0[1] + a01 * F0[4];
        F1[3] = a10 * F0[0] + a11 * F0[3];
        F1[4] = a10 * F0[1] + a11 * F0[4];
        F1[2] = F1[5] = F1[6] = F1[7] = 0.0;
        F1[8] = F0[8];
        J = (F1[0] * F1[4] - F1[1] * F1[3]) * F1[8];
    } else {
        for (int i = 0; i < 3; ++i)
            for (int j = 0; j < 3; ++j)
                F1[3 * i + j] = F0[3 * i + j] + dt * (L[3 * i] * F0[j] + L[3 * i + 1] * F0[3 + j] +
                                                      L[3 * i + 2] * F0[6 + j]);
        J = F1[0] * (F1[4] * F1[8] - F1[5] * F1[7]) - F1[1] * (F1[3] * F1[8] - F1[5] * F1[6]) +
            F1[2] * (F1[3] * F1[7] - F1[4] * F1[6]);
    }
    // A failing J is kept too: the error message and the failure output
    // show the value that failed, not the last valid one.
    s.J[p] = J;
    if (!(J > 0.0)) return false;
    s.rho[p] = s.rho0 / J;
    double *de = &s.de[6 * p];
    de[0] = dt * L[0];
    de[1] = dt * L[4];
    de[2] = dt * L[8];
    de[3] = dt * (L[1] + L[3]);
    de[4] = dt * (L[5] + L[7]);
    de[5] = dt * (L[2] + L[6]);
    if (s.has_divv) s.divv[p] = L[0] + L[4] + L[8];
    if (!s.finite_strain) hughes_winget(L, dt, &s.stress[6 * p]);
    if (!defer_work) s.work[p] += 0.5 * J * s.vol0[p] * stress_work(&s.stress[6 * p], de);
    return true;
}

// Cell-averaged dilation (seed 000 eqs. 47-53): sums per cell, kept between
// steps to avoid reallocating them.
struct DilationCells {
    std::vector<double> div, vol;
};

// Every point's kinematics from its stored L over dt; with `dilation`, each
// point's dilation is then replaced by its cell's volume-weighted mean
// before the first half of the stress work. Returns the first inverted
// point, if any.
std::optional<Inversion> kinematics(std::vector<ParticleSet> &sets, const GridGeometry &geo,
                                    double dt, DilationCells *dilation);

} // namespace talus
