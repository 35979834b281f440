#include <talus/mpm/particles.hpp>

#include "parallel/parallel.hpp"

#include <algorithm>
#include <cstdint>
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

// The cycles of a permutation (particle p takes the values particle from[p]
// had), found once for all the columns: each cycle's particles j0 j1 ... jk
// in turn, where from[j_i] = j_(i+1) and from[jk] = j0, the last with
// kCycleEnd set; particles that keep their place are left out. After a
// re-sort most do (the order decays slowly), so the list is short.
constexpr std::uint32_t kCycleEnd = 0x80000000u;
std::vector<std::uint32_t> cycles_of(const std::vector<std::uint32_t> &from) {
    const std::size_t n = from.size();
    if (n >= kCycleEnd) throw std::length_error("permute: more than 2^31 particles in a set");
    std::vector<std::uint32_t> cycles;
    std::vector<bool> done(n, false);
    for (std::size_t start = 0; start < n; ++start) {
        if (done[start] || from[start] == start) continue;
        std::size_t j = start;
        for (;;) {
            done[j] = true;
            const std::size_t k = from[j];
            if (k >= n) throw std::out_of_range("permute: an index past the set's end");
            if (k == start) {
                cycles.push_back(static_cast<std::uint32_t>(j) | kCycleEnd);
                break;
            }
            cycles.push_back(static_cast<std::uint32_t>(j));
            j = k;
        }
    }
    return cycles;
}

// Applies the cycles to one column of `bytes` bytes a particle (B: the
// same, known when compiled, so that each move is a few register moves
// and not a call of memcpy): each value moves once, with room for one
// particle's values aside. A buffer the size of the column (72 bytes per
// particle for F) would be resident for the whole run once the first sort
// had touched it.
template <std::size_t B>
void apply_cycles(std::byte *a, std::size_t bytes, const std::vector<std::uint32_t> &cycles,
                  std::byte *aside) {
    const std::size_t size = B ? B : bytes;
    auto at = [&](std::uint32_t j) { return a + static_cast<std::size_t>(j) * size; };
    for (std::size_t i = 0; i < cycles.size();) {
        std::uint32_t j = cycles[i];
        std::memcpy(aside, at(j), size);
        for (;;) {
            const std::uint32_t e = cycles[++i];
            const std::uint32_t k = e & ~kCycleEnd;
            std::memcpy(at(j), at(k), size);
            j = k;
            if (e & kCycleEnd) break;
        }
        std::memcpy(at(j), aside, size);
        ++i;
    }
}

} // namespace

// The columns are independent: each is permuted by one thread, the largest
// first, with the cycles found once. (Following the cycles per column, each
// column tested and set a bit per particle and moved its values by calls of
// memmove, all on one thread:
// bench/results/2026-11-26-xeon-2.1ghz-against-4eb0ad2-small-parts.md.)
void ParticleSet::permute(const std::vector<std::uint32_t> &from) {
    if (from.size() != n) throw std::logic_error("permute: the permutation is not the set's size");
    const std::vector<std::uint32_t> cycles = cycles_of(from);
    if (cycles.empty()) return;
    struct Raw {
        std::byte *data;
        std::size_t bytes; // per particle
        std::size_t aside; // offset of its room aside
    };
    std::vector<Raw> columns;
    std::size_t room = 0;
    for_each_column([&](auto &col, std::size_t stride) {
        const std::size_t bytes = stride * sizeof(*col.data());
        columns.push_back({reinterpret_cast<std::byte *>(col.data()), bytes, room});
        room += bytes;
    });
    std::vector<std::byte> aside(room);
    std::stable_sort(columns.begin(), columns.end(),
                     [](const Raw &a, const Raw &b) { return a.bytes > b.bytes; });
    par::for_each_task(columns.size(), [&](std::size_t t) {
        const Raw r = columns[t];
        std::byte *room_aside = aside.data() + r.aside;
        switch (r.bytes) {
        case 4: apply_cycles<4>(r.data, r.bytes, cycles, room_aside); break;
        case 8: apply_cycles<8>(r.data, r.bytes, cycles, room_aside); break;
        case 48: apply_cycles<48>(r.data, r.bytes, cycles, room_aside); break;
        case 72: apply_cycles<72>(r.data, r.bytes, cycles, room_aside); break;
        default: apply_cycles<0>(r.data, r.bytes, cycles, room_aside); break;
        }
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
