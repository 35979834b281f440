// A run's output folder: which files in it are a run's, whose run they are
// of, and who is writing into it now (docs/scenario-reference.md, "output";
// docs/restart.md). A folder holds one run: a second run into it is refused while
// the first one writes, and a restart continues only in its own run's
// folder, so that no folder ever mixes the files of two runs.
#pragma once

#include <talus/io/checkpoint.hpp>

#include <filesystem>
#include <string>

namespace talus {

// A file or folder that a run writes into its folder (the CSV files, the
// VTK files and the folders of their pieces, provenance.json), so that
// --force removes these and nothing else.
bool is_own_file(const std::filesystem::path &p);

// A new run's name: 32 hex digits from the system's random source.
std::string new_run_id();

// Throws talus::Error unless the folder `dir` is the checkpoint's run's or
// holds no run's files: its provenance.json must name the checkpoint's run
// id, or, where either side comes from a Talus that wrote none, the same
// scenario and plugin digests.
void refuse_foreign_folder(const std::filesystem::path &dir, const Checkpoint &checkpoint);

// The lock a run holds on its folder while it writes into it: an exclusive
// flock(2) on `.talus.lock` in the folder, which the kernel lets go when
// the process ends, however it ends; the file names the holder (PID, host,
// start) for the run that is refused. A new run makes the folder and
// removes it again, empty, if it leaves nothing in it; a restart finds it.
class FolderLock {
  public:
    enum class For { new_run, restart };
    // Throws talus::Error naming the holder when another process holds it.
    FolderLock(const std::filesystem::path &dir, For purpose);
    ~FolderLock();
    FolderLock(const FolderLock &) = delete;
    FolderLock &operator=(const FolderLock &) = delete;

    static constexpr const char *kFileName = ".talus.lock";
    // Where the file system cannot lock files: what the run should say
    // (it goes on without the lock); else empty.
    const std::string &warning() const { return warning_; }

  private:
    std::filesystem::path dir_, file_;
    std::string warning_;
    int fd_ = -1;
    bool made_ = false;
};

} // namespace talus
