// The cells split among ranks (decomposition.hpp) and the nodes they share
// (halo.hpp), checked against their definitions without MPI: the boxes
// tile the domain, each holds its share of the weight, the owner of every
// cell and node is the box holding it, and the shared-node lists of two
// ranks name the same nodes in the same order.
#include "ranks/decomposition.hpp"
#include "ranks/halo.hpp"
#include "state/grid.hpp"

#include <talus/error.hpp>

#include <gtest/gtest.h>

#include <numeric>
#include <random>

namespace {

using talus::CellBox;
using talus::Decomposition;

// Weights of a particle cloud given per cell (cells in x-fastest order).
struct Cloud {
    std::array<int, 3> cells;
    std::vector<double> w;
    double at(int i, int j, int k) const {
        return w[static_cast<std::size_t>(i + cells[0] * (j + cells[1] * k))];
    }
    Decomposition::Histogram histogram() const {
        return [this](const CellBox &b, int axis) {
            const std::size_t a = static_cast<std::size_t>(axis);
            std::vector<double> h(static_cast<std::size_t>(b.hi[a] - b.lo[a]), 0.0);
            for (int k = b.lo[2]; k < b.hi[2]; ++k)
                for (int j = b.lo[1]; j < b.hi[1]; ++j)
                    for (int i = b.lo[0]; i < b.hi[0]; ++i) {
                        const int c[3] = {i, j, k};
                        h[static_cast<std::size_t>(c[a] - b.lo[a])] += at(i, j, k);
                    }
            return h;
        };
    }
    double weight(const CellBox &b) const {
        double s = 0.0;
        for (int k = b.lo[2]; k < b.hi[2]; ++k)
            for (int j = b.lo[1]; j < b.hi[1]; ++j)
                for (int i = b.lo[0]; i < b.hi[0]; ++i)
                    s += at(i, j, k);
        return s;
    }
};

Cloud uniform(std::array<int, 3> cells) {
    return {cells,
            std::vector<double>(static_cast<std::size_t>(cells[0] * cells[1] * cells[2]), 8.0)};
}

// A column in one corner, as a collapse starts.
Cloud corner(std::array<int, 3> cells) {
    Cloud c = uniform(cells);
    for (int k = 0; k < cells[2]; ++k)
        for (int j = 0; j < cells[1]; ++j)
            for (int i = 0; i < cells[0]; ++i)
                c.w[static_cast<std::size_t>(i + cells[0] * (j + cells[1] * k))] =
                    i < cells[0] / 5 ? 8.0 : 0.0;
    return c;
}

void expect_tiling(const Decomposition &d) {
    const auto &n = d.cells();
    for (int k = 0; k < n[2]; ++k)
        for (int j = 0; j < n[1]; ++j)
            for (int i = 0; i < n[0]; ++i) {
                int holders = 0, holder = -1;
                for (int r = 0; r < d.ranks(); ++r)
                    if (d.box(r).contains({i, j, k})) {
                        ++holders;
                        holder = r;
                    }
                ASSERT_EQ(holders, 1) << "cell " << i << " " << j << " " << k;
                ASSERT_EQ(d.owner({i, j, k}), holder);
            }
    for (int r = 0; r < d.ranks(); ++r)
        EXPECT_GT(d.box(r).cells(), 0) << "rank " << r;
}

} // namespace

TEST(Decomposition, TheBoxesTileTheDomainAndOwnTheirCells) {
    for (int ranks : {1, 2, 3, 4, 5, 7, 8}) {
        SCOPED_TRACE(ranks);
        for (const Cloud &c :
             {uniform({40, 12, 1}), corner({40, 12, 1}), uniform({10, 9, 8}), corner({16, 6, 9})}) {
            const int dim = c.cells[2] > 1 ? 3 : 2;
            expect_tiling(Decomposition::bisect(dim, c.cells, ranks, c.histogram()));
        }
    }
}

