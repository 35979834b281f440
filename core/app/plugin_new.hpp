// `talus plugin new NAME`: a ready-to-build plugin project for an installed
// Talus (find_package(Talus)), which passes `talus plugin check` as written:
// CMakeLists.txt, the model's source with a parameter table and a state
// variable, a driver case compared with its closed form, and the tests.
#pragma once

#include <filesystem>
#include <string>

namespace talus {

// Writes the project into parent/name (which must not exist); returns that
// folder. Throws talus::Error for a name that is not lower_snake_case or a
// folder that exists; every file is written atomically.
std::filesystem::path write_plugin_project(const std::string &name,
                                           const std::filesystem::path &parent);

} // namespace talus
