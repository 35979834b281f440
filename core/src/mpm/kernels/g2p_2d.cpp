// The 2D instances of the G2P kernels (g2p_kernels.hpp).
#include "kernels/g2p_kernels.hpp"

template struct talus::g2p_kernels::Passes<2>;
