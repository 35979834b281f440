// The particles of a group: its shape filled with a regular sub-lattice of
// particles_per_cell^dim points per cell, in the set of its material, with
// the group's initial velocity and stress.
#pragma once

#include <talus/mpm/comm.hpp>
#include <talus/mpm/particles.hpp>
#include <talus/mpm/scenario.hpp>

#include <memory>
#include <string_view>
#include <vector>

namespace talus {

// Which optional columns the run needs (ParticleSet::has_*).
struct ColumnsInUse {
    bool L = true, dx = true, C = true, divv = true, lp = true;
};

// One empty set per material that a group uses or a stage switches a
// group to, in that order of first use. instances[m]: the plugin instance
// of material m.
std::vector<ParticleSet> make_sets(const Scenario &sc, ColumnsInUse columns,
                                   const std::vector<std::unique_ptr<MaterialInstance>> &instances);
// The set holding `material`'s particles.
std::size_t set_of_material(const std::vector<ParticleSet> &sets, std::size_t material);

// The id of each group's first particle: the groups' particles take
// consecutive ids in the file's order, whether present from the start or
// appearing in a later stage. Throws, at the group's place in the file,
// for a group with no particle or with particles outside the grid.
std::vector<std::int64_t> first_ids(const Scenario &sc);

// Adds group gi's particles, at their initial state, to the set of its
// material; a geostatic initial stress is that of `gravity`, the gravity
// of the stage the group appears in (refused unless it points down).
void add_group(const Scenario &sc, std::size_t gi, const Vec3 &gravity, std::int64_t first_id,
               std::vector<ParticleSet> &sets);

// Which loads and fixities of a stage's conditions act on each particle,
// by its group and current position (the load and fixity masks). Throws,
// at the entry's place in the file, for one that selects no particle;
// `when` says when ("at t = 0", "at the start of stage 'cut'"). On several
// ranks (collective), an entry is refused when it selects no particle on
// any rank, on every rank alike.
void select_particles(const Scenario &sc, const Conditions &c, std::vector<ParticleSet> &sets,
                      std::string_view when, const Comm &comm = Comm::serial());

} // namespace talus