// Each cut sends the weight in proportion to the ranks on either side, to
// within a cell plane: with planes of at most P weight, every rank's share
// is within ranks' depth of cuts x P of the mean.
TEST(Decomposition, EachRankGetsItsShareOfTheWeight) {
    std::mt19937 rng(5);
    std::uniform_real_distribution<double> u(0.0, 1.0);
    Cloud c = uniform({64, 48, 1});
    for (double &w : c.w)
        w = u(rng) < 0.7 ? 4.0 : 0.0;
    const double total = std::accumulate(c.w.begin(), c.w.end(), 0.0);
    for (int ranks : {2, 3, 4, 6, 8}) {
        SCOPED_TRACE(ranks);
        const Decomposition d = Decomposition::bisect(2, c.cells, ranks, c.histogram());
        const double mean = total / ranks;
        for (int r = 0; r < ranks; ++r) {
            const CellBox &b = d.box(r);
            // The heaviest plane a cut can leave on the wrong side: 64 cells x 4.
            const double plane = 4.0 * 64;
            EXPECT_NEAR(c.weight(b), mean, 3 * plane) << "rank " << r;
        }
    }
}

TEST(Decomposition, ACornerColumnIsSharedByWeightNotVolume) {
    const Cloud c = corner({40, 12, 1});
    const Decomposition d = Decomposition::bisect(2, c.cells, 2, c.histogram());
    // The weight is in x < 8: the cut falls there, not at x = 20.
    EXPECT_EQ(d.box(0).hi[0], 4);
    EXPECT_EQ(c.weight(d.box(0)), c.weight(d.box(1)));
}

// A checkpoint stores the boxes only: the decomposition found again from
// them owns every cell as the bisection did; boxes that do not tile the
// grid (a damaged file) are refused.
TEST(Decomposition, TheBoxesAloneGiveTheSameOwners) {
    for (int ranks : {2, 3, 5, 8}) {
        SCOPED_TRACE(ranks);
        for (const Cloud &c : {corner({40, 12, 1}), uniform({10, 9, 8}), corner({16, 6, 9})}) {
            const int dim = c.cells[2] > 1 ? 3 : 2;
            const Decomposition d = Decomposition::bisect(dim, c.cells, ranks, c.histogram());
            std::vector<CellBox> boxes;
            for (int r = 0; r < ranks; ++r)
                boxes.push_back(d.box(r));
            const Decomposition e = Decomposition::from_boxes(dim, c.cells, boxes);
            expect_tiling(e);
            for (int k = 0; k < c.cells[2]; ++k)
                for (int j = 0; j < c.cells[1]; ++j)
                    for (int i = 0; i < c.cells[0]; ++i)
                        ASSERT_EQ(e.owner({i, j, k}), d.owner({i, j, k}));
            for (int r = 0; r < ranks; ++r)
                EXPECT_EQ(e.neighbours(r, talus::kGhostLayers),
                          d.neighbours(r, talus::kGhostLayers));
        }
    }
    const Cloud c = uniform({8, 4, 1});
    const CellBox left{{0, 0, 0}, {4, 4, 1}}, right{{4, 0, 0}, {8, 4, 1}};
    EXPECT_NO_THROW(Decomposition::from_boxes(2, c.cells, {left, right}));
    // A gap, an overlap, a box past the grid.
    EXPECT_THROW(Decomposition::from_boxes(2, c.cells, {left, CellBox{{5, 0, 0}, {8, 4, 1}}}),
                 talus::Error);
    EXPECT_THROW(Decomposition::from_boxes(2, c.cells, {left, CellBox{{3, 0, 0}, {8, 4, 1}}}),
                 talus::Error);
    EXPECT_THROW(Decomposition::from_boxes(2, c.cells, {left, CellBox{{4, 0, 0}, {9, 4, 1}}}),
                 talus::Error);
}

TEST(Decomposition, MoreRanksThanCellsIsRefused) {
    const Cloud c = uniform({2, 2, 1});
    EXPECT_THROW(Decomposition::bisect(2, c.cells, 5, c.histogram()), talus::Error);
    EXPECT_NO_THROW(Decomposition::bisect(2, c.cells, 4, c.histogram()));
}

