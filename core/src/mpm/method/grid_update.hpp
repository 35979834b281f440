// Phase 2 of the cycle (seed 000): the grid update.
#pragma once

#include "method/boundary.hpp"
#include "state/grid.hpp"

#include <talus/mpm/scenario.hpp>

namespace talus {

// v = p / m (eq. 30) with the boundary conditions at t, into
// Grid::vel[node::velocity(dim)].
void grid_velocity(Grid &grid, const Boundary &bc, double t);
// v as above, and v~ = v + dt f / m (eqs. 31-32) with the conditions at
// t + dt into Grid::vel[node::kEndVelocity].
// With `damping`, the nodal force is damped first (DampingSpec), from the
// velocity v at t.
// With Accumulators::clear (a scheme whose step reads Grid::acc no more),
// the accumulators are cleared as they are read, each node's mass kept in
// Grid::vel[node::kMassCopy] (Grid::accumulators_cleared); they stay as
// they are with prescribed velocities or particle fixities, whose nodes
// the pass cannot tell apart.
enum class Accumulators { keep, clear };
// The start velocity v at a contact face (slip, friction), which the G2P
// reads for FLIP's increment v~ - v and for a position step by the mean
// velocity: `as_mapped`, p / m, the contact acting on v~ alone, so that
// the increment carries the wall's impulse to the particles (with v
// constrained too, a particle's velocity into the wall was never taken
// away: it stayed, its kinetic energy frozen, while the grid held it
// still); `constrained` where the particles move by the mean velocity,
// which must not carry them into the wall. Clamps, rollers and prescribed
// velocities constrain v always: a clamped node's v is 0 (seed 000).
enum class StartVelocity { as_mapped, constrained };
void grid_update(Grid &grid, const Boundary &bc, double t, double dt,
                 const DampingSpec &damping = {}, Accumulators after = Accumulators::keep,
                 StartVelocity start = StartVelocity::constrained);
// MUSL: the remapped velocity v_R = p_R / m with the conditions at t_end,
// written over the force slots of Grid::acc (free after the grid update),
// and with `mean` also (v + v_R) / 2 over the momentum slots (for the
// second-order position update).
void remapped_velocity(Grid &grid, const Boundary &bc, double t_end, bool mean);

} // namespace talus
