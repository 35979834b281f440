#include "ranks/migration.hpp"

#include <talus/error.hpp>

#include <fmt/format.h>

#include <algorithm>
#include <cstring>

namespace talus {

namespace {

constexpr int kTag = 7200;

template <class T>
void append(std::vector<std::byte> &out, const T *v, std::size_t count) {
    const std::size_t at = out.size();
    out.resize(at + count * sizeof(T));
    if (count > 0) std::memcpy(out.data() + at, v, count * sizeof(T));
}

// A set's particles [p in `which`] as bytes: their count, then column by
// column (ParticleSet::for_each_column's order), particle by particle.
void pack(ParticleSet &s, const std::vector<std::uint32_t> &which, std::vector<std::byte> &out) {
    const std::uint64_t count = which.size();
    append(out, &count, 1);
    s.for_each_column([&](auto &col, std::size_t stride) {
        for (std::uint32_t p : which)
            append(out, col.data() + p * stride, stride);
    });
}

// Appends the particles of one packed set; returns the bytes read.
std::size_t unpack(ParticleSet &s, const std::byte *in, std::size_t size) {
    std::uint64_t count = 0;
    if (size < sizeof count) throw Error("internal error: a migration message too short");
    std::memcpy(&count, in, sizeof count);
    std::size_t at = sizeof count;
    const std::size_t first = s.n;
    s.resize(first + count);
    s.for_each_column([&](auto &col, std::size_t stride) {
        using T = typename std::decay_t<decltype(col)>::value_type;
        const std::size_t bytes = count * stride * sizeof(T);
        if (at + bytes > size) throw Error("internal error: a migration message too short");
        if (bytes > 0) std::memcpy(col.data() + first * stride, in + at, bytes);
        at += bytes;
    });
    return at;
}

} // namespace

Migration migrate(const Comm &comm, const Decomposition &decomp, const std::vector<int> &peers,
                  const GridGeometry &geo, std::vector<ParticleSet> &sets) {
    Migration m;
    if (!comm.distributed()) return m;
    const int me = comm.rank();
    const std::size_t ranks = static_cast<std::size_t>(comm.size());
    // Destinations, per set and rank.
    std::vector<std::vector<std::vector<std::uint32_t>>> to(
        sets.size(), std::vector<std::vector<std::uint32_t>>(ranks));
    bool far = false;
    const CellBox &mine = decomp.box(me);
    for (std::size_t si = 0; si < sets.size(); ++si) {
        const ParticleSet &s = sets[si];
        for (std::size_t p = 0; p < s.n; ++p) {
            const std::array<int, 3> c = particle_cell(geo, s, p);
            if (mine.contains(c)) [[likely]]
                continue;
            const int r = decomp.owner(c);
            if (r == me) continue;
            to[si][static_cast<std::size_t>(r)].push_back(static_cast<std::uint32_t>(p));
            far = far || !std::binary_search(peers.begin(), peers.end(), r);
        }
    }
    far = comm.max(far ? 1.0 : 0.0) > 0.0;
    // One message per destination: every set's particles for it.
    std::vector<int> all;
    if (far)
        for (int r = 0; r < comm.size(); ++r)
            all.push_back(r);
    const std::vector<int> &targets = far ? all : peers;
    std::vector<std::vector<std::byte>> out(targets.size());
    for (std::size_t k = 0; k < targets.size(); ++k) {
        if (targets[k] == me) continue;
        for (std::size_t si = 0; si < sets.size(); ++si) {
            const auto &which = to[si][static_cast<std::size_t>(targets[k])];
            pack(sets[si], which, out[k]);
            m.sent += static_cast<long>(which.size());
        }
        m.bytes_sent += out[k].size();
    }
    const std::vector<std::vector<std::byte>> in =
        far ? comm.all_to_all(out) : comm.exchange(targets, out, kTag);
    // The departed particles out, the others keeping their order.
    for (std::size_t si = 0; si < sets.size(); ++si) {
        ParticleSet &s = sets[si];
        std::vector<bool> gone(s.n, false);
        for (std::size_t r = 0; r < ranks; ++r)
            for (std::uint32_t p : to[si][r])
                gone[p] = true;
        std::size_t keep = 0;
        for (std::size_t p = 0; p < s.n; ++p)
            if (!gone[p]) s.move(p, keep++);
        s.resize(keep);
    }
    // The arrivals, in ascending rank of the sender.
    for (std::size_t k = 0; k < targets.size(); ++k) {
        if (targets[k] == me || in[k].empty()) continue;
        std::size_t at = 0;
        for (std::size_t si = 0; si < sets.size(); ++si) {
            const std::size_t before = sets[si].n;
            at += unpack(sets[si], in[k].data() + at, in[k].size() - at);
            m.received += static_cast<long>(sets[si].n - before);
        }
        if (at != in[k].size())
            throw Error(fmt::format("internal error: a migration message from rank {} has {} "
                                    "bytes left over",
                                    targets[k], in[k].size() - at));
    }
    return m;
}

} // namespace talus
