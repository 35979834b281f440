// particles.pvd, the collection of a run's VTK files, grown an entry at a
// time. Written whole, a collection costs the length of all its entries at
// every output: a run of 15,000 outputs slowed 4.6-fold and wrote about a
// gigabyte for a 1 MB file. Here it is written whole once (atomically, by
// rename, as a restart also does) and then each output is one positioned
// write at its end, the new entry and the closing tags over the old
// closing tags.
#pragma once

#include <filesystem>
#include <string>
#include <utility>
#include <vector>

namespace talus {

class PvdFile {
  public:
    PvdFile() = default;
    ~PvdFile();
    PvdFile(const PvdFile &) = delete;
    PvdFile &operator=(const PvdFile &) = delete;

    // Writes `entries` (time, file name relative to the .pvd) as the whole
    // collection, under its name only once complete, and keeps it open
    // for append(). Throws talus::Error naming the file.
    void start(const std::filesystem::path &file,
               const std::vector<std::pair<double, std::string>> &entries);
    // One entry more. On a failed write the file is put back as it was
    // (the old closing tags), then talus::Error is thrown.
    void append(double time, const std::string &name);
    bool is_open() const { return fd_ >= 0; }

  private:
    std::filesystem::path file_;
    int fd_ = -1;
    long long tail_at_ = 0; // where the closing tags begin
};

} // namespace talus
