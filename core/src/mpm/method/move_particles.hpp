// The last pass of a step (seed 000 phase 4): positions, the faces that
// hold, the leaving check, and what the next step needs from the particles
// (their slabs and cells for the ordering, max(c + |v|) for its dt).
#pragma once

#include "kernels/isa.hpp"
#include "parallel/ordering.hpp"
#include "state/grid.hpp"

#include <talus/mpm/particles.hpp>

#include <array>
#include <atomic>
#include <cstddef>
#include <cstdint>
#include <limits>
#include <string>
#include <vector>

namespace talus {

// The domain's box and which of its faces are closed (any condition but
// free): a closed face is impenetrable.
struct Domain {
    std::array<double, 3> lo{0, 0, 0}, hi{0, 0, 0};
    std::array<bool, 3> closed_lo{false, false, false}, closed_hi{false, false, false};
    bool contains(const ParticleSet &s, std::size_t p, int dim) const;
};

// Whether the G2P pass has moved the particles already (the fused USL
// variant) or left their step in ParticleSet::dx.
enum class PositionStep { add_dx, already_moved };

struct StepEnd {
    double max_speed = 0.0; // max over particles of c + |v|, m/s
    long held = 0;          // positions put back onto a closed face
    double held_depth = 0.0;
    long outside = 0; // particles outside the domain (through a free face)
    // The cells the particles are in, lo..hi per axis (inclusive; as
    // GridGeometry::cell, clamped into the domain): where the next step's
    // stencils reach (Grid::reach). lo > hi: no particles.
    std::array<int, 3> cell_lo{kNoCell, kNoCell, kNoCell}, cell_hi{-1, -1, -1};
    static constexpr int kNoCell = std::numeric_limits<int>::max();
};

// The step's end, block by block: begin() before the pass, block() for
// every block of every set (from any thread, each block once, in any
// order; each starting at a multiple of the block size), finish() after
// it. Each block keeps its own partial result and
// finish() merges them in memory order, so the counts and the maximum are
// the same whatever the thread count and the schedule: the fused USL pass
// (g2p.hpp) runs block() on a block while it is still in cache, the other
// schemes in a pass of its own (move_particles).
class StepEndBlocks {
  public:
    // Partial results of one block of points: the maximum speed, the
    // points held at a closed face, those outside, those that changed slab,
    // the cells they are in, and the first and last point with their cells (descents, by more
    // than Ordering::far() cells, within the block are counted as it runs,
    // those across blocks when they merge).
    struct Partial {
        static constexpr std::size_t kNone = static_cast<std::size_t>(-1);
        double speed = 0.0, depth = 0.0;
        long outside = 0, moved = 0, held = 0, descents = 0;
        std::size_t first = kNone, last = kNone;
        std::uint32_t first_cell = 0, last_cell = 0;
        std::array<int, 3> cell_lo{StepEnd::kNoCell, StepEnd::kNoCell, StepEnd::kNoCell},
            cell_hi{-1, -1, -1};
        // Points from..from+k-1 (their cells cell[0..k)) were marked.
        void saw(std::size_t from, const std::uint32_t *cell, std::size_t k, std::uint32_t far);
        void merge(const Partial &o, std::uint32_t far);
    };

    // `block`: the points per block() call (the last of a set may be
    // shorter); block() runs with positions already moved or x + dx, in
    // packs across the vector lanes of instruction set `isa` (the results
    // do not depend on it).
    void begin(std::vector<ParticleSet> &sets, const GridGeometry &geo, const Domain &domain,
               Ordering &order, PositionStep step, std::size_t block, Isa isa);
    void block(std::size_t set, std::size_t begin, std::size_t count);
    // Throws talus::Error if a block broke block()'s contract (its partial
    // would have overwritten another's).
    StepEnd finish();

  private:
    std::vector<ParticleSet> *sets_ = nullptr;
    GridGeometry geo_;
    Domain domain_;
    Ordering *order_ = nullptr;
    bool add_ = false;
    Isa isa_ = Isa::generic;
    std::size_t block_ = 1;
    std::vector<Ordering::Marks> marks_;         // per set
    std::vector<std::vector<Partial>> partials_; // per set, per block (kept between steps)
    std::atomic<bool> misfiled_{false};          // a block not at a multiple of block_
};

// The step's end as a pass of its own (the schemes other than fused USL).
StepEnd move_particles(std::vector<ParticleSet> &sets, const GridGeometry &geo,
                       const Domain &domain, Ordering &order, PositionStep step,
                       StepEndBlocks &blocks, Isa isa);

// The particles outside the domain: removed (policy remove) or kept in
// place; the first few described for a report. Returns how many there were.
struct Leaving {
    long count = 0;
    std::vector<std::string> first; // "particle 12 of group 'a' at (x, y)"
};
Leaving collect_leaving(std::vector<ParticleSet> &sets, const Domain &domain, int dim, bool remove,
                        const std::vector<std::string> &group_names);

} // namespace talus
