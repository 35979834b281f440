// Phase 1 of the cycle (seed 000): particles to grid.
#pragma once

#include "kernels/isa.hpp"
#include "method/loads.hpp"
#include "parallel/ordering.hpp"
#include "state/grid.hpp"

#include <talus/mpm/particles.hpp>

#include <vector>

namespace talus {

// What the particles carry to the grid, one pass over them (and the node
// records in Grid::acc it adds to).
struct P2gSources {
    const GridGeometry &geo;
    const std::vector<ParticleSet> &sets;
    const Ordering &order;
    const Loads &loads;
    ShapeKind shape;
    bool affine; // APIC / TPIC: momentum carries m C_p (x_i - x_p)
    Isa isa;     // the kernels' instruction set
};

// A particle's contributions to its nodes, written once for a double or a
// vector pack of them (X). Per unit weight: the momentum m v (eq. 29) and
// the external force m g + f (eq. 21, f the particle's applied load); per
// unit gradient of the weight along c, the internal force -V sigma[:, c]
// (eq. 20), V = J V0 the current volume, sigma in Voigt order (xx, yy, zz,
// xy, yz, zx), its in-plane part for D = 2.
template <class X>
[[gnu::always_inline]] inline void particle_momentum(const X &m, const X &v, X &momentum) {
    momentum = m * v;
}
template <class X>
[[gnu::always_inline]] inline void external_force(const X &m, double g, const X &load, X &force) {
    force = load + m * g;
}
template <int D, class X>
[[gnu::always_inline]] inline void internal_force(const X &volume, const X *sigma,
                                                  X (&per_gradient)[D][D]) {
    constexpr int voigt[3][3] = {{0, 3, 5}, {3, 1, 4}, {5, 4, 2}};
    const X minus_V = -volume;
    for (int c = 0; c < D; ++c)
        for (int r = 0; r < D; ++r)
            per_gradient[c][r] = minus_V * sigma[voigt[r][c]];
}

// Nodal mass (eq. 28) and momentum with the affine term (eq. 29); the nodes
// fixed particles reach are marked (node::kFixity).
void p2g_momentum(const P2gSources &src, double *acc);
// Internal force with the current volume and Cauchy stress (eq. 20) and the
// external force, gravity and applied loads (eq. 21).
void p2g_forces(const P2gSources &src, double *acc);
// Both in one pass (USL, MUSL).
void p2g_momentum_and_forces(const P2gSources &src, double *acc);
// Momentum alone without the affine term, from the updated particle
// velocities: MUSL's remap (Sulsky et al. 1995).
void p2g_remap(const P2gSources &src, double *acc);

} // namespace talus
