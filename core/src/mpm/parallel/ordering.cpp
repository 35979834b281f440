#include "parallel/ordering.hpp"

#include "parallel/parallel.hpp"

#include <algorithm>
#include <cstdint>
#include <limits>
#include <numeric>

namespace talus {

Ordering::Ordering(const GridGeometry &geo, std::size_t n_sets)
    : geo_(geo), order_(n_sets), slab_begin_(n_sets), slab_of_(n_sets), cell_of_(n_sets) {
    // Slabs across the slowest-varying axis of the cell order (z, then y,
    // then x) that has kMinSlabs of them, else across the longest. Across
    // the last axis, a slab's particles are one stretch of memory once
    // sorted by cell, and a thread's share of the slabs, its share of the
    // fused G2P's chunks and its rows of the grid update are the same part
    // of the body, step after step, in the same core's cache; across y in
    // 3D (z too short), a slab is still one long stretch per plane of
    // cells. Across the longest axis of a domain longer than high (a
    // slope), a slab would be one short run of particles per row and the
    // threads' shares of P2G and of G2P would cross (docs/performance.md,
    // "Slabs across the slowest axis";
    // bench/results/2026-11-29-slab-axis-epyc-zen5.md). The rule depends
    // on the grid alone: one that followed the thread count would change
    // the order of P2G's sums with it.
    const int dim = geo.dim;
    const auto cells = [&](int d) { return geo.cells[static_cast<std::size_t>(d)]; };
    axis_ = -1;
    for (int d = dim - 1; d >= 0 && axis_ < 0; --d)
        if (cells(d) / kWidth >= kMinSlabs) axis_ = d;
    if (axis_ < 0) {
        axis_ = dim - 1;
        for (int d = dim - 2; d >= 0; --d)
            if (cells(d) > cells(axis_)) axis_ = d;
    }
    n_slabs_ = std::max(1, geo.cells[static_cast<std::size_t>(axis_)] / kWidth);
    // A row (2D) or plane (3D) of the cell order: cell_index's stride
    // along the last axis.
    std::uint64_t stride = 1;
    for (int d = 0; d + 1 < dim; ++d)
        stride *= static_cast<std::uint64_t>(geo.cells[static_cast<std::size_t>(d)]);
    far_ = static_cast<std::uint32_t>(
        std::min<std::uint64_t>(2 * stride, std::numeric_limits<std::uint32_t>::max()));
}

void Ordering::prepare(std::vector<ParticleSet> &sets, double threshold) {
    std::size_t n = 0;
    for (const ParticleSet &s : sets)
        n += s.n;
    if (threshold > 0.0 && out_of_order_ > threshold * static_cast<double>(n)) sort(sets);
    bin(sets);
}

Ordering::Marks Ordering::marks(std::size_t si, std::size_t n) {
    auto &slab = slab_of_[si];
    // -1: no slab yet, so every particle counts as having changed slab.
    if (slab.size() != n) slab.assign(n, -1);
    cell_of_[si].resize(n);
    return {slab.data(), cell_of_[si].data()};
}

void Ordering::invalidate() {
    for (auto &sl : slab_of_)
        sl.clear();
    slabs_changed_ = true;
}

void Ordering::restore(const std::vector<ParticleSet> &sets,
                       std::vector<std::vector<std::int32_t>> slab_of, double out_of_order,
                       bool slabs_changed) {
    slab_of_ = std::move(slab_of);
    for (std::size_t si = 0; si < order_.size(); ++si) {
        auto &slab = slab_of_[si];
        const ParticleSet &s = sets[si];
        if (slab.size() == s.n)
            for (std::size_t p = 0; p < s.n; ++p)
                if (slab[p] != slab_of_point(s, p)) {
                    slab.clear();
                    break;
                }
        order_[si].clear(); // binned afresh from the restored marks
        cell_of_[si].resize(slab.size());
    }
    out_of_order_ = out_of_order;
    slabs_changed_ = slabs_changed;
}

// Groups the particles of every set by slab (a counting sort of indices).
void Ordering::bin(const std::vector<ParticleSet> &sets) {
    // Unchanged slabs give the same order: nothing to redo.
    bool same = !slabs_changed_;
    for (std::size_t si = 0; same && si < sets.size(); ++si)
        same = order_[si].size() == sets[si].n && slab_of_[si].size() == sets[si].n;
    if (same) return;
    for (std::size_t si = 0; si < sets.size(); ++si) {
        const ParticleSet &s = sets[si];
        auto &begin = slab_begin_[si];
        begin.assign(static_cast<std::size_t>(n_slabs_) + 1, 0);
        // Slabs come from the last pass of the previous step, or are
        // computed here after a sort or at the start.
        auto &slab = slab_of_[si];
        if (slab.size() != s.n) {
            slab.resize(s.n);
            for (std::size_t p = 0; p < s.n; ++p)
                slab[p] = slab_of_point(s, p);
        }
        for (std::size_t p = 0; p < s.n; ++p)
            ++begin[static_cast<std::size_t>(slab[p]) + 1];
        std::partial_sum(begin.begin(), begin.end(), begin.begin());
        order_[si].resize(s.n);
        // Fill by decrementing the end offsets, walking backwards so that
        // each slab keeps memory order.
        end_scratch_.assign(begin.begin() + 1, begin.end());
        for (std::size_t p = s.n; p-- > 0;)
            order_[si][--end_scratch_[static_cast<std::size_t>(slab[p])]] =
                static_cast<std::uint32_t>(p);
    }
    slabs_changed_ = false;
}

namespace {

// The keys' extent and order, from one parallel pass over a set.
struct KeyRange {
    std::uint32_t lo = std::numeric_limits<std::uint32_t>::max(), hi = 0;
    // Whether the keys never decrease: within each thread's range, and (by
    // merge, in thread order) across the joins.
    bool ascending = true, empty = true;
    std::uint32_t first = 0, last = 0;
    void add(std::uint32_t k) {
        if (empty)
            first = k;
        else if (k < last)
            ascending = false;
        empty = false;
        last = k;
        lo = std::min(lo, k);
        hi = std::max(hi, k);
    }
    void merge(const KeyRange &o) {
        if (o.empty) return;
        if (empty) {
            *this = o;
            return;
        }
        ascending = ascending && o.ascending && last <= o.first;
        last = o.last;
        lo = std::min(lo, o.lo);
        hi = std::max(hi, o.hi);
    }
};

} // namespace

// Reorders each set's particles by cell: a stable sort of the permutation,
// then every column permuted in place (ParticleSet::permute).
//
// The sort is a counting sort over the cells the set occupies (one pass to
// count, one to place, in memory order so that particles of a cell keep
// theirs), O(n + cells), with the keys computed in parallel
// (bench/results/2026-11-27-re-sort-rule.md). Where the occupied cells
// outnumber the particles (a few particles spread over a large grid) the
// counts would cost more than they save, and std::stable_sort orders them
// instead. Both are stable sorts by the same key, so they give the same
// permutation.
void Ordering::sort(std::vector<ParticleSet> &sets) {
    std::vector<std::uint32_t> key, from, count;
    for (ParticleSet &s : sets) {
        key.resize(s.n);
        const KeyRange range = par::reduce<KeyRange>(s.n, [&](std::size_t p, KeyRange &r) {
            const double x[3] = {s.x[0][p], s.x[1][p], geo_.dim == 3 ? s.x[2][p] : 0.0};
            key[p] = static_cast<std::uint32_t>(geo_.cell_index(x));
            r.add(key[p]);
        });
        if (range.ascending) continue; // already in order: nothing moves
        from.resize(s.n);
        const std::size_t span = std::size_t{range.hi} - range.lo + 1;
        if (span <= s.n) {
            count.assign(span + 1, 0u);
            for (std::size_t p = 0; p < s.n; ++p)
                ++count[key[p] - range.lo + 1];
            std::partial_sum(count.begin(), count.end(), count.begin());
            for (std::size_t p = 0; p < s.n; ++p)
                from[count[key[p] - range.lo]++] = static_cast<std::uint32_t>(p);
        } else {
            std::iota(from.begin(), from.end(), 0u);
            std::stable_sort(from.begin(), from.end(),
                             [&](std::uint32_t a, std::uint32_t b) { return key[a] < key[b]; });
        }
        s.permute(from);
    }
    invalidate();
}

} // namespace talus
