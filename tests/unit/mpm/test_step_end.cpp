// The step's end pass by blocks (core/src/mpm/method/move_particles.hpp) against
// its definition written as one plain loop over the particles: positions
// put back onto closed faces (counted, with the deepest overshoot), the
// particles outside the domain, max(c + |v|), each particle's cell and
// slab, the slab changes, and the descents of the cell order in memory
// (within each set, none across sets). The blocks may run in any order and
// be of any size (the fused USL pass runs them from whichever thread takes
// them): every result must be the loop's exactly, integers and the maximum
// alike, since none of them involves a sum in floating point. So must the
// block's packs across the vector lanes of every instruction set.
#include "isas.hpp"
#include "kernels/isa.hpp"
#include "method/move_particles.hpp"
#include "parallel/ordering.hpp"

#include <talus/error.hpp>

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <limits>
#include <numeric>
#include <random>
#include <vector>

namespace {

using talus::Domain;
using talus::GridGeometry;
using talus::Isa;
using talus::Ordering;
using talus::ParticleSet;
using talus::PositionStep;
using talus::StepEnd;
using talus::StepEndBlocks;

// A grid of 40 x 24 (x 6) cells of 0.05 m from (-1, 0.5, 2); in 2D closed
// x- and y- faces, free x+ and y+; in 3D also a closed z+ face and a free
// z- one.
GridGeometry geometry(int dim = 2) {
    GridGeometry g;
    g.dim = dim;
    g.h = 0.05;
    g.inv_h = 1.0 / g.h;
    g.origin = {-1.0, 0.5, 2.0};
    g.cells = {40, 24, dim == 3 ? 6 : 1};
    return g;
}

Domain domain_of(const GridGeometry &g) {
    Domain d;
    for (std::size_t a = 0; a < static_cast<std::size_t>(g.dim); ++a) {
        d.lo[a] = g.origin[a];
        d.hi[a] = g.origin[a] + g.cells[a] * g.h;
    }
    d.closed_lo = {true, true, false};
    d.closed_hi = {false, false, g.dim == 3};
    return d;
}

// Two sets of particles, mostly in cell order with disorder mixed in, some
// stepping through the closed faces (held), some through the free ones
// (outside). Moved: x already holds x + dx, and dx is NaN (the fused
// pass's form: the step's end must not read it).
std::vector<ParticleSet> particles(const GridGeometry &g, std::uint32_t seed, bool moved = false) {
    std::mt19937 rng(seed);
    std::uniform_real_distribution<double> u(0.0, 1.0);
    const std::size_t dim = static_cast<std::size_t>(g.dim);
    std::vector<ParticleSet> sets(2);
    const std::size_t n[2] = {1500, 777};
    for (std::size_t si = 0; si < 2; ++si) {
        ParticleSet &s = sets[si];
        s.dim = g.dim;
        s.has_C = s.has_divv = s.has_lp = s.has_L = false;
        s.resize(n[si]);
        for (std::size_t p = 0; p < s.n; ++p) {
            // Sorted along the last axis by index, the others random:
            // descents inside rows.
            const double f = (static_cast<double>(p) + u(rng)) / static_cast<double>(s.n);
            for (std::size_t d = 0; d + 1 < dim; ++d)
                s.x[d][p] = g.origin[d] + u(rng) * g.cells[d] * g.h;
            s.x[dim - 1][p] = g.origin[dim - 1] + f * g.cells[dim - 1] * g.h;
            const double kick = u(rng);
            for (std::size_t d = 0; d < dim; ++d)
                s.dx[d][p] = (u(rng) - 0.5) * 0.02 + (kick < 0.05 ? -0.3 : kick > 0.95 ? 0.3 : 0.0);
            for (std::size_t d = 0; d < dim; ++d)
                s.v[d][p] = (u(rng) - 0.5) * 4.0;
            s.c[p] = 50.0 + 10.0 * u(rng);
            if (moved)
                for (std::size_t d = 0; d < dim; ++d) {
                    s.x[d][p] += s.dx[d][p];
                    s.dx[d][p] = std::nan("");
                }
        }
    }
    return sets;
}

struct Expected {
    StepEnd end;
    // Descents by more than Ordering::far() cells (what the step's end
    // counts), and by less (what it must not).
    long moved = 0, descents = 0, near_descents = 0;
    std::vector<std::vector<double>> x[3];
    std::vector<std::vector<std::int32_t>> slab;
};

// The definition, one particle after the other.
Expected reference(std::vector<ParticleSet> sets, const GridGeometry &g, const Domain &dom,
                   const Ordering &order) {
    Expected e;
    const std::size_t dim = static_cast<std::size_t>(g.dim);
    for (std::size_t d = 0; d < dim; ++d)
        e.x[d].resize(sets.size());
    e.slab.resize(sets.size());
    // Two rows (2D) or planes (3D) of the cell order: far from a cell's
    // nodes for the caches (Ordering::prepare).
    const long far = 2L * g.cells[0] * (dim == 3 ? g.cells[1] : 1);
    for (std::size_t si = 0; si < sets.size(); ++si) {
        ParticleSet &s = sets[si];
        long last_cell = -1;
        for (std::size_t p = 0; p < s.n; ++p) {
            bool in = true;
            long cell[3] = {0, 0, 0};
            double v2 = 0.0;
            for (std::size_t d = 0; d < dim; ++d) {
                double x = s.x[d][p] + s.dx[d][p];
                if (dom.closed_lo[d] && x < dom.lo[d]) {
                    e.end.held_depth = std::max(e.end.held_depth, dom.lo[d] - x);
                    ++e.end.held;
                    x = dom.lo[d];
                }
                if (dom.closed_hi[d] && x > dom.hi[d]) {
                    e.end.held_depth = std::max(e.end.held_depth, x - dom.hi[d]);
                    ++e.end.held;
                    x = dom.hi[d];
                }
                in = in && x >= dom.lo[d] && x <= dom.hi[d];
                e.x[d][si].push_back(x);
                cell[d] = std::clamp(static_cast<long>(std::floor((x - g.origin[d]) / g.h)), 0L,
                                     static_cast<long>(g.cells[d]) - 1);
                v2 += s.v[d][p] * s.v[d][p];
            }
            e.end.outside += in ? 0 : 1;
            e.end.max_speed = std::max(e.end.max_speed, s.c[p] + std::sqrt(v2));
            const long ci = cell[0] + g.cells[0] * (cell[1] + g.cells[1] * cell[2]);
            if (p > 0 && ci < last_cell) ++(ci + far < last_cell ? e.descents : e.near_descents);
            last_cell = ci;
            const int slab =
                std::min(static_cast<int>(cell[order.axis()]) / 4, order.n_slabs() - 1);
            e.slab[si].push_back(slab);
            ++e.moved; // the first pass: no slab before it
        }
    }
    return e;
}

void expect_equal(const Expected &e, const StepEnd &got, const std::vector<ParticleSet> &sets,
                  const Ordering &order) {
    EXPECT_EQ(got.held, e.end.held);
    EXPECT_EQ(got.held_depth, e.end.held_depth);
    EXPECT_EQ(got.outside, e.end.outside);
    EXPECT_EQ(got.max_speed, e.end.max_speed);
    EXPECT_EQ(order.out_of_order(), static_cast<double>(e.descents));
    EXPECT_EQ(order.slabs_changed(), e.moved > 0);
    for (std::size_t si = 0; si < sets.size(); ++si) {
        EXPECT_EQ(order.slabs(si), e.slab[si]);
        for (std::size_t d = 0; d < static_cast<std::size_t>(sets[si].dim); ++d)
            for (std::size_t p = 0; p < sets[si].n; ++p)
                ASSERT_EQ(sets[si].x[d][p], e.x[d][si][p]) << "set " << si << " particle " << p;
    }
}

TEST(StepEnd, BlocksInAnyOrderAndOfAnySizeGiveThePlainLoopsResults) {
    std::mt19937 shuffle(7);
    for (int dim : {2, 3})
        for (bool moved : {false, true})
            for (Isa isa : runnable_isas()) {
                const GridGeometry g = geometry(dim);
                const Domain dom = domain_of(g);
                const PositionStep step =
                    moved ? PositionStep::already_moved : PositionStep::add_dx;
                // Blocks shorter than, as long as and longer than a pack.
                for (const std::size_t block :
                     {std::size_t{1}, std::size_t{7}, std::size_t{8}, std::size_t{13},
                      std::size_t{128}, std::size_t{5000}}) {
                    for (int order_kind = 0; order_kind < 3; ++order_kind) {
                        std::vector<ParticleSet> sets = particles(g, 11, moved);
                        Ordering order(g, sets.size());
                        const Expected e = reference(particles(g, 11), g, dom, order);
                        // The test must be able to fail: the cases hold,
                        // descend and leave.
                        ASSERT_GT(e.end.held, 10);
                        ASSERT_GT(e.end.outside, 10);
                        ASSERT_GT(e.descents, 100);
                        ASSERT_GT(e.near_descents, 100);
                        StepEndBlocks ends;
                        ends.begin(sets, g, dom, order, step, block, isa);
                        std::vector<std::pair<std::size_t, std::size_t>> jobs;
                        for (std::size_t si = 0; si < sets.size(); ++si)
                            for (std::size_t b = 0; b < sets[si].n; b += block)
                                jobs.emplace_back(si, b);
                        if (order_kind == 1) std::reverse(jobs.begin(), jobs.end());
                        if (order_kind == 2) std::shuffle(jobs.begin(), jobs.end(), shuffle);
                        for (const auto &[si, b] : jobs)
                            ends.block(si, b, std::min(block, sets[si].n - b));
                        SCOPED_TRACE(testing::Message()
                                     << talus::isa_name(isa) << ", dim " << dim
                                     << (moved ? ", moved" : ", x + dx") << ", block " << block
                                     << ", order " << order_kind);
                        expect_equal(e, ends.finish(), sets, order);
                    }
                }
            }
}

// A block that does not start at a multiple of the block size would file
// its partial over another's: refused when the pass ends, not lost.
TEST(StepEnd, AMisalignedBlockIsRefusedNotLost) {
    const GridGeometry g = geometry();
    const Domain dom = domain_of(g);
    std::vector<ParticleSet> sets = particles(g, 3);
    Ordering order(g, sets.size());
    StepEndBlocks ends;
    ends.begin(sets, g, dom, order, PositionStep::add_dx, 128, Isa::generic);
    ends.block(0, 0, 100);
    ends.block(0, 100, 128); // overlaps block 0's slot
    EXPECT_THROW(ends.finish(), talus::Error);
    // The next pass starts clean.
    ends.begin(sets, g, dom, order, PositionStep::add_dx, 128, Isa::generic);
    for (std::size_t si = 0; si < sets.size(); ++si)
        for (std::size_t b = 0; b < sets[si].n; b += 128)
            ends.block(si, b, std::min<std::size_t>(128, sets[si].n - b));
    EXPECT_NO_THROW(ends.finish());
}

TEST(StepEnd, ThePassOfItsOwnGivesThePlainLoopsResults) {
    const GridGeometry g = geometry();
    const Domain dom = domain_of(g);
    for (Isa isa : runnable_isas()) {
        std::vector<ParticleSet> sets = particles(g, 23);
        Ordering order(g, sets.size());
        const Expected e = reference(particles(g, 23), g, dom, order);
        StepEndBlocks ends;
        SCOPED_TRACE(talus::isa_name(isa));
        expect_equal(e, talus::move_particles(sets, g, dom, order, PositionStep::add_dx, ends, isa),
                     sets, order);
    }
}

} // namespace

