// Files Talus reads are regular files. A FIFO named as a scenario or a
// plugin blocks the reader for ever, a device (/dev/zero) is read until
// memory runs out, a directory reads as nothing: each is refused by name
// instead (docs/security.md).
#pragma once

#include <filesystem>
#include <string>

namespace talus {

// What `p` is when it exists and is not a regular file, symbolic links
// followed ("a directory", "a FIFO", "a character device", ...); empty for
// a regular file or one that does not exist (whose open says so). Never
// opens it.
std::string not_a_regular_file(const std::filesystem::path &p);

// The whole content of the regular file `p`, opened without blocking on a
// FIFO and checked on the open descriptor. Throws talus::Error
// "<p>: <why>" ("cannot open file: No such file or directory", "a FIFO, not
// a file: ...").
std::string read_regular_file(const std::filesystem::path &p);

} // namespace talus
