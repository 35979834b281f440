// The background grid: a Cartesian lattice of spacing h from `origin`, of
// which this process holds a local index box (ghost layers included). Nodes
// are numbered globally from the domain's first node (0 at the origin,
// negative in the ghost layers below it); a kernel turns a global node
// number into a slot of the local records through the box (first, extent;
// Stencil::combine), never assuming the box starts at the domain: an MPI
// rank will hold only its own part.
#pragma once

#include <talus/mpm/shape_functions.hpp>

#include "parallel/parallel.hpp"

#include <algorithm>
#include <array>
#include <cstddef>
#include <cstdint>
#include <new>
#include <vector>

namespace talus {

// Fields of a node record: 8 doubles (one cache line), so that a particle's
// scatter touches one line per node, not one per field.
namespace node {
inline constexpr std::size_t kRecord = 8;
// The P2G accumulators (Grid::acc): mass, momentum, force, and in [7] bit k
// set when a particle of particle_velocities[k] reaches the node (exact in
// a double: 32 bits).
inline constexpr std::size_t kMass = 0, kMomentum = 1, kForce = 4, kFixity = 7;
// The velocities (Grid::vel): v~ at the end of the step first, then v at
// its start. The G2P's gradient and offset sums read v~ alone: a record's
// first half (half records, stencil.hpp); in 2D both fit that half, and
// the 2D G2P reads nothing else.
inline constexpr std::size_t kEndVelocity = 0;
constexpr std::size_t velocity(int dim) { return dim == 2 ? 2 : 4; }
// A slot no kernel reads (3D: v~ 0-2, v 4-6; 2D: 0-3): where a grid
// update that clears the accumulators leaves the node's mass
// (Grid::accumulators_cleared).
inline constexpr std::size_t kMassCopy = 7;
} // namespace node

// What a kernel needs to find a particle's nodes: plain values, copied
// into the kernel's registers.
struct GridGeometry {
    int dim = 2;
    double h = 1.0, inv_h = 1.0;
    std::array<double, 3> origin{0, 0, 0};
    // Cells of the whole domain per axis: where the clamped kernels' faces are.
    std::array<int, 3> cells{1, 1, 1};
    // The local box: its first global node per axis and nodes per axis.
    std::array<int, 3> first{0, 0, 0}, extent{1, 1, 1};
    // D_p^-1 of APIC away from the faces for the B-splines, 1/m^2 (0 for
    // the tent-based kernels, whose affine matrix is the gradient).
    double affine_dinv = 0.0;

