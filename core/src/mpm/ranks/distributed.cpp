// A Simulation on several ranks (docs/mpi.md): its set-up from the
// generated particles, and what the step adds to the serial cycle: the
// shared nodes' sums after each P2G, the particles' migration after the
// step's end, and agreement on a failure.
#include "simulation_state.hpp"

#include "ranks/migration.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <numeric>

namespace talus {

namespace {

// The particles of `sets` per cell plane of `box` across `axis`, summed
// over the ranks (the bisection's weights; collective).
std::vector<double> plane_counts(const Comm &comm, const std::vector<ParticleSet> &sets,
                                 const GridGeometry &geo, const CellBox &box, int axis) {
    const std::size_t a = static_cast<std::size_t>(axis);
    std::vector<double> w(static_cast<std::size_t>(box.hi[a] - box.lo[a]), 0.0);
    for (const ParticleSet &s : sets)
        for (std::size_t p = 0; p < s.n; ++p) {
            const std::array<int, 3> c = particle_cell(geo, s, p);
            if (box.contains(c)) w[static_cast<std::size_t>(c[a] - box.lo[a])] += 1.0;
        }
    comm.sum(w.data(), w.size());
    return w;
}

// Puts points [begin, s.n) of `s` in ascending id order.
void sort_by_id(ParticleSet &s, std::size_t begin) {
    std::vector<std::uint32_t> from(s.n);
    std::iota(from.begin(), from.end(), 0u);
    std::sort(from.begin() + static_cast<std::ptrdiff_t>(begin), from.end(),
              [&](std::uint32_t a, std::uint32_t b) { return s.id[a] < s.id[b]; });
    s.permute(from);
}

} // namespace

void Simulation::Impl::distribute() {
    // Each rank holds a share of the particles (its rows of each group's
    // lattice, or its part of a snapshot's): the cells are split by the
    // counts summed over the ranks, and the particles go to their cells'
    // ranks.
    std::size_t held = 0;
    for (const ParticleSet &s : sets)
        held += s.n;
    traffic.largest_share = std::max(traffic.largest_share, held);
    const GridGeometry &geo = grid.geo;
    auto weight = [&](const CellBox &box, int axis) {
        return plane_counts(comm, sets, geo, box, axis);
    };
    try { // the same weights on every rank: the same outcome
        decomp = Decomposition::bisect(sc.dim, geo.cells, comm.size(), weight);
    } catch (const Error &e) {
        fail_together(comm, e.what());
    }
    talus::migrate(comm, decomp, decomp.neighbours(comm.rank(), kGhostLayers), geo, sets);
    take_box();
    // In id order (generation order), however the particles were shared.
    for (ParticleSet &s : sets)
        sort_by_id(s, 0);
}

void Simulation::Impl::arrive(std::size_t set, std::size_t begin) {
    traffic.largest_share = std::max(traffic.largest_share, sets[set].n - begin);
    talus::migrate(comm, decomp, halo.neighbours(), grid.geo, sets);
    order.invalidate(); // indices moved
    sort_by_id(sets[set], begin);
}

void Simulation::Impl::take_box() {
    const CellBox &mine = decomp.box(comm.rank());
    grid = Grid(sc.dim, sc.origin, sc.size, sc.cell, sc.solver.shape, mine.lo, mine.hi);
    boundary = Boundary(sc, conditions(), grid, stage_start, comm);
    order = Ordering(grid.geo, sets.size());
    halo = Halo(decomp, comm.rank(), grid.geo, kGhostLayers);
    if (sc.solver.cell_averaged_dilation) { // sized for this rank's cells
        dilation.div.assign(grid.n_cells, 0.0);
        dilation.vol.assign(grid.n_cells, 0.0);
    }
    traffic.shared_nodes = halo.shared_nodes();
    traffic.neighbours = static_cast<int>(halo.neighbours().size());
}

void Simulation::Impl::rebalance_if_uneven() {
    if ((step + 1) % sc.solver.rebalance_every != 0) return;
    auto tm = timer(Phase::migration);
    long n = 0;
    for (const ParticleSet &s : sets)
        n += static_cast<long>(s.n);
    const double most = comm.max(static_cast<double>(n));
    const double mean = static_cast<double>(comm.sum(n)) / comm.size();
    if (!(most > sc.solver.rebalance_imbalance * mean)) return;
    // Each rank counts its own particles per plane; the sum is global.
    const GridGeometry &geo = grid.geo;
    auto weight = [&](const CellBox &box, int axis) {
        return plane_counts(comm, sets, geo, box, axis);
    };
    Decomposition next = Decomposition::bisect(sc.dim, geo.cells, comm.size(), weight);
    bool same = true;
    for (int r = 0; r < comm.size(); ++r)
        same = same && next.box(r) == decomp.box(r);
    if (same) return;
    decomp = std::move(next);
    const Migration m =
        talus::migrate(comm, decomp, decomp.neighbours(comm.rank(), kGhostLayers), grid.geo, sets);
    traffic.migrated += m.sent;
    traffic.migration_bytes += m.bytes_sent;
    take_box();
    ++traffic.rebalances;
}

void Simulation::Impl::exchange(unsigned fields) {
    auto tm = timer(Phase::halo_exchange);
    traffic.halo_bytes += halo.sum(comm, grid.acc.data(), fields);
}

void Simulation::Impl::migrate() {
    auto tm = timer(Phase::migration);
    const Migration m = talus::migrate(comm, decomp, halo.neighbours(), grid.geo, sets);
    traffic.migrated += m.sent;
    traffic.migration_bytes += m.bytes_sent;
    if (m.sent > 0 || m.received > 0) order.invalidate(); // indices moved
}

void Simulation::Impl::agree(std::exception_ptr error) const { comm.agree(error); }

} // namespace talus
