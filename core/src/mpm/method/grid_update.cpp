#include "method/grid_update.hpp"

#include "parallel/parallel.hpp"

#include <algorithm>
#include <cmath>

namespace talus {

using node::kRecord;

namespace {

// D a constant: the node's component loop unrolled (with the dimension
// read at run time it stayed a loop per node).
template <int D, bool Update, DampingKind Damping>
void velocities_in(Grid &grid, const Boundary &bc, double t, double dt, double alpha, bool clear,
                   Boundary::Only on_start) {
    double *a = grid.acc.data(), *v = grid.vel.data();
    const std::size_t vs = node::velocity(D), ve = node::kEndVelocity;
    clear = clear && bc.faces_only();
    // v = p / m everywhere and, when updating, v~ = v + dt f / m in the same
    // pass; the constrained nodes are then redone in order (conditions on v,
    // v~ from the constrained v, conditions on v~), which matters for
    // friction, where v~'s approach speed depends on the constrained v.
    // Over the active box alone (Grid::reset): elsewhere no particle reads.
    auto update = [&](std::size_t i) {
        const double m = a[kRecord * i + node::kMass];
        const double inv = m > 0.0 ? 1.0 / m : 0.0;
        for (std::size_t d = 0; d < static_cast<std::size_t>(D); ++d) {
            const double v0 = a[kRecord * i + node::kMomentum + d] * inv;
            v[kRecord * i + vs + d] = v0;
            if constexpr (Update) {
                double &f = a[kRecord * i + node::kForce + d];
                // Damping changes the force itself, so that the constrained
                // nodes below and the diagnostics see the damped force.
                if constexpr (Damping == DampingKind::local)
                    // Cundall: f - alpha |f| sign(v), component by component.
                    f -= alpha * std::abs(f) * static_cast<double>((v0 > 0.0) - (v0 < 0.0));
                else if constexpr (Damping == DampingKind::viscous)
                    f -= alpha * m * v0;
                v[kRecord * i + ve + d] = v0 + dt * f * inv;
            }
        }
        if (clear) v[kRecord * i + node::kMassCopy] = m;
    };
    // With `clear`, the nodes no condition reads are cleared while their
    // record is in cache, which spares the next step's reset its pass over
    // the accumulators; the constrained ones once the conditions are done
    // with them, below.
    const SlotBox &box = grid.active();
    const SlotBox untouched = clear ? bc.untouched(grid) : SlotBox{};
    const std::size_t lo = static_cast<std::size_t>(box.lo[0]);
    par::for_each(box.rows(), [&](std::size_t r) {
        const std::size_t first = box.row_begin(r, grid.geo.extent), n = box.row_length();
        const SlotBox cut = box.row(r).cut(untouched);
        const std::size_t c0 = cut.empty() ? n : static_cast<std::size_t>(cut.lo[0]) - lo,
                          c1 = cut.empty() ? n : static_cast<std::size_t>(cut.hi[0]) - lo;
        for (std::size_t i = first; i < first + c0; ++i)
            update(i);
        for (std::size_t i = first + c0; i < first + c1; ++i) {
            update(i);
            std::fill_n(a + kRecord * i, kRecord, 0.0);
        }
        for (std::size_t i = first + c1; i < first + n; ++i)
            update(i);
    });
    bc.apply(grid, v, vs, a, t, on_start);
    if constexpr (!Update) return;
    bc.for_each_constrained_node(grid, [&](std::size_t i) {
        const double m = a[kRecord * i + node::kMass];
        const double inv = m > 0.0 ? 1.0 / m : 0.0;
        for (std::size_t d = 0; d < static_cast<std::size_t>(D); ++d)
            v[kRecord * i + ve + d] =
                v[kRecord * i + vs + d] + dt * a[kRecord * i + node::kForce + d] * inv;
    });
    bc.apply(grid, v, ve, a, t + dt);
    if (!clear) return;
    bc.for_each_constrained_node(
        grid, [&](std::size_t i) { std::fill_n(a + kRecord * i, kRecord, 0.0); });
    grid.accumulators_cleared();
}

template <bool Update, DampingKind Damping = DampingKind::none>
void velocities(Grid &grid, const Boundary &bc, double t, double dt, double alpha = 0.0,
                bool clear = false, Boundary::Only on_start = Boundary::Only::all) {
    if (grid.geo.dim == 2)
        velocities_in<2, Update, Damping>(grid, bc, t, dt, alpha, clear, on_start);
    else
        velocities_in<3, Update, Damping>(grid, bc, t, dt, alpha, clear, on_start);
}

} // namespace

void grid_velocity(Grid &grid, const Boundary &bc, double t) {
    velocities<false>(grid, bc, t, 0.0);
}

void grid_update(Grid &grid, const Boundary &bc, double t, double dt, const DampingSpec &damping,
                 Accumulators after, StartVelocity start) {
    const bool clear = after == Accumulators::clear;
    const Boundary::Only on =
        start == StartVelocity::as_mapped ? Boundary::Only::bilateral : Boundary::Only::all;
    switch (damping.kind) {
    case DampingKind::local:
        velocities<true, DampingKind::local>(grid, bc, t, dt, damping.coefficient, clear, on);
        break;
    case DampingKind::viscous:
        velocities<true, DampingKind::viscous>(grid, bc, t, dt, damping.coefficient, clear, on);
        break;
    default: velocities<true>(grid, bc, t, dt, 0.0, clear, on); break;
    }
}

void remapped_velocity(Grid &grid, const Boundary &bc, double t_end, bool mean) {
    double *a = grid.acc.data();
    const double *v = grid.vel.data();
    const std::size_t D = static_cast<std::size_t>(grid.geo.dim);
    grid.for_each_active_node([&](std::size_t i) {
        const double m = a[kRecord * i + node::kMass];
        for (std::size_t d = 0; d < D; ++d)
            a[kRecord * i + node::kForce + d] =
                m > 0.0 ? a[kRecord * i + node::kMomentum + d] / m : 0.0;
    });
    bc.apply(grid, a, node::kForce, a, t_end);
    const std::size_t vs = node::velocity(grid.geo.dim);
    if (mean)
        grid.for_each_active_node([&](std::size_t i) {
            for (std::size_t d = 0; d < D; ++d) {
                const std::size_t k = kRecord * i + d;
                a[k + node::kMomentum] = 0.5 * (v[k + vs] + a[k + node::kForce]);
            }
        });
}

} // namespace talus
