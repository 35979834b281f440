// The particles as VTK XML files ParaView opens directly: one unstructured
// grid of vertex cells per output time (.vtu, binary appended data) and a
// collection (.pvd) listing them with their times. A run on several ranks
// writes a piece per rank and a parallel file (.pvtu) naming the pieces.
#pragma once

#include <talus/mpm/simulation.hpp>

#include <filesystem>
#include <string>
#include <utility>
#include <vector>

namespace talus {

// Writes the particles of `sim` (this rank's) to `file` (complete or not at all: through
// a temporary renamed into place). Point data: id, group, material,
// displacement, velocity, stress, p, q, volume, J, density, mass, F, and
// the named plugin state variables (NaN where a material lacks one). Field
// data: group_names and material_names, indexed by the group and material
// arrays, so a viewer can show names for the integers.
void write_vtu(const std::filesystem::path &file, const Simulation &sim,
               const std::vector<std::string> &state_fields);

// The parallel file of one output time: the point arrays write_vtu writes,
// and the pieces (file names relative to `file`'s folder), one per rank.
void write_pvtu(const std::filesystem::path &file, const Simulation &sim,
                const std::vector<std::string> &state_fields,
                const std::vector<std::string> &pieces);

} // namespace talus
