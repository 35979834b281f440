// The order particles are visited in: sorted by cell in memory (so that
// neighbours on the grid are neighbours in memory, for the caches of P2G
// and G2P), and binned into slabs for the conflict-free parallel P2G.
//
// Slab colouring: slabs of `width` cells along `axis`; a particle's stencil
// reaches at most one cell below and two above its own, so slabs of one
// colour (every other slab) never write the same node when width >= 4.
#pragma once

#include "state/grid.hpp"

#include <talus/mpm/particles.hpp>

#include <cstddef>
#include <cstdint>
#include <vector>

namespace talus {

class Ordering {
  public:
    Ordering(const GridGeometry &geo, std::size_t n_sets);

    // Cells per slab along the axis.
    static constexpr int kWidth = 4;
    // Slabs the slowest axis needs to be chosen (the constructor): 8 keep
    // two threads busy through both colours, each with two slabs of each.
    static constexpr int kMinSlabs = 8;

    int axis() const { return axis_; }
    int n_slabs() const { return n_slabs_; }
    int slab_of_cell(int cell) const { return std::min(cell / kWidth, n_slabs_ - 1); }
    // Particle p's slab, from its position.
    int slab_of_point(const ParticleSet &s, std::size_t p) const {
        return slab_of_cell(geo_.cell(axis_, s.x[static_cast<std::size_t>(axis_)][p]));
    }
    // Set si's particles of one slab, in memory order.
    struct Range {
        const std::uint32_t *begin, *end;
    };
    Range slab(std::size_t si, int slab) const {
        const auto &b = slab_begin_[si];
        const std::uint32_t *o = order_[si].data();
        return {o + b[static_cast<std::size_t>(slab)], o + b[static_cast<std::size_t>(slab) + 1]};
    }

    // Re-sorts every set by cell if more than `threshold` of the particles
    // are far out of cell order (0: never), then bins them by slab.
    //
    // Far: in a cell more than far() cells below its predecessor's in
    // memory. A particle a row or so out of place still finds its node
    // records in the cache its predecessors filled (P2G and G2P read a
    // cell's nodes and the rows, or planes, on either side), so only the
    // descents past that window are the decay a sort repairs. Counting
    // every descent sorts a flowing body at almost every step, where
    // particles cross cells all the time, and the re-sorts then cost more
    // than the order they restore saves (docs/performance.md, "When to
    // re-sort"; bench/results/2026-11-27-re-sort-rule.md).
    void prepare(std::vector<ParticleSet> &sets, double threshold);
    // Sorts every set by cell now.
    void sort(std::vector<ParticleSet> &sets);

    // What the last pass of a step records for the next one: each
    // particle's slab and cell, written in that pass's loop.
    struct Marks {
        std::int32_t *slab;
        std::uint32_t *cell;
    };
    Marks marks(std::size_t si, std::size_t n);
    // After that pass: how many particles changed slab, and how many sit
    // far below their predecessor in the cell order (the decay of the sort).
    void marked(long changed_slab, double out_of_order) {
        slabs_changed_ = changed_slab > 0;
        out_of_order_ = out_of_order;
    }
    // The window of the decay: two rows (2D) or planes (3D) of the cell
    // order. Not capped in bytes: on a large 3D grid a cap below a plane
    // would count every crossing of a plane again, and a particle a plane
    // out of place adds only the nodes of one plane of its stencil to what
    // its neighbours in memory read.
    std::uint32_t far() const { return far_; }
    static bool far_below(std::uint32_t cell, std::uint32_t before, std::uint32_t far) {
        return std::uint64_t{cell} + far < before;
    }

    // Particles were removed or moved: slabs are recomputed at the next bin.
    void invalidate();

    // What the next step's order depends on (Snapshot), and its restoring.
    const std::vector<std::int32_t> &slabs(std::size_t si) const { return slab_of_[si]; }
    double out_of_order() const { return out_of_order_; }
    bool slabs_changed() const { return slabs_changed_; }
    // The marks are checked against the restored sets' positions: a set
    // with one that is not its particle's slab (a checkpoint of a build
    // that chose other slabs, or a damaged one) is binned afresh from the
    // positions. Trusted, such a mark would put a particle into a slab
    // whose nodes another thread writes at the same time, or past the
    // slab count.
    void restore(const std::vector<ParticleSet> &sets,
                 std::vector<std::vector<std::int32_t>> slab_of, double out_of_order,
                 bool slabs_changed);

  private:
    void bin(const std::vector<ParticleSet> &sets);
    GridGeometry geo_;
    int axis_ = 0, n_slabs_ = 1;
    std::uint32_t far_ = 0;
    std::vector<std::vector<std::uint32_t>> order_;    // per set: particle indices by slab
    std::vector<std::vector<std::size_t>> slab_begin_; // per set: n_slabs + 1 offsets
    std::vector<std::vector<std::int32_t>> slab_of_;   // per set, per particle
    std::vector<std::vector<std::uint32_t>> cell_of_;  // per set, per particle
    std::vector<std::size_t> end_scratch_;
    double out_of_order_ = 0.0;
    bool slabs_changed_ = true;
};

} // namespace talus
