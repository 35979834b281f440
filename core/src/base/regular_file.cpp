#include <talus/regular_file.hpp>

#include <talus/error.hpp>

#include <cerrno>
#include <cstring>
#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

namespace talus {

namespace {

std::string kind_of(mode_t m) {
    if (S_ISREG(m)) return {};
    if (S_ISDIR(m)) return "a directory";
    if (S_ISFIFO(m)) return "a FIFO";
    if (S_ISCHR(m)) return "a character device";
    if (S_ISBLK(m)) return "a block device";
    if (S_ISSOCK(m)) return "a socket";
    return "not a regular file";
}

std::string refusal(const std::string &kind) {
    return kind + ", not a file: Talus reads regular files only";
}

} // namespace

std::string not_a_regular_file(const std::filesystem::path &p) {
    struct stat st {};
    if (::stat(p.c_str(), &st) != 0) return {};
    const std::string kind = kind_of(st.st_mode);
    return kind.empty() ? kind : refusal(kind);
}

std::string read_regular_file(const std::filesystem::path &p) {
    // O_NONBLOCK: the open of a FIFO without a writer returns at once.
    const int fd = ::open(p.c_str(), O_RDONLY | O_NONBLOCK | O_CLOEXEC);
    if (fd < 0) throw Error(p.string() + ": cannot open file: " + std::strerror(errno));
    struct stat st {};
    std::string kind = ::fstat(fd, &st) != 0 ? "not a readable file" : kind_of(st.st_mode);
    if (!kind.empty()) {
        ::close(fd);
        throw Error(p.string() + ": " + refusal(kind));
    }
    ::fcntl(fd, F_SETFL, ::fcntl(fd, F_GETFL) & ~O_NONBLOCK);
    std::string text;
    text.reserve(static_cast<std::size_t>(st.st_size));
    char buf[1 << 16];
    for (;;) {
        const ssize_t n = ::read(fd, buf, sizeof buf);
        if (n > 0) {
            text.append(buf, static_cast<std::size_t>(n));
        } else if (n == 0) {
            break;
        } else if (errno != EINTR) {
            const int err = errno;
            ::close(fd);
            throw Error(p.string() + ": cannot read file: " + std::strerror(err));
        }
    }
    ::close(fd);
    return text;
}

} // namespace talus
