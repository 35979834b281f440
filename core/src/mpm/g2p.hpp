// Phase 3 of the cycle (seed 000): grid to particles.
#pragma once

#include "grid.hpp"
#include "isa.hpp"
#include "kinematics.hpp"
#include "loads.hpp"

#include <talus/mpm/particles.hpp>
#include <talus/mpm/scenario.hpp>

#include <optional>
#include <vector>

namespace talus {

struct G2pTargets {
    const GridGeometry &geo;
    std::vector<ParticleSet> &sets;
    const Loads &loads; // the fixities override the grid's answer
    ShapeKind shape;
    Transfer transfer;
    double alpha; // FLIP fraction (0 for the affine transfers)
    Isa isa;      // the kernels' instruction set
};

// How the particles move in the velocity pass (docs/theory.md, "Kinematic
// consistency"): not at all (their scheme moves them in the gradient pass),
// by dt v~, or by dt (v + v~) / 2. The step goes into ParticleSet::dx.
enum class Motion { none, end_velocity, mean_velocity };

// Velocity by the transfer (eq. 36, or PIC with the affine matrix), the
// position step by `motion`, and with `store_gradient` the velocity
// gradient from v~ (eq. 38) into ParticleSet::L.
void g2p_velocity(const G2pTargets &t, const double *vel, double dt, Motion motion,
                  bool store_gradient);
// The same with the kinematics fused in (USL): L stays in registers and
// goes straight into kinematics_point, and the particles move at once
// (x += step, no dx). Returns the first inverted point, if any.
std::optional<Inversion> g2p_velocity_and_kinematics(const G2pTargets &t, const double *vel,
                                                     double dt, Motion motion);
// The velocity gradient (eq. 38) of the velocity at `offset` of the node
// records `field` into ParticleSet::L, for the schemes whose F follows
// another field than v~ (USF, MUSL, USAVG). With move_dt > 0 the particle
// also steps by move_dt times the velocity at `move_offset` of the same
// records (ParticleSet::dx).
void g2p_gradient(const G2pTargets &t, const double *field, std::size_t offset,
                  std::size_t move_offset, double move_dt);

} // namespace talus