    // Global node numbers (i, j, k) of a local slot.
    std::array<int, 3> global(std::size_t slot) const;
    // Cell of a coordinate along axis d, clamped into the domain. Inline:
    // called per particle and axis at the end of every step.
    int cell(int d, double x) const {
        const std::size_t dd = static_cast<std::size_t>(d);
        return clamped_cell((x - origin[dd]) * inv_h, cells[dd]);
    }
    // floor(xi) clamped into [0, n): a coordinate far outside the domain, or
    // NaN (a run blowing up, which the step's leaving check reports next),
    // is clamped before any conversion to int, which would be undefined.
    static int clamped_cell(double xi, int n) {
        if (!(xi >= 0.0)) return 0;
        if (xi >= n - 1) return n - 1;
        return static_cast<int>(xi); // truncation is floor for xi >= 0
    }
    // Cell number (in the domain's cell order) of a position.
    std::size_t cell_index(const double *x) const;
    // Cells this grid's rank owns along axis d (its box; the domain's on
    // one rank): the held nodes but the ghost layers and the far face.
    int owned_cells(int d) const {
        return extent[static_cast<std::size_t>(d)] - 1 - 2 * kGhostLayers;
    }
    // Cell number among the cells this grid's rank owns (its box, in the
    // same order), clamped into the box.
    std::size_t owned_cell_index(const double *x) const;
};

// Storage for node records starting on a cache-line boundary: a record of
// 8 doubles is then one line, not two (the heap's large blocks start 16
// bytes into a page).
template <class T>
struct CacheLineAllocator {
    using value_type = T;
    static constexpr std::align_val_t kAlign{64};
    CacheLineAllocator() = default;
    template <class U>
    CacheLineAllocator(const CacheLineAllocator<U> &) {}
    T *allocate(std::size_t n) { return static_cast<T *>(::operator new(n * sizeof(T), kAlign)); }
    void deallocate(T *p, std::size_t) { ::operator delete(p, kAlign); }
    friend bool operator==(const CacheLineAllocator &, const CacheLineAllocator &) { return true; }
};
using NodeRecords = std::vector<double, CacheLineAllocator<double>>;

// A box of local node slots, [lo, hi) per axis, walked as rows: runs of
// consecutive slots along axis 0 (slot = i + e0 (j + e1 k) for the
// grid's extent e).
struct SlotBox {
    std::array<int, 3> lo{0, 0, 0}, hi{0, 0, 0};
    bool empty() const { return hi[0] <= lo[0] || hi[1] <= lo[1] || hi[2] <= lo[2]; }
    std::size_t nodes() const { return empty() ? 0 : rows() * row_length(); }
    std::size_t rows() const {
        return empty() ? 0
                       : static_cast<std::size_t>(hi[1] - lo[1]) *
                             static_cast<std::size_t>(hi[2] - lo[2]);
    }
    std::size_t row_length() const { return static_cast<std::size_t>(hi[0] - lo[0]); }
    bool contains(const std::array<int, 3> &ijk) const {
        return ijk[0] >= lo[0] && ijk[0] < hi[0] && ijk[1] >= lo[1] && ijk[1] < hi[1] &&
               ijk[2] >= lo[2] && ijk[2] < hi[2];
    }
    SlotBox cut(const SlotBox &o) const {
        SlotBox b;
        for (std::size_t d = 0; d < 3; ++d) {
            b.lo[d] = std::max(lo[d], o.lo[d]);
            b.hi[d] = std::max(b.lo[d], std::min(hi[d], o.hi[d]));
        }
        return b;
    }
    // Row r (r < rows()) as a box of one row.
    SlotBox row(std::size_t r) const {
        const int n1 = hi[1] - lo[1];
        SlotBox b = *this;
        b.lo[1] = lo[1] + static_cast<int>(r) % n1;
        b.lo[2] = lo[2] + static_cast<int>(r) / n1;
        b.hi[1] = b.lo[1] + 1;
        b.hi[2] = b.lo[2] + 1;
        return b;
    }
    // The first slot of row r (r < rows()) of a grid of `extent` nodes.
    std::size_t row_begin(std::size_t r, const std::array<int, 3> &extent) const {
        const SlotBox b = row(r);
        const auto at = [&](std::size_t d) { return static_cast<std::size_t>(b.lo[d]); };
        return at(0) + static_cast<std::size_t>(extent[0]) *
                           (at(1) + static_cast<std::size_t>(extent[1]) * at(2));
    }
    // f(slot) for the slots of row r, ascending.
    template <class F>
    void for_each_in_row(std::size_t r, const std::array<int, 3> &extent, F &&f) const {
        const std::size_t first = row_begin(r, extent);
        for (std::size_t i = first; i < first + row_length(); ++i)
            f(i);
    }
    // f(slot) for every slot of the box, ascending.
    template <class F>
    void for_each_slot(const std::array<int, 3> &extent, F &&f) const {
        for (std::size_t r = 0; r < rows(); ++r)
            for_each_in_row(r, extent, f);
    }
};

struct Grid {
    GridGeometry geo;
    std::size_t n_nodes = 0; // held: the owned cells' nodes and the ghost layers
    std::size_t n_cells = 0; // owned (owned_cell_index)
    NodeRecords acc, vel;    // node records, see node::
    // The nodes on or beyond each face (x-, x+, y-, y+, z-, z+) that carry
    // the face's condition (face_layer of the kernel): a box of slots each
    // (empty where this rank holds none).
    std::array<SlotBox, 6> face_nodes;

