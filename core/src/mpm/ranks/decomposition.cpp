#include "ranks/decomposition.hpp"

#include <talus/error.hpp>

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <numeric>

namespace talus {

NodeBox intersect(const NodeBox &a, const NodeBox &b) {
    NodeBox o;
    for (std::size_t d = 0; d < 3; ++d) {
        o.lo[d] = std::max(a.lo[d], b.lo[d]);
        o.hi[d] = std::min(a.hi[d], b.hi[d]);
    }
    return o;
}

Decomposition::Decomposition(int dim, const std::array<int, 3> &cells) : dim_(dim), cells_(cells) {
    CellBox all;
    all.hi = cells;
    boxes_.push_back(all);
    tree_.push_back(Cut{.rank = 0});
}

Decomposition Decomposition::bisect(int dim, const std::array<int, 3> &cells, int ranks,
                                    const Histogram &weight) {
    Decomposition d(dim, cells);
    if (ranks <= 1) return d;
    long total = 1;
    for (int a = 0; a < dim; ++a)
        total *= cells[static_cast<std::size_t>(a)];
    if (total < ranks)
        throw Error(fmt::format("the grid has {} cells, fewer than the {} ranks to share them",
                                total, ranks));
    d.boxes_.assign(static_cast<std::size_t>(ranks), CellBox{});
    d.tree_.clear();
    d.build(d.boxes_[0] = CellBox{{0, 0, 0}, cells}, 0, ranks, weight);
    return d;
}

// Cuts `box` for ranks [first_rank, first_rank + ranks); returns its tree
// node. Every rank runs the same cuts (the histograms are global), so every
// rank builds the same tree.
int Decomposition::build(const CellBox &box, int first_rank, int ranks, const Histogram &weight) {
    const int me = static_cast<int>(tree_.size());
    tree_.emplace_back();
    if (ranks == 1) {
        tree_[static_cast<std::size_t>(me)].rank = first_rank;
        boxes_[static_cast<std::size_t>(first_rank)] = box;
        return me;
    }
    const int low_ranks = ranks / 2, high_ranks = ranks - low_ranks;
    // The longest side that can be cut with enough cells on either side
    // for its ranks; on a tie the later axis (slabs across the slowest
    // index keep a box's particles contiguous in cell order).
    int axis = -1;
    long best_len = 0;
    for (int a = 0; a < dim_; ++a) {
        const std::size_t aa = static_cast<std::size_t>(a);
        const long len = box.hi[aa] - box.lo[aa];
        const long cross = box.cells() / std::max<long>(1, len);
        // The smallest low part that holds low_ranks cells, and the
        // largest that leaves high_ranks.
        const long min_low = (low_ranks + cross - 1) / cross;
        const long max_low = len - (high_ranks + cross - 1) / cross;
        if (min_low > max_low) continue;
        if (len >= best_len) {
            best_len = len;
            axis = a;
        }
    }
    if (axis < 0)
        throw Error(
            fmt::format("cannot share a box of {} cells among {} ranks", box.cells(), ranks));
    const std::size_t aa = static_cast<std::size_t>(axis);
    const long len = box.hi[aa] - box.lo[aa];
    const long cross = box.cells() / len;
    const long min_low = (low_ranks + cross - 1) / cross;
    const long max_low = len - (high_ranks + cross - 1) / cross;
    std::vector<double> w = weight(box, axis);
    if (static_cast<long>(w.size()) != len)
        throw Error(fmt::format("internal error: a histogram of {} planes for a side of {}",
                                w.size(), len));
    double sum = std::accumulate(w.begin(), w.end(), 0.0);
    if (!(sum > 0.0)) { // no particles: share the volume
        std::fill(w.begin(), w.end(), 1.0);
        sum = static_cast<double>(len);
    }
    const double target = sum * static_cast<double>(low_ranks) / static_cast<double>(ranks);
    // The cut whose low part's weight is nearest the target; among equals
    // the one nearest the proportional split of the side (empty planes).
    const double even = static_cast<double>(len) * low_ranks / ranks;
    long cut = min_low;
    double best = std::numeric_limits<double>::infinity(), best_even = best;
    double below = std::accumulate(w.begin(), w.begin() + min_low, 0.0);
    for (long c = min_low; c <= max_low; ++c) {
        const double miss = std::abs(below - target);
        const double off = std::abs(static_cast<double>(c) - even);
        if (miss < best || (miss == best && off < best_even)) {
            best = miss;
            best_even = off;
            cut = c;
        }
        if (c < len) below += w[static_cast<std::size_t>(c)];
    }
    CellBox low = box, high = box;
    low.hi[aa] = box.lo[aa] + static_cast<int>(cut);
    high.lo[aa] = low.hi[aa];
    const int l = build(low, first_rank, low_ranks, weight);
    const int h = build(high, first_rank + low_ranks, high_ranks, weight);
    Cut &c = tree_[static_cast<std::size_t>(me)];
    c.axis = axis;
    c.cut = low.hi[aa];
    c.low = l;
    c.high = h;
    return me;
}

Decomposition Decomposition::from_boxes(int dim, const std::array<int, 3> &cells,
                                        const std::vector<CellBox> &boxes) {
    Decomposition d(dim, cells);
    if (boxes.empty()) throw Error("a decomposition of no boxes");
    d.boxes_ = boxes;
    d.tree_.clear();
    std::vector<int> ranks(boxes.size());
    std::iota(ranks.begin(), ranks.end(), 0);
    d.rebuild(CellBox{{0, 0, 0}, cells}, ranks);
    return d;
}

// The tree node for `ranks`, whose boxes must tile `region`: a plane that
// no box straddles splits them into two non-empty sets (a bisection's
// boxes always have one), down to one box, which must be the region.
int Decomposition::rebuild(const CellBox &region, const std::vector<int> &ranks) {
    const int me = static_cast<int>(tree_.size());
    tree_.emplace_back();
    auto bad = [&] {
        return Error(fmt::format("the {} cell boxes do not tile the grid of {} x {} x {} cells as "
                                 "a bisection does",
                                 boxes_.size(), cells_[0], cells_[1], cells_[2]));
    };
    if (ranks.size() == 1) {
        if (!(boxes_[static_cast<std::size_t>(ranks[0])] == region)) throw bad();
        tree_[static_cast<std::size_t>(me)].rank = ranks[0];
        return me;
    }
    for (int axis = 0; axis < dim_; ++axis) {
        const std::size_t a = static_cast<std::size_t>(axis);
        for (int r : ranks) {
            const int cut = boxes_[static_cast<std::size_t>(r)].hi[a];
            if (cut <= region.lo[a] || cut >= region.hi[a]) continue;
            std::vector<int> low, high;
            for (int q : ranks) {
                const CellBox &b = boxes_[static_cast<std::size_t>(q)];
                if (b.hi[a] <= cut)
                    low.push_back(q);
                else if (b.lo[a] >= cut)
                    high.push_back(q);
            }
            if (low.size() + high.size() != ranks.size()) continue; // a box straddles it
            CellBox lo_region = region, hi_region = region;
            lo_region.hi[a] = cut;
            hi_region.lo[a] = cut;
            const int l = rebuild(lo_region, low);
            const int h = rebuild(hi_region, high);
            Cut &c = tree_[static_cast<std::size_t>(me)];
            c.axis = axis;
            c.cut = cut;
            c.low = l;
            c.high = h;
            return me;
        }
    }
    throw bad();
}

int Decomposition::owner(std::array<int, 3> cell) const {
    for (std::size_t d = 0; d < 3; ++d)
        cell[d] = std::clamp(cell[d], 0, cells_[d] - 1);
    int k = 0;
    while (tree_[static_cast<std::size_t>(k)].rank < 0) {
        const Cut &c = tree_[static_cast<std::size_t>(k)];
        k = cell[static_cast<std::size_t>(c.axis)] < c.cut ? c.low : c.high;
    }
    return tree_[static_cast<std::size_t>(k)].rank;
}

int Decomposition::node_owner(std::array<int, 3> node) const { return owner(node); }

NodeBox Decomposition::nodes(int rank, int ghost) const {
    const CellBox &b = box(rank);
    NodeBox n;
    for (std::size_t d = 0; d < 3; ++d) {
        if (static_cast<int>(d) < dim_) {
            n.lo[d] = b.lo[d] - ghost;
            n.hi[d] = b.hi[d] + ghost;
        } else {
            n.lo[d] = n.hi[d] = 0;
        }
    }
    return n;
}

std::vector<int> Decomposition::neighbours(int rank, int ghost) const {
    std::vector<int> out;
    const NodeBox mine = nodes(rank, ghost);
    for (int r = 0; r < ranks(); ++r)
        if (r != rank && !intersect(mine, nodes(r, ghost)).empty()) out.push_back(r);
    return out;
}

} // namespace talus
