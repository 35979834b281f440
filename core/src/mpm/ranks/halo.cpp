#include "ranks/halo.hpp"

#include <talus/error.hpp>

#include <algorithm>
#include <bit>
#include <cstring>

namespace talus {

namespace {

constexpr int kTag = 7100;

std::size_t slot_of(const GridGeometry &geo, int i, int j, int k) {
    const std::size_t ex = static_cast<std::size_t>(geo.extent[0]);
    const std::size_t ey = static_cast<std::size_t>(geo.extent[1]);
    return static_cast<std::size_t>(i - geo.first[0]) +
           ex * (static_cast<std::size_t>(j - geo.first[1]) +
                 ey * static_cast<std::size_t>(k - geo.first[2]));
}

} // namespace

Halo::Halo(const Decomposition &decomp, int rank, const GridGeometry &geo, int ghost)
    : rank_(rank), peers_(decomp.neighbours(rank, ghost)) {
    const NodeBox mine = decomp.nodes(rank, ghost);
    std::vector<std::vector<std::uint32_t>> slots(peers_.size());
    for (std::size_t k = 0; k < peers_.size(); ++k) {
        // Both sides walk the overlap in global node order: the same list.
        const NodeBox o = intersect(mine, decomp.nodes(peers_[k], ghost));
        for (int z = o.lo[2]; z <= o.hi[2]; ++z)
            for (int y = o.lo[1]; y <= o.hi[1]; ++y)
                for (int x = o.lo[0]; x <= o.hi[0]; ++x)
                    slots[k].push_back(static_cast<std::uint32_t>(slot_of(geo, x, y, z)));
        shared_.insert(shared_.end(), slots[k].begin(), slots[k].end());
    }
    std::sort(shared_.begin(), shared_.end());
    shared_.erase(std::unique(shared_.begin(), shared_.end()), shared_.end());
    positions_.resize(peers_.size());
    for (std::size_t k = 0; k < peers_.size(); ++k)
        for (std::uint32_t s : slots[k])
            positions_[k].push_back(static_cast<std::uint32_t>(
                std::lower_bound(shared_.begin(), shared_.end(), s) - shared_.begin()));
    send_.resize(peers_.size());
}

std::size_t Halo::sum(const Comm &comm, double *records, unsigned fields) {
    if (peers_.empty()) return 0;
    std::size_t f_list[node::kRecord], nf = 0;
    for (std::size_t f = 0; f < node::kRecord; ++f)
        if (fields & (1u << f)) f_list[nf++] = f;
    auto is_fixity = [](std::size_t f) { return f == node::kFixity; };
    std::size_t sent = 0;
    for (std::size_t k = 0; k < peers_.size(); ++k) {
        std::vector<std::byte> &out = send_[k];
        out.resize(positions_[k].size() * nf * sizeof(double));
        double *o = reinterpret_cast<double *>(out.data());
        for (std::uint32_t pos : positions_[k]) {
            const double *r = records + node::kRecord * shared_[pos];
            for (std::size_t q = 0; q < nf; ++q)
                *o++ = r[f_list[q]];
        }
        sent += out.size();
    }
    const std::vector<std::vector<std::byte>> in = comm.exchange(peers_, send_, kTag);
    // This rank's own contributions aside, the shared fields cleared, then
    // every rank's added in ascending rank order (0 + a is a exactly).
    own_.resize(shared_.size() * nf);
    for (std::size_t s = 0; s < shared_.size(); ++s) {
        double *r = records + node::kRecord * shared_[s];
        for (std::size_t q = 0; q < nf; ++q) {
            own_[s * nf + q] = r[f_list[q]];
            r[f_list[q]] = 0.0;
        }
    }
    auto add = [&](double &to, double v, std::size_t f) {
        if (is_fixity(f))
            to =
                static_cast<double>(static_cast<std::uint32_t>(to) | static_cast<std::uint32_t>(v));
        else
            to += v;
    };
    auto add_own = [&] {
        for (std::size_t s = 0; s < shared_.size(); ++s) {
            double *r = records + node::kRecord * shared_[s];
            for (std::size_t q = 0; q < nf; ++q)
                add(r[f_list[q]], own_[s * nf + q], f_list[q]);
        }
    };
    bool own_done = false;
    for (std::size_t k = 0; k < peers_.size(); ++k) {
        if (!own_done && peers_[k] > rank_) {
            add_own();
            own_done = true;
        }
        const double *v = reinterpret_cast<const double *>(in[k].data());
        if (in[k].size() != positions_[k].size() * nf * sizeof(double))
            throw Error("internal error: a halo message of the wrong length");
        for (std::uint32_t pos : positions_[k]) {
            double *r = records + node::kRecord * shared_[pos];
            for (std::size_t q = 0; q < nf; ++q)
                add(r[f_list[q]], *v++, f_list[q]);
        }
    }
    if (!own_done) add_own();
    return sent;
}

} // namespace talus