    // The domain [origin, origin + cells h] with kGhostLayers around it; on
    // one of several ranks, the nodes of its cells [box_lo, box_hi) with
    // kGhostLayers around them (Decomposition::nodes).
    Grid(int dim, const std::array<double, 3> &origin, const std::array<double, 3> &size, double h,
         ShapeKind shape);
    Grid(int dim, const std::array<double, 3> &origin, const std::array<double, 3> &size, double h,
         ShapeKind shape, const std::array<int, 3> &box_lo, const std::array<int, 3> &box_hi);
    // The nodes the step's particles reach, for a step whose particles lie
    // in the global cells lo..hi per axis (inclusive; their cells clamped
    // into the domain, as GridGeometry::cell): a box every kernel's stencil
    // from those cells stays in, cut to the held nodes. A particle in cell
    // c reaches nodes c - 1 .. c + 2 at most (shape_functions.hpp: the
    // quadratic and cubic B-splines and GIMP; the tents c .. c + 1); one
    // on the domain's far face (xi = n, whose clamped cell is n - 1) up to
    // c + 3 with the cubic B-spline. kGhostLayers (2) nodes either side of
    // the cell's own two, c - 2 .. c + 3, cover both. An empty range (lo >
    // hi: no particles) reaches no node.
    SlotBox reach(const std::array<int, 3> &cell_lo, const std::array<int, 3> &cell_hi) const;
    // Every held node.
    SlotBox all() const;
    // Clears the P2G accumulators for a step whose particles reach
    // `active`: where the last step's did (every node before the first
    // step), unless its grid update cleared them already
    // (accumulators_cleared), so that they are zero everywhere. The step's kernels then work
    // within the active box alone (active()): the P2G sums land there, the
    // grid update writes the velocities there and nowhere else. Outside it
    // Grid::vel is left as it was and is not read (a particle reads only the
    // nodes of its stencil).
    void reset(const SlotBox &active);
    void reset() { reset(all()); }
    // Told by a grid update that used the accumulators last in its step
    // and cleared them in the active box while it read them, leaving each
    // node's mass in vel[node::kMassCopy]: the next reset has nothing left
    // to clear.
    void accumulators_cleared() {
        written_ = SlotBox{};
        mass_copied_ = true;
    }
    const SlotBox &active() const { return active_; }
    // f(slot) for every node of the active box, its rows in parallel (the
    // grid update, the fixities' grid side).
    template <class F>
    void for_each_active_node(F &&f) const {
        const SlotBox &b = active_;
        par::for_each(b.rows(), [&](std::size_t r) { b.for_each_in_row(r, geo.extent, f); });
    }
    // Local (i, j, k) of a slot.
    std::array<int, 3> local(std::size_t slot) const {
        const std::size_t ex = static_cast<std::size_t>(geo.extent[0]);
        const std::size_t ey = static_cast<std::size_t>(geo.extent[1]);
        return {static_cast<int>(slot % ex), static_cast<int>((slot / ex) % ey),
                static_cast<int>(slot / (ex * ey))};
    }
    // Clears the momentum slots alone (before MUSL's remap), in the active box.
    void clear_momentum();
    // A node's mass from the last P2G: in the accumulators, or where the
    // grid update copied it before clearing them.
    double node_mass(std::size_t slot) const {
        const double m = acc[node::kRecord * slot + node::kMass];
        return mass_copied_ && active_.contains(local(slot))
                   ? m + vel[node::kRecord * slot + node::kMassCopy]
                   : m;
    }
    // Total nodal mass, summed over every node (any accumulator left
    // non-zero outside the active box shows in it).
    double mass() const;
    // Position of a node's Greville point, the point it stands for (the
    // clamped B-splines' nodes near a face sit between lattice points).
    std::array<double, 3> node_point(std::size_t slot, ShapeKind shape) const;

  private:
    // The nodes the current step's particles reach, and those the P2G
    // accumulators may be non-zero in (the last active box; every node
    // until the first reset).
    SlotBox active_, written_;
    bool mass_copied_ = false;
};

} // namespace talus
