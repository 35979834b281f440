// The 2D instances of the P2G kernels (p2g_kernels.hpp).
#include "kernels/p2g_kernels.hpp"

template void talus::p2g_kernels::run<2>(Pass, const P2gSources &, double *);
