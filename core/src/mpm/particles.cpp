#include <talus/mpm/particles.hpp>

#include <algorithm>
#include <cstring>
#include <new>
#include <stdexcept>
#include <type_traits>
#include <vector>

namespace talus {

namespace {
constexpr std::size_t kAlign = 64; // a cache line: no column shares one with another
std::size_t round_up(std::size_t bytes) { return (bytes + kAlign - 1) / kAlign * kAlign; }
} // namespace

void ParticleSet::Free::operator()(std::byte *p) const {
    ::operator delete[](p, std::align_val_t(kAlign));
}

std::size_t ParticleSet::bytes_per_particle() {
    std::size_t bytes = 0;
    for_each_column([&](auto &col, std::size_t stride) {
        bytes += stride * sizeof(typename std::decay_t<decltype(col)>::value_type);
    });
    return bytes;
}

void ParticleSet::resize(std::size_t count) {
    if (count > capacity_) {
        // Grow by half again (generation adds particles one at a time), and
        // carve every column from one new arena.
        const std::size_t cap = std::max({count, capacity_ + capacity_ / 2, std::size_t{64}});
        std::size_t total = 0;
        for_each_column([&](auto &col, std::size_t stride) {
            total += round_up(cap * stride * sizeof(*col.data_));
        });
        std::unique_ptr<std::byte[], Free> fresh(
            static_cast<std::byte *>(::operator new[](total, std::align_val_t(kAlign))));
        std::size_t offset = 0;
        for_each_column([&](auto &col, std::size_t stride) {
            using T = typename std::decay_t<decltype(col)>::value_type;
            T *dst = reinterpret_cast<T *>(fresh.get() + offset);
            if (col.data_) std::memcpy(dst, col.data_, n * stride * sizeof(T));
            col.data_ = dst;
            offset += round_up(cap * stride * sizeof(T));
        });
        arena_ = std::move(fresh);
        capacity_ = cap;
    }
    for_each_column([&](auto &col, std::size_t stride) {
        using T = typename std::decay_t<decltype(col)>::value_type;
        if (count > n) std::memset(col.data_ + n * stride, 0, (count - n) * stride * sizeof(T));
        col.size_ = count * stride;
    });
    n = count;
}

namespace {

// Applies the permutation (particle p takes the values particle from[p] had)
// to one column in place by following its cycles: each value moves once,
// with room for one particle's values aside. A buffer the size of the
// column (72 bytes per particle for F) would be resident for the whole run
// once the first sort had touched it.
template <class T>
void permute_in_place(T *a, std::size_t stride, const std::vector<std::uint32_t> &from,
                      std::vector<bool> &done, std::vector<T> &aside) {
    const std::size_t n = from.size();
    done.assign(n, false);
    aside.resize(stride);
    for (std::size_t start = 0; start < n; ++start) {
        if (done[start] || from[start] == start) continue;
        std::copy_n(a + start * stride, stride, aside.data());
        std::size_t j = start;
        for (;;) {
            done[j] = true;
            const std::size_t k = from[j];
            if (k == start) {
                std::copy_n(aside.data(), stride, a + j * stride);
                break;
            }
            std::copy_n(a + k * stride, stride, a + j * stride);
            j = k;
        }
    }
}

} // namespace

void ParticleSet::permute(const std::vector<std::uint32_t> &from) {
    std::vector<bool> done;
    for_each_column([&](auto &a, std::size_t stride) {
        using T = typename std::decay_t<decltype(a)>::value_type;
        std::vector<T> aside;
        permute_in_place(a.data(), stride, from, done, aside);
    });
}

void ParticleSet::move(std::size_t from, std::size_t to) {
    if (from == to) return;
    for_each_column([&](auto &col, std::size_t stride) {
        std::copy_n(col.data_ + from * stride, stride, col.data_ + to * stride);
    });
}

void ParticleSet::copy_point(ParticleSet &other, std::size_t p, std::size_t q) {
    // Both sets walk the same columns in the same order, but for the state
    // (whose size depends on the material), skipped in both.
    struct Source {
        const std::byte *at;
        std::size_t bytes;
    };
    std::array<Source, 48> src{};
    std::size_t k = 0;
    other.for_each_column([&](auto &col, std::size_t stride) {
        if (static_cast<const void *>(&col) == static_cast<const void *>(&other.state)) return;
        src.at(k++) = {reinterpret_cast<const std::byte *>(col.data() + p * stride),
                       stride * sizeof(*col.data())};
    });
    std::size_t j = 0;
    for_each_column([&](auto &col, std::size_t stride) {
        if (static_cast<const void *>(&col) == static_cast<const void *>(&state)) return;
        const Source s = src.at(j++);
        if (s.bytes != stride * sizeof(*col.data()))
            throw std::logic_error("copy_point: the two sets use different columns");
        std::memcpy(col.data() + q * stride, s.at, s.bytes);
    });
    if (j != k) throw std::logic_error("copy_point: the two sets use different columns");
}

} // namespace talus
