// Digests of a checkpoint file's bytes, kept in the file's user block (the
// space HDF5 leaves to the application at the start of the file): one per
// array's stored values, one of everything else (the attributes and HDF5's
// own structures), and one of the table itself. They are checked on the
// raw bytes before HDF5 reads anything of the file, so that a damaged
// checkpoint is refused, naming the array, and HDF5 never parses damaged
// structures (which it can misread, or crash on).
#pragma once

#include <hdf5.h>

#include <cstdint>
#include <filesystem>
#include <optional>
#include <string>
#include <vector>

namespace talus::checkpoint_digests {

// An array's stored values: where they start in the file, how many bytes.
struct Range {
    std::string name; // "/sets/0/x"
    std::uint64_t offset = 0, bytes = 0;
};

// The user block a file with these arrays needs (a power of two, at least
// 512 bytes, as HDF5 requires): `arrays` of names `name_bytes` long in all.
std::size_t userblock_size(std::size_t arrays, std::size_t name_bytes);

// Every array of the open file `file` with stored values. Throws
// talus::Error (without the file's name) when HDF5 fails.
std::vector<Range> arrays(hid_t file);

// Writes the digests into the user block of the closed file `file`.
// Throws talus::Error when a read or write fails, or the table does not
// fit the user block.
void seal(const std::filesystem::path &file, std::size_t userblock,
          const std::vector<Range> &arrays);

// Whether `file` starts with a digest table (files of the checkpoint
// formats before 4 do not).
bool sealed(const std::filesystem::path &file);

// What is damaged ("the array '/sets/0/x' does not match its digest"), or
// nullopt when every digest matches. For a sealed file only.
std::optional<std::string> damage(const std::filesystem::path &file);

} // namespace talus::checkpoint_digests
