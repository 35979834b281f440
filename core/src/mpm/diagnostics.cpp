// What the run reports about itself: conserved quantities and counters
// (Simulation::diagnostics), and what a scenario will need before anything
// is allocated (estimate_resources).
#include "simulation_state.hpp"

#include "state/particle_generation.hpp"

#include <talus/material/plugin_loader.hpp>

#include <cmath>

namespace talus {

namespace {

// sum_a w_a (x_a - x)^2 along axis d at coordinate x, m^2: the diagonal
// entry of APIC's D_p (x_a: the nodes' Greville points).
double affine_moment(const GridGeometry &g, ShapeKind shape, int d, double x) {
    const std::size_t dd = static_cast<std::size_t>(d);
    const double xi = (x - g.origin[dd]) * g.inv_h;
    auto moment = [&](auto kernel) {
        using S = decltype(kernel);
        int base = 0;
        double w[S::width], dw[S::width], gv[S::width];
        S::eval_bounded(xi, 0.0, g.cells[dd], base, w, dw, gv);
        return second_moment<S::width>(w, gv, xi) * g.h * g.h;
    };
    return shape == ShapeKind::bspline3 ? moment(BSpline3Shape{}) : moment(BSpline2Shape{});
}

} // namespace

Diagnostics Simulation::diagnostics() const {
    const Impl &g = *impl_;
    Diagnostics dg;
    dg.step = g.step;
    dg.time = g.time;
    dg.dt = g.last_dt;
    dg.removed = g.removed;
    dg.cut_steps = g.materials.cut_steps();
    dg.held_at_faces = g.held_at_faces;
    dg.held_depth = g.held_depth;
    const int D = g.sc.dim;
    // The affine velocity field carries angular momentum too: for the
    // B-splines, sum_i x_i x p_i gains m eps:(C D_p) with D_p = h^2/4
    // (quadratic) or h^2/3 (cubic) away from the faces (Jiang et al. 2015).
    const bool affine = g.sc.solver.transfer != Transfer::flip && g.grid.geo.affine_dinv > 0.0;
    for (const ParticleSet &s : g.sets) {
        dg.particles += s.n;
        for (std::size_t p = 0; p < s.n; ++p) {
            const double m = s.mass[p];
            double v[3] = {0, 0, 0}, x[3] = {0, 0, 0};
            for (std::size_t d = 0; d < static_cast<std::size_t>(D); ++d) {
                v[d] = s.v[d][p];
                x[d] = s.x[d][p];
            }
            dg.mass += m;
            for (std::size_t d = 0; d < 3; ++d)
                dg.momentum[d] += m * v[d];
            dg.kinetic_energy += 0.5 * m * (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]);
            dg.stress_work += s.work[p];
            static const double no_affine[9] = {};
            const double *C = s.has_C ? &s.C[9 * p] : no_affine;
            double Dp[3] = {0, 0, 0}; // D_p per axis (diagonal), m^2
            if (affine)
                for (int d = 0; d < D; ++d)
                    Dp[d] = affine_moment(g.grid.geo, g.sc.solver.shape, d, x[d]);
            // sum_i x_i x m w_ip C (x_i - x_p) = x_p x m v_p + m eps_kab C_bc D_ac.
            dg.angular_momentum[2] +=
                m * (x[0] * v[1] - x[1] * v[0]) + m * (Dp[0] * C[3] - Dp[1] * C[1]);
            if (D == 3) {
                dg.angular_momentum[0] +=
                    m * (x[1] * v[2] - x[2] * v[1]) + m * (Dp[1] * C[7] - Dp[2] * C[5]);
                dg.angular_momentum[1] +=
                    m * (x[2] * v[0] - x[0] * v[2]) + m * (Dp[2] * C[2] - Dp[0] * C[6]);
            }
        }
    }
    if (g.comm.distributed()) {
        // Over the ranks (the removed and held counts already are: the
        // step's end sums them).
        double sums[9] = {dg.mass,
                          dg.momentum[0],
                          dg.momentum[1],
                          dg.momentum[2],
                          dg.kinetic_energy,
                          dg.stress_work,
                          dg.angular_momentum[0],
                          dg.angular_momentum[1],
                          dg.angular_momentum[2]};
        g.comm.sum(sums, 9);
        dg.mass = sums[0];
        dg.momentum = {sums[1], sums[2], sums[3]};
        dg.kinetic_energy = sums[4];
        dg.stress_work = sums[5];
        dg.angular_momentum = {sums[6], sums[7], sums[8]};
        dg.particles = static_cast<std::size_t>(g.comm.sum(static_cast<long>(dg.particles)));
        dg.cut_steps = g.comm.sum(dg.cut_steps);
    }
    return dg;
}

ResourceEstimate estimate_resources(const Scenario &sc) {
    ResourceEstimate e;
    const int D = sc.dim;
    e.nodes = 1.0;
    double cells = 1.0;
    for (std::size_t d = 0; d < static_cast<std::size_t>(D); ++d) {
        const double n = std::round(sc.size[d] / sc.cell);
        e.nodes *= n + 1 + 2 * kGhostLayers;
        cells *= n;
    }
    // Per node: the two 8-double records (acc, vel); per cell: the bins and
    // the cell-averaged dilation sums.
    e.bytes = e.nodes * 2 * 8 * 8 + cells * (4 + (sc.solver.cell_averaged_dilation ? 16 : 0));
    for (const GroupSpec &g : sc.groups) {
        const double n = g.shape.measure(D) / std::pow(sc.cell / g.particles_per_cell, D);
        e.particles += n;
        // Every column of a set of this material, each optional one counted,
        // then the ordering's slab, cell and order indices and the sort's
        // key and permutation.
        ParticleSet probe;
        probe.dim = D;
        probe.state_size = sc.materials[g.material].spec.state.size;
        e.bytes += n * (static_cast<double>(probe.bytes_per_particle()) + 12 + 16);
    }
    return e;
}

} // namespace talus
