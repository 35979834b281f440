// Files the core writes, with every write checked. A failed write (full
// disk, quota, permissions, a file-size limit) throws talus::Error naming
// the file and the operating system's reason; nothing is left half written
// under the final name.
#pragma once

#include <cstdint>
#include <filesystem>
#include <string>
#include <string_view>

namespace talus {

// A file written front to back and appended to as a run goes (diagnostics,
// probes). flush() pushes each finished row to the OS, so a run that stops
// early leaves complete rows only.
class OutputFile {
  public:
    OutputFile() = default;
    // Creates or truncates `file`; messages name `shown` when given (the
    // final name of a temporary).
    explicit OutputFile(const std::filesystem::path &file, std::filesystem::path shown = {});
    // Reopens a file a run had written for appending, cut back to its first
    // `size` bytes (a restart drops what came after its checkpoint). Throws
    // if the file is missing or shorter.
    static OutputFile resume(const std::filesystem::path &file, std::uint64_t size);
    ~OutputFile();
    OutputFile(OutputFile &&other) noexcept;
    OutputFile &operator=(OutputFile &&other) noexcept;
    OutputFile(const OutputFile &) = delete;
    OutputFile &operator=(const OutputFile &) = delete;

    bool is_open() const { return fd_ >= 0; }
    const std::filesystem::path &path() const { return path_; }
    void write(std::string_view bytes);
    OutputFile &operator<<(std::string_view bytes) {
        write(bytes);
        return *this;
    }
    // Hands the buffered bytes to the OS (a complete row becomes visible).
    void flush();
    // Bytes written so far (handed to the OS or still buffered).
    std::uint64_t bytes() const { return written_ + buffer_.size(); }
    // Flushes and closes; a failure to close is a failed write (NFS, quota).
    void close();

  private:
    [[noreturn]] void fail(const char *what, int err);
    void write_all(const char *p, std::size_t n);
    std::filesystem::path path_, shown_;
    int fd_ = -1;
    std::string buffer_;
    std::uint64_t written_ = 0;
};

// A file that appears under its name only once it is complete: written to a
// hidden temporary beside it and renamed over it by commit(). Destroyed
// without commit() (an exception on the way), the temporary is removed.
class AtomicFile {
  public:
    explicit AtomicFile(const std::filesystem::path &file);
    ~AtomicFile();
    AtomicFile(const AtomicFile &) = delete;
    AtomicFile &operator=(const AtomicFile &) = delete;
    void write(std::string_view bytes) { out_.write(bytes); }
    void commit();

  private:
    std::filesystem::path target_, tmp_;
    OutputFile out_;
    bool committed_ = false;
};

// Writes `content` to `path` through an AtomicFile.
void write_file_atomically(const std::filesystem::path &path, std::string_view content);

} // namespace talus