namespace {

// A position far outside the domain or NaN (a run blowing up) takes the
// clamped end cell without an out-of-range conversion to int (undefined
// behaviour, which the sanitizer build reports), and for a finite
// coordinate the cell is floor() clamped into the domain.
TEST(StepEnd, CellsOfPositionsFarOutsideOrNaNAreClamped) {
    using talus::GridGeometry;
    const int n = 40;
    EXPECT_EQ(GridGeometry::clamped_cell(std::nan(""), n), 0);
    EXPECT_EQ(GridGeometry::clamped_cell(-1e300, n), 0);
    EXPECT_EQ(GridGeometry::clamped_cell(1e300, n), n - 1);
    EXPECT_EQ(GridGeometry::clamped_cell(std::numeric_limits<double>::infinity(), n), n - 1);
    for (double xi = -3.0; xi < n + 3.0; xi += 0.0625)
        EXPECT_EQ(GridGeometry::clamped_cell(xi, n),
                  std::clamp(static_cast<int>(std::floor(xi)), 0, n - 1))
            << "xi = " << xi;
}

TEST(StepEnd, AParticleWithANonFinitePositionIsCountedOutside) {
    const GridGeometry g = geometry();
    const Domain dom = domain_of(g);
    std::vector<ParticleSet> sets = particles(g, 31);
    Ordering order(g, sets.size());
    Expected e = reference(particles(g, 31), g, dom, order);
    sets[0].dx[0][17] = std::nan("");
    sets[1].dx[1][3] = 1e300;
    StepEndBlocks ends;
    const StepEnd got =
        talus::move_particles(sets, g, dom, order, PositionStep::add_dx, ends, talus::kernel_isa());
    // Particle 17 of set 0 and 3 of set 1 were inside the domain before
    // (the reference counted them so) unless the test's random steps had
    // already taken them out.
    const long was_out = (e.x[0][0][17] < dom.lo[0] || e.x[0][0][17] > dom.hi[0] ||
                          e.x[1][0][17] < dom.lo[1] || e.x[1][0][17] > dom.hi[1])
                             ? 1
                             : 0;
    const long was_out_2 = (e.x[0][1][3] < dom.lo[0] || e.x[0][1][3] > dom.hi[0] ||
                            e.x[1][1][3] < dom.lo[1] || e.x[1][1][3] > dom.hi[1])
                               ? 1
                               : 0;
    EXPECT_EQ(got.outside, e.end.outside + (1 - was_out) + (1 - was_out_2));
    EXPECT_TRUE(std::isnan(sets[0].x[0][17]));
}

} // namespace
