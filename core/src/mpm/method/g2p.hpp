// Phase 3 of the cycle (seed 000): grid to particles.
#pragma once

#include "kernels/isa.hpp"
#include "method/loads.hpp"
#include "state/grid.hpp"

#include <talus/mpm/particles.hpp>
#include <talus/mpm/scenario.hpp>

#include <cstddef>
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

// A particle's new velocity and position step along one axis from the
// velocities G2P maps to it, the end one v~ and the start one v (eqs. 36
// and 37), written once for a double or a vector pack of them (X): the
// FLIP/PIC blend v~ + alpha (v_p - v), and dt v~ at first order or
// dt (v + v~) / 2 at second (docs/theory.md on eq. 37).
template <class X>
[[gnu::always_inline]] inline void blended_velocity(const X &end, const X &start, const X &v_p,
                                                    double alpha, X &v_new) {
    v_new = end + alpha * (v_p - start);
}
template <class X>
[[gnu::always_inline]] inline void position_step(const X &end, const X &start, double dt,
                                                 bool second, X &step) {
    step = second ? 0.5 * dt * (end + start) : dt * end;
}

// Velocity by the transfer (eq. 36, or PIC with the affine matrix), the
// position step by `motion`, and with `store_gradient` the velocity
// gradient from v~ (eq. 38) into ParticleSet::L.
void g2p_velocity(const G2pTargets &t, const double *vel, double dt, Motion motion,
                  bool store_gradient);
// Where the fused G2P hands the velocity gradients of each block of points
// it has finished, while their data are in cache: the kinematics and the
// material update (phases.cpp ties it to MaterialUpdate). One call per
// block, not per point.
class GradientBlocks {
  public:
    virtual std::size_t block_size() const = 0;
    // The calling thread's buffer for block_size() gradients by columns:
    // component c (row-major 3x3) of the block's point k at
    // c * block_size() + k (entries outside the D x D block stay zero).
    virtual double *buffer() = 0;
    // Points [begin, begin + count) of `set` have their gradients in buffer().
    virtual void take(std::size_t set, std::size_t begin, std::size_t count) = 0;

  protected:
    ~GradientBlocks() = default;
};

// The same with the rest of the particle's step fused in (USL): each block's
// gradients go to `blocks`, and the particles move at once (x += step, no
// dx).
void g2p_velocity_and_update(const G2pTargets &t, const double *vel, double dt, Motion motion,
                             GradientBlocks &blocks);
// The velocity gradient (eq. 38) of the velocity at `offset` of the node
// records `field` into ParticleSet::L, for the schemes whose F follows
// another field than v~ (USF, MUSL, USAVG). With move_dt > 0 the particle
// also steps by move_dt times the velocity at `move_offset` of the same
// records (ParticleSet::dx).
void g2p_gradient(const G2pTargets &t, const double *field, std::size_t offset,
                  std::size_t move_offset, double move_dt);

} // namespace talus
