#include <talus/io/output_file.hpp>

#include <talus/error.hpp>

#include <fmt/format.h>

#include <cerrno>
#include <cstring>
#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

namespace talus {

namespace fs = std::filesystem;

namespace {
// Rows are small; the OS sees them in blocks of about this size, and at
// every flush().
constexpr std::size_t kBlock = 1 << 16;
} // namespace

OutputFile::OutputFile(const fs::path &file, fs::path shown)
    : path_(file), shown_(shown.empty() ? file : std::move(shown)) {
    fd_ = ::open(file.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0644);
    if (fd_ < 0) fail("cannot create the file", errno);
}

OutputFile OutputFile::resume(const fs::path &file, std::uint64_t size) {
    OutputFile f;
    f.path_ = f.shown_ = file;
    f.fd_ = ::open(file.c_str(), O_WRONLY | O_CLOEXEC);
    if (f.fd_ < 0) f.fail("cannot reopen the file to continue it", errno);
    struct stat st {};
    if (::fstat(f.fd_, &st) != 0) f.fail("cannot read the file's size", errno);
    if (static_cast<std::uint64_t>(st.st_size) < size)
        throw Error(fmt::format("{}: holds {} bytes, fewer than the {} the checkpoint recorded: "
                                "this is not the output the checkpoint belongs to",
                                file.string(), st.st_size, size));
    if (::ftruncate(f.fd_, static_cast<off_t>(size)) != 0 ||
        ::lseek(f.fd_, static_cast<off_t>(size), SEEK_SET) < 0)
        f.fail("cannot cut the file back to the checkpoint", errno);
    f.written_ = size;
    return f;
}

OutputFile::~OutputFile() {
    if (fd_ >= 0) ::close(fd_); // an abandoned file: its error was reported already
}

OutputFile::OutputFile(OutputFile &&o) noexcept
    : path_(std::move(o.path_)), shown_(std::move(o.shown_)), fd_(o.fd_),
      buffer_(std::move(o.buffer_)), written_(o.written_) {
    o.fd_ = -1;
}

OutputFile &OutputFile::operator=(OutputFile &&o) noexcept {
    if (this != &o) {
        if (fd_ >= 0) ::close(fd_);
        path_ = std::move(o.path_);
        shown_ = std::move(o.shown_);
        fd_ = o.fd_;
        buffer_ = std::move(o.buffer_);
        written_ = o.written_;
        o.fd_ = -1;
    }
    return *this;
}

void OutputFile::fail(const char *what, int err) {
    if (fd_ >= 0) ::close(fd_);
    fd_ = -1;
    buffer_.clear();
    throw Error(fmt::format("{}: {}: {}", shown_.string(), what, std::strerror(err)));
}

void OutputFile::write(std::string_view bytes) {
    if (fd_ < 0) throw Error(fmt::format("{}: write to a closed file", shown_.string()));
    if (bytes.size() >= kBlock) { // large arrays go straight through
        flush();
        write_all(bytes.data(), bytes.size());
        return;
    }
    buffer_.append(bytes);
    if (buffer_.size() >= kBlock) flush();
}

void OutputFile::flush() {
    if (fd_ < 0) return;
    write_all(buffer_.data(), buffer_.size());
    buffer_.clear();
}

void OutputFile::write_all(const char *p, std::size_t left) {
    while (left > 0) {
        const ssize_t n = ::write(fd_, p, left);
        if (n < 0) {
            if (errno == EINTR) continue;
            fail("write failed", errno);
        }
        p += n;
        left -= static_cast<std::size_t>(n);
        written_ += static_cast<std::uint64_t>(n);
    }
}

void OutputFile::close() {
    if (fd_ < 0) return;
    flush();
    const int fd = fd_;
    fd_ = -1;
    if (::close(fd) != 0) fail("write failed (on close)", errno);
}

AtomicFile::AtomicFile(const fs::path &file)
    : target_(file),
      tmp_(file.parent_path() / fmt::format(".{}.tmp.{}", file.filename().string(), ::getpid())) {
    out_ = OutputFile(tmp_, target_);
}

AtomicFile::~AtomicFile() {
    if (!committed_) {
        out_ = OutputFile();
        ::unlink(tmp_.c_str());
    }
}

void AtomicFile::commit() {
    out_.close();
    if (::rename(tmp_.c_str(), target_.c_str()) != 0)
        throw Error(fmt::format("{}: cannot move the finished file into place: {}",
                                target_.string(), std::strerror(errno)));
    committed_ = true;
}

void write_file_atomically(const fs::path &path, std::string_view content) {
    AtomicFile f(path);
    f.write(content);
    f.commit();
}

} // namespace talus
