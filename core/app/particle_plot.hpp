// `talus run --plot`: the final state of a run, drawn from its
// final_particles.csv by Debian's python3-matplotlib.
#pragma once

#include <filesystem>
#include <string>

namespace talus {

// Draws the particles of `csv` (id, group, coordinates, one field) at their
// final positions, coloured by the field: in 2D the plane, in 3D a side
// view onto the x - z plane. Throws talus::Error when python3 or matplotlib
// is missing or the script fails.
void plot_final_particles(const std::filesystem::path &csv, const std::filesystem::path &png,
                          const std::string &title);

} // namespace talus
