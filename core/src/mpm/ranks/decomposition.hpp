// The grid's cells split among ranks (docs/mpi.md, "Decomposition"): by
// recursive coordinate bisection weighted by particle count (Berger and
// Bokhari 1987), each rank owning a box of cells. A rank holds the nodes of
// its box widened by the ghost layers (kGhostLayers, the widest stencil's
// reach from a cell), so that every node its particles reach is local;
// nodes shared with other ranks are summed after each P2G (halo.hpp).
#pragma once

#include <array>
#include <cstddef>
#include <functional>
#include <vector>

namespace talus {

// Cells [lo, hi) per axis (the unused axes of 2D are [0, 1)).
struct CellBox {
    std::array<int, 3> lo{0, 0, 0}, hi{1, 1, 1};
    long cells() const {
        return static_cast<long>(hi[0] - lo[0]) * (hi[1] - lo[1]) * (hi[2] - lo[2]);
    }
    bool contains(const std::array<int, 3> &c) const {
        for (std::size_t d = 0; d < 3; ++d)
            if (c[d] < lo[d] || c[d] >= hi[d]) return false;
        return true;
    }
    friend bool operator==(const CellBox &, const CellBox &) = default;
};

// Nodes [lo, hi] per axis (inclusive), global numbering.
struct NodeBox {
    std::array<int, 3> lo{0, 0, 0}, hi{0, 0, 0};
    bool empty() const {
        for (std::size_t d = 0; d < 3; ++d)
            if (hi[d] < lo[d]) return true;
        return false;
    }
};
NodeBox intersect(const NodeBox &a, const NodeBox &b);

class Decomposition {
  public:
    // The particle weight of each cell plane of `box` across `axis`
    // (box.hi[axis] - box.lo[axis] values): of all ranks' particles, so in
    // a running simulation the caller sums its own over the ranks. Called
    // the same number of times, in the same order, on every rank.
    using Histogram = std::function<std::vector<double>(const CellBox &box, int axis)>;

    // All cells on one rank.
    Decomposition(int dim, const std::array<int, 3> &cells);
    // `ranks` boxes of the domain's cells, each with about the same weight:
    // a box is cut across its longest side at the plane that best splits
    // its weight in proportion to the ranks on either side. Every box gets
    // at least one cell plane; throws talus::Error when the grid has fewer
    // cells along the cut sides than there are ranks.
    static Decomposition bisect(int dim, const std::array<int, 3> &cells, int ranks,
                                const Histogram &weight);

    // The decomposition whose rank r owns boxes[r] (a checkpoint's): its
    // bisection tree is found again from the boxes. Throws talus::Error
    // when they do not tile the grid as a bisection would.
    static Decomposition from_boxes(int dim, const std::array<int, 3> &cells,
                                    const std::vector<CellBox> &boxes);

    int dim() const { return dim_; }
    int ranks() const { return static_cast<int>(boxes_.size()); }
    const std::array<int, 3> &cells() const { return cells_; }
    const CellBox &box(int rank) const { return boxes_[static_cast<std::size_t>(rank)]; }
    // The rank owning a cell (clamped into the domain).
    int owner(std::array<int, 3> cell) const;
    // The rank owning a node: that of the cell the node begins (the last
    // cell for the domain's far nodes, the first for the ghost layers), so
    // each node has exactly one.
    int node_owner(std::array<int, 3> node) const;
    // The nodes rank r holds: its cells' nodes and `ghost` layers around.
    NodeBox nodes(int rank, int ghost) const;
    // The ranks whose held nodes overlap rank r's, ascending, r excluded.
    std::vector<int> neighbours(int rank, int ghost) const;

  private:
    // The bisection tree: an inner node cuts at `cut` along `axis` (cells
    // below go to `low`), a leaf is a rank.
    struct Cut {
        int axis = 0, cut = 0, low = -1, high = -1, rank = -1;
    };
    int build(const CellBox &box, int first_rank, int ranks, const Histogram &weight);
    int rebuild(const CellBox &region, const std::vector<int> &ranks);
    int dim_ = 2;
    std::array<int, 3> cells_{1, 1, 1};
    std::vector<CellBox> boxes_;
    std::vector<Cut> tree_;
};

} // namespace talus
