// The particle re-sort (core/src/mpm/parallel/ordering.hpp), which permutes every
// column in place by following the permutation's cycles: afterwards the
// particles are in cell order, particles of one cell keep their previous
// relative order (a stable sort), and every value of every column, of any
// width and type, is still its particle's. Each value is written as a
// function of the particle's id and the value's place in its row, so that
// a value left behind, moved twice or taken from a neighbour is seen.
#include "parallel/ordering.hpp"
#include "parallel/parallel.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <atomic>
#include <chrono>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <random>
#include <string>
#include <thread>
#include <type_traits>
#include <vector>

namespace {

using talus::GridGeometry;
using talus::Ordering;
using talus::ParticleSet;

GridGeometry geometry(int dim) {
    GridGeometry g;
    g.dim = dim;
    g.h = 0.1;
    g.inv_h = 1.0 / g.h;
    g.origin = {0.0, 0.0, 0.0};
    g.cells = {12, 9, dim == 3 ? 7 : 1};
    return g;
}

// What the column value of particle `id` at place k of its row must be.
double expected(std::int64_t id, std::size_t k) {
    return static_cast<double>(id) * 100.0 + static_cast<double>(k);
}

// A set of n particles at random places, each column filled by
// expected(id, k): ids 0..n-1 in memory order before the sort.
ParticleSet particles(const GridGeometry &g, std::size_t n, std::uint32_t state_size,
                      std::uint32_t seed) {
    std::mt19937 rng(seed);
    std::uniform_real_distribution<double> u(0.0, 1.0);
    ParticleSet s;
    s.dim = g.dim;
    s.state_size = state_size;
    s.resize(n);
    for (std::size_t p = 0; p < n; ++p) {
        s.id[p] = static_cast<std::int64_t>(p);
        s.group[p] = static_cast<std::int32_t>(p % 7);
        s.load_mask[p] = static_cast<std::uint32_t>(p % 5);
        s.fix_mask[p] = static_cast<std::uint32_t>(p % 3);
    }
    s.for_each_named_column([&](const char *name, auto &col, std::size_t stride) {
        using T = typename std::decay_t<decltype(col)>::value_type;
        if constexpr (std::is_same_v<T, double>) {
            const std::string nm = name;
            if (nm == "x" || nm == "y" || nm == "z") return; // the positions: below
            for (std::size_t p = 0; p < n; ++p)
                for (std::size_t k = 0; k < stride; ++k)
                    col[p * stride + k] = expected(static_cast<std::int64_t>(p), k);
        }
    });
    for (int d = 0; d < g.dim; ++d)
        for (std::size_t p = 0; p < n; ++p)
            s.x[static_cast<std::size_t>(d)][p] = u(rng) * g.cells[d] * g.h;
    return s;
}

void check_sorted(int dim, std::uint32_t state_size) {
    const GridGeometry g = geometry(dim);
    std::vector<ParticleSet> sets;
    // The sort counts particles per cell where the occupied span of cells
    // is at most the particle count (the first set: 3001 particles over
    // 108 or 756 cells), and falls back on a comparison sort where it is
    // not (the third: 40 particles in the grid's first and last cells).
    // The two must give the same order.
    sets.push_back(particles(g, 3001, state_size, 5));
    sets.push_back(particles(g, 64, state_size, 6));
    sets.push_back(particles(g, 40, state_size, 7));
    for (std::size_t p = 0; p < sets.back().n; ++p)
        for (int d = 0; d < dim; ++d)
            sets.back().x[static_cast<std::size_t>(d)][p] =
                p % 3 == 0 ? 0.5 * g.h : (g.cells[static_cast<std::size_t>(d)] - 0.5) * g.h;
    // Keep the positions each id had, to check them after the sort.
    std::vector<std::vector<std::vector<double>>> position(sets.size());
    for (std::size_t si = 0; si < sets.size(); ++si)
        for (int d = 0; d < dim; ++d)
            position[si].emplace_back(sets[si].x[static_cast<std::size_t>(d)].begin(),
                                      sets[si].x[static_cast<std::size_t>(d)].end());
    Ordering order(g, sets.size());
    order.sort(sets);
    for (std::size_t si = 0; si < sets.size(); ++si) {
        ParticleSet &s = sets[si];
        ASSERT_EQ(s.n, position[si][0].size());
        std::vector<bool> seen(s.n, false);
        std::size_t last_cell = 0;
        std::int64_t last_id = -1;
        for (std::size_t p = 0; p < s.n; ++p) {
            const std::int64_t id = s.id[p];
            ASSERT_GE(id, 0);
            ASSERT_LT(static_cast<std::size_t>(id), s.n);
            ASSERT_FALSE(seen[static_cast<std::size_t>(id)]) << "id " << id << " twice";
            seen[static_cast<std::size_t>(id)] = true;
            const double x[3] = {s.x[0][p], s.x[1][p], dim == 3 ? s.x[2][p] : 0.0};
            for (int d = 0; d < dim; ++d)
                ASSERT_EQ(x[d],
                          position[si][static_cast<std::size_t>(d)][static_cast<std::size_t>(id)]);
            const std::size_t cell = g.cell_index(x);
            ASSERT_GE(cell, last_cell) << "set " << si << ", particle " << p;
            if (p > 0 && cell == last_cell) {
                ASSERT_GT(id, last_id) << "not stable in cell " << cell;
            }
            last_cell = cell;
            last_id = id;
            EXPECT_EQ(s.group[p], id % 7);
            EXPECT_EQ(s.load_mask[p], static_cast<std::uint32_t>(id % 5));
            EXPECT_EQ(s.fix_mask[p], static_cast<std::uint32_t>(id % 3));
        }
        s.for_each_named_column([&](const char *name, auto &col, std::size_t stride) {
            using T = typename std::decay_t<decltype(col)>::value_type;
            if constexpr (std::is_same_v<T, double>) {
                const std::string nm = name;
                if (nm == "x" || nm == "y" || nm == "z") return;
                for (std::size_t p = 0; p < s.n; ++p)
                    for (std::size_t k = 0; k < stride; ++k)
                        ASSERT_EQ(col[p * stride + k], expected(s.id[p], k))
                            << "column " << name << ", particle " << p << ", value " << k;
            }
        });
    }
}

TEST(Ordering, SortPutsParticlesInCellOrderStablyWithEveryColumnTheirOwn2D) { check_sorted(2, 0); }

TEST(Ordering, SortPutsParticlesInCellOrderStablyWithEveryColumnTheirOwn3D) { check_sorted(3, 5); }

// Binning by slab (Ordering::prepare without a sort): each slab's list
// holds exactly the particles whose cell lies in it, in memory order, for
// a small set and a large one, with two threads, with slabs across the
// slowest axis (y) and across x (y has too few cells).
TEST(Ordering, BinsEveryParticleIntoItsSlabInMemoryOrder) {
    const int threads = talus::par::max_threads();
    for (const std::array<int, 3> cells : {std::array<int, 3>{40, 64, 1}, {64, 28, 1}})
        for (const std::size_t n : {std::size_t{5000}, std::size_t{150001}}) {
            GridGeometry g = geometry(2);
            g.cells = cells; // 16 slabs of 4 cells along y, then along x
            std::vector<ParticleSet> sets;
            sets.push_back(particles(g, n, 0, 9));
            talus::par::set_threads(2);
            Ordering order(g, sets.size());
            order.prepare(sets, 0.0);
            const ParticleSet &s = sets[0];
            std::vector<int> seen(s.n, 0);
            ASSERT_EQ(order.axis(), cells[0] == 64 ? 0 : 1);
            ASSERT_EQ(order.n_slabs(), 16);
            for (int slab = 0; slab < order.n_slabs(); ++slab) {
                const Ordering::Range r = order.slab(0, slab);
                ASSERT_GT(r.end - r.begin, 0);
                for (const std::uint32_t *k = r.begin; k != r.end; ++k) {
                    ASSERT_LT(*k, s.n);
                    if (k != r.begin) {
                        ASSERT_GT(*k, k[-1]) << "slab " << slab << " out of memory order";
                    }
                    const int cell = static_cast<int>(
                        std::floor(s.x[static_cast<std::size_t>(order.axis())][*k] * g.inv_h));
                    ASSERT_EQ(std::min(cell / 4, 15), slab) << "particle " << *k;
                    ++seen[*k];
                }
            }
            for (std::size_t p = 0; p < s.n; ++p)
                ASSERT_EQ(seen[p], 1) << "particle " << p << " binned " << seen[p] << " times";
        }
    talus::par::set_threads(threads);
}

// A checkpoint's slab marks are checked against the positions: marks of
// another axis (a build that chose slabs across x, 16 of them where this
// one makes 10 across y) are dropped and the set binned afresh, while
// marks that match are kept as they are (the restored run bins as the
// uninterrupted one does).
TEST(Ordering, RestoredMarksOfOtherSlabsAreBinnedAfresh) {
    GridGeometry g = geometry(2);
    g.cells = {64, 40, 1};
    std::vector<ParticleSet> sets;
    sets.push_back(particles(g, 20000, 0, 11));
    const ParticleSet &s = sets[0];
    std::vector<std::int32_t> across_x(s.n), across_y(s.n);
    for (std::size_t p = 0; p < s.n; ++p) {
        across_x[p] = std::min(g.cell(0, s.x[0][p]) / 4, 15);
        across_y[p] = std::min(g.cell(1, s.x[1][p]) / 4, 9);
    }
    {
        Ordering order(g, 1);
        ASSERT_EQ(order.axis(), 1);
        order.restore(sets, {across_y}, 0.0, false);
        EXPECT_TRUE(order.slabs(0) == across_y);
    }
    Ordering order(g, 1);
    order.restore(sets, {across_x}, 0.0, false);
    EXPECT_TRUE(order.slabs(0).empty());
    order.prepare(sets, 0.0);
    ASSERT_EQ(order.n_slabs(), 10);
    std::size_t seen = 0;
    for (int slab = 0; slab < order.n_slabs(); ++slab) {
        const Ordering::Range r = order.slab(0, slab);
        for (const std::uint32_t *k = r.begin; k != r.end; ++k, ++seen)
            ASSERT_EQ(across_y[*k], slab) << "particle " << *k;
    }
    EXPECT_EQ(seen, s.n);
}

// Which axis the slabs run across: the slowest-varying of the cell order
// (z, then y, then x) with at least 8 slabs of 4 cells, else the longest
// (the last on a tie).
TEST(Ordering, SlabsRunAcrossTheSlowestAxisWithEightOfThem) {
    struct Case {
        int dim;
        std::array<int, 3> cells;
        int axis, slabs;
    };
    for (const Case &c :
         {Case{2, {1000, 250, 1}, 1, 62}, Case{2, {250, 1000, 1}, 1, 250},
          Case{2, {60, 32, 1}, 1, 8}, Case{2, {60, 31, 1}, 0, 15}, Case{2, {20, 28, 1}, 1, 7},
          Case{2, {28, 28, 1}, 1, 7}, Case{3, {50, 50, 50}, 2, 12}, Case{3, {100, 50, 25}, 1, 12},
          Case{3, {100, 28, 28}, 0, 25}, Case{3, {20, 24, 20}, 1, 6}}) {
        GridGeometry g = geometry(c.dim);
        g.cells = c.cells;
        const Ordering order(g, 1);
        EXPECT_EQ(order.axis(), c.axis) << c.cells[0] << " x " << c.cells[1] << " x " << c.cells[2];
        EXPECT_EQ(order.n_slabs(), c.slabs) << c.cells[0] << " x " << c.cells[1];
    }
}

// The slabs' schedule (par::for_each_slab_by_colour, P2G's loop): every
// slab once, and an odd slab only after both its even neighbours have
// finished (it writes nodes they write), with two threads and no barrier
// between the colours. Each even slab but the last sleeps, the later ones
// longer, so that without the wait a thread would start an odd slab while
// a neighbour is still running (the test fails with the wait removed).
// Also a slab count of 1 and 2 (no odd slab with a right neighbour).
TEST(Ordering, AnOddSlabStartsOnlyAfterBothEvenNeighboursFinish) {
    const int threads = talus::par::max_threads();
    talus::par::set_threads(2);
    for (const int n : {1, 2, 3, 7, 13}) {
        SCOPED_TRACE("slabs: " + std::to_string(n));
        std::atomic<int> clock{0};
        std::vector<int> start(static_cast<std::size_t>(n), -1),
            end(static_cast<std::size_t>(n), -1);
        std::vector<std::atomic<int>> runs(static_cast<std::size_t>(n));
        talus::par::for_each_slab_by_colour(n, [&](int slab) {
            const std::size_t i = static_cast<std::size_t>(slab);
            ++runs[i];
            start[i] = clock++;
            if (slab % 2 == 0 && slab + 1 < n)
                std::this_thread::sleep_for(std::chrono::milliseconds(5 + 5 * slab));
            end[i] = clock++;
        });
        for (int slab = 0; slab < n; ++slab) {
            const std::size_t i = static_cast<std::size_t>(slab);
            EXPECT_EQ(runs[i].load(), 1) << "slab " << slab;
            if (slab % 2 == 0) continue;
            EXPECT_GT(start[i], end[i - 1]) << "odd slab " << slab << " before its left neighbour";
            if (slab + 1 < n) {
                EXPECT_GT(start[i], end[i + 1])
                    << "odd slab " << slab << " before its right neighbour";
            }
        }
    }
    talus::par::set_threads(threads);
}

// The decay that triggers a re-sort counts descents by more than far()
// cells: two rows (2D) or planes (3D) of the cell order, however large.
TEST(Ordering, FarIsTwoRowsOrPlanesOfTheCellOrder) {
    EXPECT_EQ(Ordering(geometry(2), 1).far(), 2u * 12u);
    EXPECT_EQ(Ordering(geometry(3), 1).far(), 2u * 12u * 9u);
    GridGeometry wide = geometry(3);
    wide.cells = {300, 200, 10};
    EXPECT_EQ(Ordering(wide, 1).far(), 2u * 300u * 200u);
    EXPECT_TRUE(Ordering::far_below(0, 25, 24));
    EXPECT_FALSE(Ordering::far_below(1, 25, 24));
    EXPECT_FALSE(Ordering::far_below(30, 25, 24));
    // No wrap-around near the largest cell index: cell + far past 2^32
    // would come out small in 32 bits and count as far below.
    EXPECT_FALSE(Ordering::far_below(0xfffffff0u, 0xffffffffu, 24));
    EXPECT_TRUE(Ordering::far_below(0xfffffff0u - 25, 0xffffffffu, 24));
}

} // namespace
