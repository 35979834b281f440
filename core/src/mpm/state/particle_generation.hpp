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

// The groups' particle ids: consecutive in the file's order of the groups,
// whether present from the start or appearing in a later stage, and within
// a group row by row through its lattice. On several ranks each rank
// generates a share of every group's rows (a contiguous run, in id order;
// collective), so that no rank holds every particle.
struct GroupIds {
    std::vector<std::int64_t> first;       // per group: the id of its first particle
    std::vector<std::int64_t> share_first; // per group: that of this rank's share
};
// Throws, at the group's place in the file, for a group with no particle
// or with particles outside the grid (on several ranks, on every rank).
GroupIds group_ids(const Scenario &sc, const Comm &comm = Comm::serial());

// Adds this rank's share of group gi's particles (all of them on one
// rank), at their initial state, to the set of its material, with ids
// from `first_id` (GroupIds::share_first); a geostatic initial stress is
// that of `gravity`, the gravity of the stage the group appears in
// (refused unless it points down).
void add_group(const Scenario &sc, std::size_t gi, const Vec3 &gravity, std::int64_t first_id,
               std::vector<ParticleSet> &sets, const Comm &comm = Comm::serial());

// Which loads and fixities of a stage's conditions act on each particle,
// by its group and current position (the load and fixity masks). Throws,
// at the entry's place in the file, for one that selects no particle;
// `when` says when ("at t = 0", "at the start of stage 'cut'"). On several
// ranks (collective), an entry is refused when it selects no particle on
// any rank, on every rank alike.
void select_particles(const Scenario &sc, const Conditions &c, std::vector<ParticleSet> &sets,
                      std::string_view when, const Comm &comm = Comm::serial());

} // namespace talus
