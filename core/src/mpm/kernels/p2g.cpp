#include "method/p2g.hpp"

#include "kernels/p2g_kernels.hpp"

namespace talus {

namespace {

void run(p2g_kernels::Pass pass, const P2gSources &src, double *acc) {
    if (src.geo.dim == 2)
        p2g_kernels::run<2>(pass, src, acc);
    else
        p2g_kernels::run<3>(pass, src, acc);
}

} // namespace

void p2g_momentum(const P2gSources &src, double *acc) {
    run(src.affine ? p2g_kernels::Pass::momentum_affine : p2g_kernels::Pass::momentum, src, acc);
}

void p2g_forces(const P2gSources &src, double *acc) { run(p2g_kernels::Pass::forces, src, acc); }

void p2g_momentum_and_forces(const P2gSources &src, double *acc) {
    run(src.affine ? p2g_kernels::Pass::momentum_affine_and_forces
                   : p2g_kernels::Pass::momentum_and_forces,
        src, acc);
}

void p2g_remap(const P2gSources &src, double *acc) { run(p2g_kernels::Pass::remap, src, acc); }

} // namespace talus
