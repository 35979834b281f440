// `talus point --plot`: the four panels a soil engineer reads, drawn by
// Debian's python3-matplotlib from the driver's CSV.
#pragma once

#include <filesystem>
#include <string>

namespace talus {

// Draws PNG from the CSV file `csv` (the driver's columns): q against axial
// strain, volumetric against axial strain, the q - p' path, and the
// controlled quantities against time. Throws talus::Error when python3 or
// matplotlib is missing or the script fails.
void plot_point_csv(const std::filesystem::path &csv, const std::filesystem::path &png,
                    const std::string &title);

} // namespace talus
