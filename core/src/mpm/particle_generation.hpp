// The particles at t = 0: each group's shape filled with a regular
// sub-lattice of particles_per_cell^dim points per cell, one set per
// material, with the group's initial velocity and stress.
#pragma once

#include <talus/mpm/particles.hpp>
#include <talus/mpm/scenario.hpp>

#include <memory>
#include <vector>

namespace talus {

// Which optional columns the run needs (ParticleSet::has_*).
struct ColumnsInUse {
    bool L = true, dx = true, C = true, divv = true, lp = true;
};

// Throws, at the entry's place in the file, for a group with no particle,
// particles outside the grid, a geostatic stress without gravity down the
// last axis, or a load or fixity that selects no particle.
// instances[m]: the plugin instance of material m.
std::vector<ParticleSet>
generate_particles(const Scenario &sc, ColumnsInUse columns,
                   const std::vector<std::unique_ptr<MaterialInstance>> &instances);

} // namespace talus
