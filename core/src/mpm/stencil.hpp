// One particle's stencil: the nodes its shape function reaches, with the
// weights, their gradients and (for the affine transfers) the offsets of
// the nodes from the particle. Tensor products of the per-axis functions of
// shape_functions.hpp; the kernels see the domain's bounds (eval_bounded):
// the B-splines are clamped at the faces (docs/theory.md, "Boundaries").
#pragma once

#include "grid.hpp"

#include <talus/mpm/particles.hpp>
#include <talus/mpm/shape_functions.hpp>

#include <cstddef>

namespace talus {

template <int D, class S, bool Offsets = true>
struct Stencil {
    static constexpr int W = S::width;
    static constexpr int NN = D == 2 ? W * W : W * W * W;
    std::size_t idx[NN]; // local node slots
    double w[NN];
    double grad[NN][D];
    double off[Offsets ? NN : 1][D]; // x_i - x_p, m (x_i: the node's Greville point)
    // 1 / D_p per axis, 1/m^2: D_p = sum_i w_ip (x_i - x_p)(x_i - x_p)^T is
    // diagonal for a tensor-product kernel with linear precision (the cross
    // terms factor into sum_a w_a (x_a - x_p) = 0), h^2/4 (quadratic) or
    // h^2/3 (cubic) away from the faces (Jiang et al. 2015).
    double dinv[D];

    // Almost every particle is away from the faces, where the uniform kernel
    // holds. The hot kernels test this once per particle and run their
    // per-particle body in two instantiations, the uniform one inline and
    // the clamped one out of line: one branch inside the shared body costs
    // 10 % in 3D through register allocation alone.
    [[gnu::always_inline]] static bool interior(const GridGeometry &g, const ParticleSet &s,
                                                std::size_t p) {
        bool inner = true;
        for (int d = 0; d < D; ++d) {
            const std::size_t dd = static_cast<std::size_t>(d);
            inner = inner && S::interior((s.x[dd][p] - g.origin[dd]) * g.inv_h, g.cells[dd]);
        }
        return inner;
    }

    // Near == false requires interior(g, s, p).
    template <bool Near>
    [[gnu::always_inline]] void eval(const GridGeometry &g, const ParticleSet &s, std::size_t p) {
        int base[D];
        double w1[D][W], dw1[D][W], g1[D][W], xi[D];
        for (int d = 0; d < D; ++d) {
            const std::size_t dd = static_cast<std::size_t>(d);
            xi[d] = (s.x[dd][p] - g.origin[dd]) * g.inv_h;
            if constexpr (Near)
                S::eval_bounded(xi[d], s.lp[p], g.cells[dd], base[d], w1[d], dw1[d], g1[d]);
            else
                S::eval(xi[d], s.lp[p], base[d], w1[d], dw1[d]);
            for (int k = 0; k < W; ++k)
                dw1[d][k] *= g.inv_h; // d/dx = d/dxi / h, once per axis
            if constexpr (Offsets) {
                if constexpr (Near) {
                    const double m2 = second_moment<W>(w1[d], g1[d], xi[d]) * g.h * g.h;
                    dinv[d] = m2 > 0.0 ? 1.0 / m2 : 0.0;
                } else {
                    dinv[d] = g.affine_dinv;
                }
            }
        }
        combine(g, base, w1, dw1, Near ? g1 : nullptr, xi);
    }

    // Tensor products of the per-axis weights from global node `base`; node
    // points g1 in cells (the nodes themselves when null).
    [[gnu::always_inline]] void combine(const GridGeometry &g, const int *base,
                                        const double (*w1)[W], const double (*dw1)[W],
                                        const double (*g1)[W], const double *xi) {
        double o1[D][W];
        if constexpr (Offsets)
            for (int d = 0; d < D; ++d)
                for (int k = 0; k < W; ++k)
                    o1[d][k] = ((g1 ? g1[d][k] : base[d] + k) - xi[d]) * g.h;
        // The stencil's first node in the local box, once per axis.
        int lb[3] = {0, 0, 0};
        for (int d = 0; d < D; ++d)
            lb[d] = base[d] - g.first[static_cast<std::size_t>(d)];
        const std::size_t ex = static_cast<std::size_t>(g.extent[0]);
        const std::size_t exy = ex * static_cast<std::size_t>(g.extent[1]);
        auto slot = [&](int a, int b, int c) {
            return static_cast<std::size_t>(lb[0] + a) + ex * static_cast<std::size_t>(lb[1] + b) +
                   exy * static_cast<std::size_t>(lb[2] + c);
        };
        int q = 0;
        if constexpr (D == 2) {
            for (int b = 0; b < W; ++b)
                for (int a = 0; a < W; ++a, ++q) {
                    idx[q] = slot(a, b, 0);
                    w[q] = w1[0][a] * w1[1][b];
                    grad[q][0] = dw1[0][a] * w1[1][b];
                    grad[q][1] = w1[0][a] * dw1[1][b];
                    if constexpr (Offsets) {
                        off[q][0] = o1[0][a];
                        off[q][1] = o1[1][b];
                    }
                }
        } else {
            for (int c = 0; c < W; ++c)
                for (int b = 0; b < W; ++b)
                    for (int a = 0; a < W; ++a, ++q) {
                        idx[q] = slot(a, b, c);
                        const double wbc = w1[1][b] * w1[2][c];
                        w[q] = w1[0][a] * wbc;
                        grad[q][0] = dw1[0][a] * wbc;
                        grad[q][1] = w1[0][a] * dw1[1][b] * w1[2][c];
                        grad[q][2] = w1[0][a] * w1[1][b] * dw1[2][c];
                        if constexpr (Offsets) {
                            off[q][0] = o1[0][a];
                            off[q][1] = o1[1][b];
                            off[q][2] = o1[2][c];
                        }
                    }
        }
    }
};

// Runs f.template operator()<D, S>() for the run's dimension and kernel:
// the one runtime choice per pass that selects the compiled kernels.
template <class F>
void with_kernel(int dim, ShapeKind shape, F &&f) {
    auto by_shape = [&]<int D>() {
        switch (shape) {
        case ShapeKind::linear: f.template operator()<D, LinearShape>(); break;
        case ShapeKind::gimp: f.template operator()<D, GimpShape>(); break;
        case ShapeKind::bspline2: f.template operator()<D, BSpline2Shape>(); break;
        case ShapeKind::bspline3: f.template operator()<D, BSpline3Shape>(); break;
        }
    };
    if (dim == 2)
        by_shape.template operator()<2>();
    else
        by_shape.template operator()<3>();
}

} // namespace talus
