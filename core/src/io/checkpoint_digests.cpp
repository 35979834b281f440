#include "checkpoint_digests.hpp"

#include <talus/error.hpp>

#include <fmt/format.h>

#include <algorithm>
#include <cerrno>
#include <charconv>
#include <cstring>
#include <fcntl.h>
#include <sstream>
#include <sys/stat.h>
#include <unistd.h>

namespace talus::checkpoint_digests {

namespace fs = std::filesystem;

namespace {

constexpr const char *kMagic = "talus checkpoint digests 1 ";

// A 64-bit digest over 8-byte words. Each step (xor the word, multiply by
// an odd constant, xor-shift) is a bijection of the state, so damage
// confined to one word (a flipped bit, a changed byte) always changes the
// digest, and other damage goes unseen with a chance of about 2^-64. It
// guards against damage, not against a deliberate forgery.
class Digest {
  public:
    void word(std::uint64_t w) {
        h_ ^= w;
        h_ *= 0x9fb21c651e98df25ull;
        h_ ^= h_ >> 29;
    }
    void bytes(const void *data, std::size_t n) {
        const auto *p = static_cast<const unsigned char *>(data);
        std::size_t k = 0;
        for (; k + 8 <= n; k += 8) {
            std::uint64_t w;
            std::memcpy(&w, p + k, 8);
            word(w);
        }
        if (k < n) {
            std::uint64_t w = 0;
            std::memcpy(&w, p + k, n - k);
            word(w);
        }
        word(n);
    }
    std::uint64_t value() const { return h_; }

  private:
    std::uint64_t h_ = 0x6a09e667f3bcc908ull;
};

// A file descriptor, closed on every path.
class File {
  public:
    File(const fs::path &path, int flags) : fd_(::open(path.c_str(), flags | O_CLOEXEC)) {
        if (fd_ < 0) throw Error(fmt::format("cannot open: {}", std::strerror(errno)));
    }
    ~File() { ::close(fd_); }
    File(const File &) = delete;
    File &operator=(const File &) = delete;
    std::uint64_t size() const {
        struct stat st {};
        if (::fstat(fd_, &st) != 0)
            throw Error(fmt::format("cannot stat: {}", std::strerror(errno)));
        return static_cast<std::uint64_t>(st.st_size);
    }
    // Exactly n bytes at `at`, or an error (a short file is damaged).
    void read(void *to, std::size_t n, std::uint64_t at) const {
        auto *p = static_cast<char *>(to);
        while (n > 0) {
            const ssize_t r = ::pread(fd_, p, n, static_cast<off_t>(at));
            if (r < 0 && errno == EINTR) continue;
            if (r < 0) throw Error(fmt::format("cannot read: {}", std::strerror(errno)));
            if (r == 0) throw Error("the file ends early");
            p += r, n -= static_cast<std::size_t>(r), at += static_cast<std::uint64_t>(r);
        }
    }
    void write(const void *from, std::size_t n, std::uint64_t at) const {
        const auto *p = static_cast<const char *>(from);
        while (n > 0) {
            const ssize_t r = ::pwrite(fd_, p, n, static_cast<off_t>(at));
            if (r < 0 && errno == EINTR) continue;
            if (r <= 0) throw Error(fmt::format("cannot write: {}", std::strerror(errno)));
            p += r, n -= static_cast<std::size_t>(r), at += static_cast<std::uint64_t>(r);
        }
    }

