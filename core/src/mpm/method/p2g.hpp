// Phase 1 of the cycle (seed 000): particles to grid.
#pragma once

#include "grid.hpp"
#include "isa.hpp"
#include "loads.hpp"
#include "ordering.hpp"

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
