// Reading the dynamic symbol table of a shared library from the file, without
// loading it: what a plugin exports is part of its contract.
#pragma once

#include <filesystem>
#include <string>
#include <vector>

namespace talus {

// Names of the symbols the library defines and exports (global or weak
// binding, default or protected visibility, defined in a section). Throws
// talus::Error if the file is not a readable 64-bit ELF shared object.
std::vector<std::string> exported_symbols(const std::filesystem::path &file);

} // namespace talus
