#include "state/grid.hpp"

#include "parallel/parallel.hpp"

#include <algorithm>
#include <cmath>

namespace talus {

std::array<int, 3> GridGeometry::global(std::size_t slot) const {
    const std::size_t ex = static_cast<std::size_t>(extent[0]);
    const std::size_t ey = static_cast<std::size_t>(extent[1]);
    return {static_cast<int>(slot % ex) + first[0], static_cast<int>((slot / ex) % ey) + first[1],
            static_cast<int>(slot / (ex * ey)) + first[2]};
}

std::size_t GridGeometry::cell_index(const double *x) const {
    std::size_t idx = 0, stride = 1;
    for (int d = 0; d < dim; ++d) {
        idx += static_cast<std::size_t>(cell(d, x[d])) * stride;
        stride *= static_cast<std::size_t>(cells[static_cast<std::size_t>(d)]);
    }
    return idx;
}

std::size_t GridGeometry::owned_cell_index(const double *x) const {
    std::size_t idx = 0, stride = 1;
    for (int d = 0; d < dim; ++d) {
        const std::size_t a = static_cast<std::size_t>(d);
        const int lo = first[a] + kGhostLayers, n = owned_cells(d);
        idx += static_cast<std::size_t>(std::clamp(cell(d, x[d]) - lo, 0, n - 1)) * stride;
        stride *= static_cast<std::size_t>(n);
    }
    return idx;
}

Grid::Grid(int dim, const std::array<double, 3> &origin, const std::array<double, 3> &size,
           double h, ShapeKind shape)
    : Grid(dim, origin, size, h, shape, {0, 0, 0}, {-1, -1, -1}) {}

Grid::Grid(int dim, const std::array<double, 3> &origin, const std::array<double, 3> &size,
           double h, ShapeKind shape, const std::array<int, 3> &box_lo,
           const std::array<int, 3> &box_hi) {
    geo.dim = dim;
    geo.h = h;
    geo.inv_h = 1.0 / h;
    geo.origin = origin;
    n_nodes = 1;
    n_cells = 1;
    for (std::size_t d = 0; d < 3; ++d) {
        if (static_cast<int>(d) < dim) {
            geo.cells[d] = static_cast<int>(std::lround(size[d] / h));
            // box_hi < box_lo: the whole domain.
            const int lo = box_hi[d] < box_lo[d] ? 0 : box_lo[d];
            const int hi = box_hi[d] < box_lo[d] ? geo.cells[d] : box_hi[d];
            geo.first[d] = lo - kGhostLayers;
            geo.extent[d] = hi - lo + 1 + 2 * kGhostLayers;
        } else {
            geo.cells[d] = 1;
            geo.first[d] = 0;
            geo.extent[d] = 1;
        }
        n_nodes *= static_cast<std::size_t>(geo.extent[d]);
        if (static_cast<int>(d) < dim)
            n_cells *= static_cast<std::size_t>(geo.owned_cells(static_cast<int>(d)));
    }
    acc.assign(node::kRecord * n_nodes, 0.0);
    vel.assign(node::kRecord * n_nodes, 0.0);
    active_ = written_ = all();
    // Sum over the stencil of w (x_i - x_p)(x_i - x_p)^T is h^2/4 I for the
    // quadratic and h^2/3 I for the cubic B-spline (Jiang et al. 2015).
    if (shape == ShapeKind::bspline2) geo.affine_dinv = 4.0 / (h * h);
    if (shape == ShapeKind::bspline3) geo.affine_dinv = 3.0 / (h * h);
    // The nodes whose functions are non-zero at a face, and those beyond,
    // carry that face's condition: for the clamped B-splines the layer just
    // outside the face (the node on the face has a function vanishing there
    // and stays free), for the tent-based kernels the face node and beyond.
    const int layer = face_layer(shape);
    for (std::size_t d = 0; d < static_cast<std::size_t>(dim); ++d) {
        // Global node numbers <= -layer, and >= cells + layer.
        const int e = geo.extent[d];
        SlotBox below = all(), above = all();
        below.hi[d] = std::clamp(-layer - geo.first[d] + 1, 0, e);
        above.lo[d] = std::clamp(geo.cells[d] + layer - geo.first[d], 0, e);
        face_nodes[2 * d] = below;
        face_nodes[2 * d + 1] = above;
    }
    for (SlotBox &f : face_nodes)
        if (f.empty()) f = SlotBox{};
}

SlotBox Grid::reach(const std::array<int, 3> &cell_lo, const std::array<int, 3> &cell_hi) const {
    SlotBox b;
    for (std::size_t d = 0; d < 3; ++d) {
        if (static_cast<int>(d) >= geo.dim) {
            b.hi[d] = 1;
            continue;
        }
        // In 64 bits: an empty range comes as INT_MAX .. INT_MIN.
        const long lo = long{cell_lo[d]} - kGhostLayers - geo.first[d];
        const long hi = long{cell_hi[d]} + 1 + kGhostLayers + 1 - geo.first[d];
        b.lo[d] = static_cast<int>(std::clamp(lo, 0L, long{geo.extent[d]}));
        b.hi[d] = static_cast<int>(std::clamp(hi, long{b.lo[d]}, long{geo.extent[d]}));
    }
    return b;
}

SlotBox Grid::all() const {
    SlotBox b;
    b.hi = geo.extent;
    return b;
}

void Grid::reset(const SlotBox &active) {
    // Parallel, row by row: on a large grid this is tens of megabytes
    // every step.
    const SlotBox w = written_;
    const std::size_t len = node::kRecord * w.row_length();
    // Nothing to clear after a grid update that cleared them: no parallel
    // region either (a barrier less a step).
    if (!w.empty())
        par::for_each(w.rows(), [&](std::size_t r) {
            std::fill_n(acc.begin() +
                            static_cast<std::ptrdiff_t>(node::kRecord * w.row_begin(r, geo.extent)),
                        len, 0.0);
        });
    active_ = written_ = active;
    mass_copied_ = false;
}

void Grid::clear_momentum() {
    active_.for_each_slot(geo.extent, [&](std::size_t i) {
        for (std::size_t d = 0; d < static_cast<std::size_t>(geo.dim); ++d)
            acc[node::kRecord * i + node::kMomentum + d] = 0.0;
    });
}

double Grid::mass() const {
    double m = 0.0;
    for (std::size_t i = 0; i < n_nodes; ++i)
        m += node_mass(i);
    return m;
}

std::array<double, 3> Grid::node_point(std::size_t slot, ShapeKind shape) const {
    const std::array<int, 3> ijk = geo.global(slot);
    std::array<double, 3> x{0, 0, 0};
    for (std::size_t d = 0; d < static_cast<std::size_t>(geo.dim); ++d)
        x[d] = geo.origin[d] + node_greville(shape, ijk[d], geo.cells[d]) * geo.h;
    return x;
}

} // namespace talus
