// Particles move to the rank owning their cell (docs/mpi.md, "Migration"):
// after each step's end, and after a rebalance, with every column of the
// set (the plugin's state, of any size, included).
#pragma once

#include "ranks/decomposition.hpp"
#include "state/grid.hpp"

#include <talus/mpm/comm.hpp>
#include <talus/mpm/particles.hpp>

#include <array>
#include <cstddef>
#include <vector>

namespace talus {

// The cell (i, j, k) of particle p, clamped into the domain (the unused
// axis of 2D is 0): what decides its rank.
inline std::array<int, 3> particle_cell(const GridGeometry &geo, const ParticleSet &s,
                                        std::size_t p) {
    std::array<int, 3> c{0, 0, 0};
    for (int d = 0; d < geo.dim; ++d)
        c[static_cast<std::size_t>(d)] = geo.cell(d, s.x[static_cast<std::size_t>(d)][p]);
    return c;
}

struct Migration {
    long sent = 0, received = 0; // particles
    std::size_t bytes_sent = 0;
};

// Sends each particle whose cell `decomp` gives another rank to it, and
// appends the particles sent here (in ascending rank of the sender, each
// sender's in its memory order); the particles that stay keep their
// order. Collective. A step moves a particle less than a cell (the time
// step's stability limit), so it goes to a neighbour (`peers`); should one
// go farther, every rank takes part in an exchange with all the others.
Migration migrate(const Comm &comm, const Decomposition &decomp, const std::vector<int> &peers,
                  const GridGeometry &geo, std::vector<ParticleSet> &sets);

} // namespace talus
