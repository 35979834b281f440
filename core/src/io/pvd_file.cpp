#include <talus/io/pvd_file.hpp>

#include <talus/error.hpp>
#include <talus/io/output_file.hpp>

#include "xml_text.hpp"

#include <fmt/format.h>

#include <cerrno>
#include <cstring>
#include <fcntl.h>
#include <unistd.h>

namespace talus {

namespace fs = std::filesystem;

namespace {

constexpr std::string_view kHead = "<?xml version=\"1.0\"?>\n<VTKFile type=\"Collection\" "
                                   "version=\"1.0\" byte_order=\"LittleEndian\">\n"
                                   "  <Collection>\n";
constexpr std::string_view kTail = "  </Collection>\n</VTKFile>\n";

std::string entry(double t, const std::string &name) {
    return fmt::format("    <DataSet timestep=\"{:.17g}\" part=\"0\" file=\"{}\"/>\n", t,
                       xml_escape(name));
}

} // namespace

PvdFile::~PvdFile() {
    if (fd_ >= 0) ::close(fd_);
}

void PvdFile::start(const fs::path &file,
                    const std::vector<std::pair<double, std::string>> &entries) {
    if (fd_ >= 0) ::close(fd_);
    fd_ = -1;
    file_ = file;
    std::string c(kHead);
    for (const auto &[t, f] : entries)
        c += entry(t, f);
    tail_at_ = static_cast<long long>(c.size());
    c += kTail;
    write_file_atomically(file, c);
    fd_ = ::open(file.c_str(), O_WRONLY | O_CLOEXEC);
    if (fd_ < 0)
        throw Error(fmt::format("{}: cannot reopen the collection to add to it: {}", file.string(),
                                std::strerror(errno)));
}

void PvdFile::append(double time, const std::string &name) {
    if (fd_ < 0) throw Error(fmt::format("{}: the collection is not open", file_.string()));
    // One write of a few hundred bytes, less than a page: a process killed
    // at any moment leaves the old file or the new one (the kernel copies
    // such a write whole), and a restart writes the collection afresh.
    const std::string add = entry(time, name) + std::string(kTail);
    std::size_t done = 0;
    while (done < add.size()) {
        const ssize_t n = ::pwrite(fd_, add.data() + done, add.size() - done,
                                   static_cast<off_t>(tail_at_) + static_cast<off_t>(done));
        if (n > 0) {
            done += static_cast<std::size_t>(n);
            continue;
        }
        if (n < 0 && errno == EINTR) continue;
        const int err = n < 0 ? errno : ENOSPC;
        // Put the closing tags back where they were and drop the rest: the
        // file stays the valid collection of the outputs before this one
        // (shrinking a file needs no space).
        const bool restored =
            ::pwrite(fd_, kTail.data(), kTail.size(), static_cast<off_t>(tail_at_)) ==
                static_cast<ssize_t>(kTail.size()) &&
            ::ftruncate(fd_, static_cast<off_t>(tail_at_ + static_cast<long long>(kTail.size()))) ==
                0;
        throw Error(
            fmt::format("{}: write failed: {}{}", file_.string(), std::strerror(err),
                        restored ? " (the collection is as it was before this output)" : ""));
    }
    tail_at_ += static_cast<long long>(add.size() - kTail.size());
}

} // namespace talus