// Every node has one owner, the rank whose box begins it; the neighbour
// relation is symmetric; and for two neighbours the overlap of their held
// nodes is exactly the nodes both hold.
TEST(Decomposition, NodesHaveOneOwnerAndNeighboursAreMutual) {
    const Cloud c = uniform({10, 9, 8});
    const Decomposition d = Decomposition::bisect(3, c.cells, 6, c.histogram());
    const int g = talus::kGhostLayers;
    for (int r = 0; r < d.ranks(); ++r)
        for (int q : d.neighbours(r, g)) {
            const auto back = d.neighbours(q, g);
            EXPECT_TRUE(std::find(back.begin(), back.end(), r) != back.end()) << r << " " << q;
        }
    for (int k = -g; k <= 8 + g; ++k)
        for (int j = -g; j <= 9 + g; ++j)
            for (int i = -g; i <= 10 + g; ++i) {
                const int o = d.node_owner({i, j, k});
                const talus::NodeBox held = d.nodes(o, g);
                EXPECT_TRUE(i >= held.lo[0] && i <= held.hi[0] && j >= held.lo[1] &&
                            j <= held.hi[1] && k >= held.lo[2] && k <= held.hi[2])
                    << "node " << i << " " << j << " " << k << " not held by its owner " << o;
            }
}

// Two ranks' halos list their shared nodes in the same global order, so
// that a message's values land on the same nodes; and the nodes listed are
// exactly those both hold.
TEST(Halo, NeighboursListTheSharedNodesInTheSameOrder) {
    for (int dim : {2, 3}) {
        SCOPED_TRACE(dim);
        const Cloud c = dim == 2 ? uniform({12, 10, 1}) : uniform({8, 7, 6});
        const int ranks = 5;
        const Decomposition d = Decomposition::bisect(dim, c.cells, ranks, c.histogram());
        const int g = talus::kGhostLayers;
        std::vector<talus::Grid> grids;
        std::vector<talus::Halo> halos;
        for (int r = 0; r < ranks; ++r) {
            const std::array<double, 3> size{0.1 * c.cells[0], 0.1 * c.cells[1],
                                             dim == 3 ? 0.1 * c.cells[2] : 0.0};
            grids.emplace_back(dim, std::array<double, 3>{0, 0, 0}, size, 0.1,
                               talus::ShapeKind::bspline2, d.box(r).lo, d.box(r).hi);
        }
        for (int r = 0; r < ranks; ++r)
            halos.emplace_back(d, r, grids[static_cast<std::size_t>(r)].geo, g);
        auto globals = [&](int r, std::size_t k) {
            std::vector<std::array<int, 3>> out;
            for (std::uint32_t s : halos[static_cast<std::size_t>(r)].slots(k))
                out.push_back(grids[static_cast<std::size_t>(r)].geo.global(s));
            return out;
        };
        for (int r = 0; r < ranks; ++r) {
            const auto &peers = halos[static_cast<std::size_t>(r)].neighbours();
            EXPECT_EQ(peers, d.neighbours(r, g));
            for (std::size_t k = 0; k < peers.size(); ++k) {
                const int q = peers[k];
                const auto &back = halos[static_cast<std::size_t>(q)].neighbours();
                const std::size_t kq =
                    static_cast<std::size_t>(std::find(back.begin(), back.end(), r) - back.begin());
                ASSERT_LT(kq, back.size());
                const auto mine = globals(r, k);
                EXPECT_EQ(mine, globals(q, kq)) << "ranks " << r << " and " << q;
                // Exactly the nodes both hold.
                const talus::NodeBox both = talus::intersect(d.nodes(r, g), d.nodes(q, g));
                std::size_t count = 1;
                for (std::size_t a = 0; a < 3; ++a)
                    count *= static_cast<std::size_t>(both.hi[a] - both.lo[a] + 1);
                EXPECT_EQ(mine.size(), count);
            }
        }
    }
}
