#include "method/g2p.hpp"

#include "kernels/g2p_kernels.hpp"

namespace talus {

void g2p_velocity(const G2pTargets &t, const double *vel, double dt, Motion motion,
                  bool store_gradient) {
    if (t.geo.dim == 2)
        g2p_kernels::Passes<2>::velocity(t, vel, dt, motion, store_gradient);
    else
        g2p_kernels::Passes<3>::velocity(t, vel, dt, motion, store_gradient);
}

void g2p_velocity_and_update(const G2pTargets &t, const double *vel, double dt, Motion motion,
                             GradientBlocks &blocks) {
    if (t.geo.dim == 2)
        g2p_kernels::Passes<2>::velocity_and_update(t, vel, dt, motion, blocks);
    else
        g2p_kernels::Passes<3>::velocity_and_update(t, vel, dt, motion, blocks);
}

void g2p_gradient(const G2pTargets &t, const double *field, std::size_t offset,
                  std::size_t move_offset, double move_dt) {
    if (t.geo.dim == 2)
        g2p_kernels::Passes<2>::gradient(t, field, offset, move_offset, move_dt);
    else
        g2p_kernels::Passes<3>::gradient(t, field, offset, move_offset, move_dt);
}

} // namespace talus