  private:
    int fd_;
};

// The digest of bytes [from, to) of the file, read in pieces of 1 MB.
std::uint64_t digest_of(const File &f, std::uint64_t from, std::uint64_t to, Digest d = {}) {
    std::vector<char> buffer(std::size_t{1} << 20);
    for (std::uint64_t at = from; at < to;) {
        const std::size_t n =
            static_cast<std::size_t>(std::min<std::uint64_t>(buffer.size(), to - at));
        f.read(buffer.data(), n, at);
        d.bytes(buffer.data(), n);
        at += n;
    }
    return d.value();
}

// The digest of everything past the user block but the arrays' values
// (sorted, not overlapping).
std::uint64_t rest_of(const File &f, std::uint64_t userblock, std::uint64_t size,
                      const std::vector<Range> &arrays) {
    Digest d;
    std::uint64_t at = userblock;
    for (const Range &r : arrays) {
        d.word(digest_of(f, at, r.offset));
        at = r.offset + r.bytes;
    }
    d.word(digest_of(f, at, size));
    return d.value();
}

std::uint64_t text_digest(const std::string &text) {
    Digest d;
    d.bytes(text.data(), text.size());
    return d.value();
}

struct Visit {
    std::vector<std::string> datasets;
};

#if H5_VERSION_GE(1, 12, 0)
using ObjectInfo = H5O_info2_t;
#define TALUS_H5_VISIT H5Ovisit3
#else
using ObjectInfo = H5O_info_t;
#define TALUS_H5_VISIT H5Ovisit2
#endif

herr_t visit(hid_t, const char *name, const ObjectInfo *info, void *data) {
    if (info->type == H5O_TYPE_DATASET) static_cast<Visit *>(data)->datasets.push_back(name);
    return 0;
}

bool parse(std::string_view s, std::uint64_t &v, int base = 10) {
    const auto r = std::from_chars(s.data(), s.data() + s.size(), v, base);
    return r.ec == std::errc() && r.ptr == s.data() + s.size() && !s.empty();
}

} // namespace

std::size_t userblock_size(std::size_t arrays, std::size_t name_bytes) {
    const std::size_t need = 256 + arrays * 72 + name_bytes;
    std::size_t size = 512;
    while (size < need)
        size *= 2;
    return size;
}

std::vector<Range> arrays(hid_t file) {
    Visit v;
    if (TALUS_H5_VISIT(file, H5_INDEX_NAME, H5_ITER_INC, visit, &v, H5O_INFO_BASIC) < 0)
        throw Error("cannot list the file's arrays");
    std::vector<Range> out;
    for (const std::string &name : v.datasets) {
        const hid_t d = H5Dopen2(file, name.c_str(), H5P_DEFAULT);
        if (d < 0) throw Error("cannot open the array " + name);
        const haddr_t offset = H5Dget_offset(d);
        const hsize_t bytes = H5Dget_storage_size(d);
        H5Dclose(d);
        if (offset == HADDR_UNDEF || bytes == 0) continue; // no values stored
        out.push_back({"/" + name, offset, bytes});
    }
    std::sort(out.begin(), out.end(),
              [](const Range &a, const Range &b) { return a.offset < b.offset; });
    return out;
}

void seal(const fs::path &file, std::size_t userblock, const std::vector<Range> &arrays) {
    const File f(file, O_RDWR);
    const std::uint64_t size = f.size();
    std::ostringstream t;
    t << kMagic << userblock << '\n' << "file " << size << '\n';
    t << fmt::format("rest {:016x}\n", rest_of(f, userblock, size, arrays));
    for (const Range &r : arrays)
        t << fmt::format("array {} {} {:016x} {}\n", r.offset, r.bytes,
                         digest_of(f, r.offset, r.offset + r.bytes), r.name);
    std::string text = t.str();
    text += fmt::format("self {:016x}\n", text_digest(text));
    if (text.size() > userblock)
        throw Error(fmt::format("the digests ({} bytes) do not fit the user block ({})",
                                text.size(), userblock));
    text.resize(userblock, '\0');
    f.write(text.data(), text.size(), 0);
}

bool sealed(const fs::path &file) {
    try {
        const File f(file, O_RDONLY);
        const std::size_t n = std::strlen(kMagic);
        if (f.size() < n) return false;
        std::string head(n, '\0');
        f.read(head.data(), n, 0);
        return head == kMagic;
    } catch (const Error &) {
        return false;
    }
}

std::optional<std::string> damage(const fs::path &file) {
    const std::string table_damaged = "the checkpoint's digest table is damaged";
    try {
        const File f(file, O_RDONLY);
        const std::uint64_t size = f.size();
        std::string head(std::min<std::uint64_t>(size, 64), '\0');
        f.read(head.data(), head.size(), 0);
        const std::size_t m = std::strlen(kMagic), eol = head.find('\n');
        std::uint64_t userblock = 0;
        if (head.compare(0, m, kMagic) != 0 || eol == std::string::npos ||
            !parse(std::string_view(head).substr(m, eol - m), userblock) || userblock < 512 ||
            userblock > (std::uint64_t{1} << 24) || (userblock & (userblock - 1)) != 0 ||
            userblock > size)
            return table_damaged;
        std::string text(userblock, '\0');
        f.read(text.data(), text.size(), 0);
        text.resize(std::strlen(text.c_str()));
        // The table's own digest first: no number of it is used before.
        const std::size_t self = text.rfind("self ");
        std::uint64_t stored = 0;
        if (self == std::string::npos || text.size() < self + 6 ||
            !parse(std::string_view(text).substr(self + 5, text.size() - self - 6), stored, 16) ||
            text.back() != '\n' || text_digest(text.substr(0, self)) != stored)
            return table_damaged;
        std::istringstream in(text.substr(0, self));
        std::string line;
        std::getline(in, line); // the magic
        std::uint64_t written_size = 0, rest = 0;
        std::vector<Range> arrays;
        std::vector<std::uint64_t> sums;
        while (std::getline(in, line)) {
            std::istringstream w(line);
            std::string key, a, b, c, name;
            w >> key;
            std::uint64_t x = 0;
            if (key == "file" && (w >> a) && parse(a, x)) {
                written_size = x;
            } else if (key == "rest" && (w >> a) && parse(a, x, 16)) {
                rest = x;
            } else if (key == "array" && (w >> a >> b >> c >> name)) {
                Range r{name, 0, 0};
                std::uint64_t sum = 0;
                if (!parse(a, r.offset) || !parse(b, r.bytes) || !parse(c, sum, 16))
                    return table_damaged;
                arrays.push_back(r);
                sums.push_back(sum);
            } else {
                return table_damaged;
            }
        }
        if (written_size != size)
            return fmt::format("the checkpoint is {} bytes long, {} were written (cut short "
                               "or appended to)",
                               size, written_size);
        std::uint64_t end = userblock;
        for (const Range &r : arrays) {
            if (r.offset < end || r.bytes > size - r.offset) return table_damaged;
            end = r.offset + r.bytes;
        }
        for (std::size_t k = 0; k < arrays.size(); ++k) {
            const Range &r = arrays[k];
            if (digest_of(f, r.offset, r.offset + r.bytes) != sums[k])
                return fmt::format("the array '{}' does not match its digest", r.name);
        }
        if (rest_of(f, userblock, size, arrays) != rest)
            return "its attributes or HDF5's structures do not match their digest";
        return std::nullopt;
    } catch (const Error &e) {
        return std::string(e.what());
    }
}

} // namespace talus::checkpoint_digests
