#include "method/boundary.hpp"

#include "parallel/parallel.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>

namespace talus {

Boundary::Boundary(const Scenario &sc, const Conditions &c, const Grid &grid, double t0,
                   const Comm &comm)
    : dim_(sc.dim), t0_(t0), faces_(c.faces) {
    for (const NodalVelocity &nv : c.nodal_velocities) {
        Prescribed p{{}, nv.velocity};
        // A node stands for its Greville point (clamped B-splines).
        for (std::size_t i = 0; i < grid.n_nodes; ++i) {
            const std::array<double, 3> x = grid.node_point(i, sc.solver.shape);
            if (nv.box.contains(x.data(), dim_)) p.nodes.push_back(static_cast<std::uint32_t>(i));
        }
        // On several ranks a box may lie outside this rank's nodes: refused
        // only when it holds none on any.
        const long held = comm.sum(static_cast<long>(p.nodes.size()));
        if (held == 0)
            fail_together(
                comm, nv.origin.error(fmt::format(
                          "the box holds no grid node (nodes are {:g} m apart{}); enlarge the box",
                          grid.geo.h,
                          face_layer(sc.solver.shape) > 0 ? ", at their Greville points near a face"
                                                          : "")));
        prescribed_.push_back(std::move(p));
    }
    for (const ParticleVelocity &pv : c.particle_velocities)
        fixities_.push_back(pv.velocity);
}

SlotBox Boundary::untouched(const Grid &grid) const {
    SlotBox b = grid.active();
    for (std::size_t f = 0; f < 6; ++f) {
        const SlotBox &layer = grid.face_nodes[f];
        if (faces_[f].type == FaceType::free || layer.empty()) continue;
        const std::size_t axis = f / 2;
        // Grid: a face's layer spans the held nodes on its other axes.
        if (f % 2 == 0)
            b.lo[axis] = std::max(b.lo[axis], layer.hi[axis]);
        else
            b.hi[axis] = std::min(b.hi[axis], layer.lo[axis]);
    }
    return b.empty() ? SlotBox{} : b;
}

// Contact (slip, friction) is unilateral: a node moving away from the wall
// is left alone; one moving into it loses its normal velocity and, with
// Coulomb friction, its tangential speed is reduced by mu times the normal
// speed removed (a velocity projection of the impulse).
void Boundary::apply(const Grid &grid, double *field, std::size_t offset, const double *fixity,
                     double t_run, Only only) const {
    const double t = t_run - t0_;
    auto V = [&](std::size_t i) { return field + node::kRecord * i + offset; };
    for (int f = 0; f < 2 * dim_; ++f) {
        const FaceCondition &fc = faces_[static_cast<std::size_t>(f)];
        if (fc.type == FaceType::free) continue;
        const bool contact = fc.type != FaceType::fixed && fc.type != FaceType::roller;
        if (contact && only == Only::bilateral) continue;
        const std::size_t axis = static_cast<std::size_t>(f / 2);
        const double sign = (f % 2 == 0) ? -1.0 : 1.0; // outward normal
        for_each_node(grid, grid.face_nodes[static_cast<std::size_t>(f)], [&](std::size_t i) {
            double *v = V(i);
            if (fc.type == FaceType::fixed) {
                for (int d = 0; d < dim_; ++d)
                    v[d] = 0.0;
            } else if (fc.type == FaceType::roller) {
                v[axis] = 0.0;
            } else {
                const double vn = sign * v[axis];
                if (vn <= 0.0) return; // separating: no contact
                v[axis] = 0.0;
                if (fc.friction == 0.0) return;
                double vt2 = 0.0;
                for (int d = 0; d < dim_; ++d)
                    if (static_cast<std::size_t>(d) != axis) vt2 += v[d] * v[d];
                const double vt = std::sqrt(vt2);
                const double scale = vt > 0.0 ? std::max(0.0, 1.0 - fc.friction * vn / vt) : 0.0;
                for (int d = 0; d < dim_; ++d)
                    if (static_cast<std::size_t>(d) != axis) v[d] *= scale;
            }
        });
    }
    for (const Prescribed &p : prescribed_)
        for (int d = 0; d < dim_; ++d)
            if (const auto &fn = p.velocity.c[static_cast<std::size_t>(d)]) {
                const double v = (*fn)(t);
                for (std::uint32_t i : p.nodes)
                    if (grid.active().contains(grid.local(i))) V(i)[d] = v;
            }
    // Particle fixities act on the grid too: every node a fixed particle
    // reaches moves as prescribed, so the body attached to those particles
    // is held through the grid (a fixity on the particles alone would keep
    // them in place while the grid, and the rest of the body, moved on).
    // The constrained zone is the fixed particles plus one kernel support.
    if (fixities_.empty()) return;
    double value[kMaxLoads][3] = {};
    bool on[kMaxLoads][3] = {};
    for (std::size_t k = 0; k < fixities_.size(); ++k)
        for (int d = 0; d < dim_; ++d)
            if (const auto &fn = fixities_[k].c[static_cast<std::size_t>(d)]) {
                value[k][d] = (*fn)(t);
                on[k][d] = true;
            }
    const int D = dim_;
    grid.for_each_active_node([&](std::size_t i) {
        std::uint32_t mask = static_cast<std::uint32_t>(fixity[node::kRecord * i + node::kFixity]);
        while (mask) {
            const std::size_t k = static_cast<std::size_t>(__builtin_ctz(mask));
            mask &= mask - 1;
            for (int d = 0; d < D; ++d)
                if (on[k][d]) V(i)[d] = value[k][d];
        }
    });
}

} // namespace talus
