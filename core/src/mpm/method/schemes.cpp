// The schemes (docs/theory.md, "The four schemes"): when the stress is
// updated within a step, and which grid velocity moves the particles and
// advances F ("Kinematic consistency"). Each is the seed's four phases in
// its own order: P2G, grid update, G2P (velocity, kinematics, material
// update), and the step's end. A grid update after which the step reads
// the accumulators no more clears them as it goes (Accumulators::clear):
// all but MUSL's, whose remap maps onto the masses again.
#include "simulation_state.hpp"

namespace talus {

using node::kForce, node::kMomentum;

// Update stress last: L from v~, the particles move with v~ (or with
// (v + v~) / 2 at second order).
void Simulation::Impl::usl(double t, double dt) {
    p2g_momentum_and_forces();
    grid_update(t, dt, Accumulators::clear);
    g2p_velocity(dt, /*store_gradient=*/true);
    material_update(t, dt);
    move_particles(PositionStep::add_dx);
}

// USL with the kinematics, the material update and the step's end done
// block by block inside the G2P loop while the block's data are in cache:
// no stored gradient, no position step, two passes over the particles less.
// g2p_velocity_and_update (phases.cpp) hands each block G2P has finished to
// MaterialUpdate::block (material_update.cpp), then to the step's end.
void Simulation::Impl::usl_fused(double t, double dt) {
    p2g_momentum_and_forces();
    grid_update(t, dt, Accumulators::clear);
    g2p_velocity_and_update(t, dt);
}

// Update stress first: L from the mapped start velocities v, which also
// move the particles; then the forces from the updated stress.
void Simulation::Impl::usf(double t, double dt) {
    p2g_momentum();
    grid_velocity(t);
    const std::size_t v = node::velocity(grid.geo.dim);
    g2p_gradient(grid.vel.data(), v, v, dt);
    material_update(t, dt);
    p2g_forces();
    grid_update(t, dt, Accumulators::clear);
    g2p_velocity(dt, /*store_gradient=*/false);
    move_particles(PositionStep::add_dx);
}

// Modified USL (Sulsky et al. 1995): USL's velocity update, then the
// updated particle momentum is mapped again and L taken from that field,
// which also moves the particles (moved by v~ instead, they drift from what
// F records under a held load).
void Simulation::Impl::musl(double t, double dt) {
    p2g_momentum_and_forces();
    grid_update(t, dt);
    g2p_velocity(dt, /*store_gradient=*/false);
    p2g_remap();
    remapped_velocity(t + dt);
    const bool mean = velocity_motion == Motion::mean_velocity;
    g2p_gradient(grid.acc.data(), kForce, mean ? kMomentum : kForce, dt);
    material_update(t, dt);
    move_particles(PositionStep::add_dx);
}

// Update stress average (Nairn 2003): half the increment from v before the
// forces, half from v~ after; the particles move with (v + v~) / 2.
void Simulation::Impl::usavg(double t, double dt) {
    p2g_momentum();
    grid_velocity(t);
    g2p_gradient(grid.vel.data(), node::velocity(grid.geo.dim), 0, 0.0);
    material_update(t, 0.5 * dt);
    p2g_forces();
    grid_update(t, dt, Accumulators::clear);
    g2p_velocity(dt, /*store_gradient=*/true);
    material_update(t + 0.5 * dt, 0.5 * dt);
    move_particles(PositionStep::add_dx);
}

} // namespace talus
