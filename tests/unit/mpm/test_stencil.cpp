// The factorised transfer kernels (core/src/mpm/stencil.hpp) against the
// textbook form they replace: every node's weight w_i = prod_d N(xi_d - k_d),
// its gradient and its offset formed one by one from the per-axis shape
// functions, then the scatter sum_i (w_i a + grad w_i . G + w_i off_i . O)
// and the gather sums done node by node. Both are the same sums in another
// order, so they agree to round-off: terms are of order one and each result
// is a sum of at most 64 nodes of a few products, so 1e-13 bounds the
// reordering's rounding with margin.
#include "stencil.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <random>
#include <vector>

namespace {

using talus::GridGeometry;
using talus::ParticleSet;

template <int D, class S>
struct Case {
    talus::Grid grid;
    ParticleSet set;
    explicit Case(talus::ShapeKind kind) : grid(D, {0.0, 0.0, 0.0}, {1.0, 0.8, 0.6}, 0.1, kind) {
        set.dim = D;
        set.has_L = set.has_dx = set.has_C = set.has_divv = false;
        set.resize(1);
        set.lp[0] = 0.25;
    }
    // The explicit per-node data for the particle at x: slot, weight,
    // gradient, offset.
    struct NodeRef {
        std::size_t slot;
        double w, grad[3], off[3];
    };
    std::vector<NodeRef> nodes(bool near) const {
        const GridGeometry &g = grid.geo;
        constexpr int W = S::width;
        int base[3] = {0, 0, 0};
        double w[3][W], dw[3][W], at[3][W];
        for (int d = 0; d < D; ++d) {
            const double xi = (set.x[static_cast<std::size_t>(d)][0] - g.origin[d]) * g.inv_h;
            if (near)
                S::eval_bounded(xi, set.lp[0], g.cells[d], base[d], w[d], dw[d], at[d]);
            else {
                S::eval(xi, set.lp[0], base[d], w[d], dw[d]);
                for (int k = 0; k < W; ++k)
                    at[d][k] = base[d] + k;
            }
            for (int k = 0; k < W; ++k) {
                dw[d][k] /= g.h;
                at[d][k] = (at[d][k] - xi) * g.h;
            }
        }
        std::vector<NodeRef> out;
        for (int c = 0; c < (D == 3 ? W : 1); ++c)
            for (int b = 0; b < W; ++b)
                for (int a = 0; a < W; ++a) {
                    const int k[3] = {a, b, c};
                    NodeRef r{};
                    std::size_t stride = 1;
                    r.slot = 0;
                    r.w = 1.0;
                    for (int d = 0; d < D; ++d) {
                        r.slot += static_cast<std::size_t>(base[d] + k[d] - g.first[d]) * stride;
                        stride *= static_cast<std::size_t>(g.extent[d]);
                        r.w *= w[d][k[d]];
                        r.off[d] = at[d][k[d]];
                    }
                    for (int d = 0; d < D; ++d) {
                        r.grad[d] = 1.0;
                        for (int e = 0; e < D; ++e)
                            r.grad[d] *= e == d ? dw[e][k[e]] : w[e][k[e]];
                    }
                    out.push_back(r);
                }
        return out;
    }
};

template <class Lanes, int D, class S>
void check_with(talus::ShapeKind kind) {
    Case<D, S> cs(kind);
    const GridGeometry &g = cs.grid.geo;
    std::mt19937_64 rng(11);
    std::uniform_real_distribution<double> unit(-1.0, 1.0);
    for (int trial = 0; trial < 200; ++trial) {
        // Half the positions anywhere in the domain (the clamped kernels near
        // its faces), half within a cell of a face.
        for (int d = 0; d < D; ++d) {
            const double L = g.cells[static_cast<std::size_t>(d)] * g.h;
            const double u = 0.5 * (unit(rng) + 1.0);
            cs.set.x[static_cast<std::size_t>(d)][0] =
                trial % 2 ? u * L : (u < 0.5 ? u * 0.2 * g.h : L - (u - 0.5) * 0.2 * g.h);
        }
        using St = talus::Stencil<D, S>;
        const bool near = !St::interior(g, cs.set, 0);
        St st;
        if (near)
            st.template eval<true, true>(g, cs.set, 0);
        else
            st.template eval<false, true>(g, cs.set, 0);
        const auto ref = cs.nodes(near);

        Lanes a{}, grad[D]{}, offs[D]{};
        for (int k = 0; k < talus::kLanes; ++k) {
            talus::set_lane(a, static_cast<std::size_t>(k), unit(rng));
            for (int d = 0; d < D; ++d) {
                talus::set_lane(grad[d], static_cast<std::size_t>(k), unit(rng));
                // an affine matrix of order 1/h
                talus::set_lane(offs[d], static_cast<std::size_t>(k), unit(rng) / g.h);
            }
        }
        std::vector<double> records(cs.grid.acc.size(), 0.0);
        st.template scatter<true, true, Lanes>(g, records.data(), a, grad, offs);
        std::vector<double> expect(records.size(), 0.0);
        for (const auto &r : ref)
            for (int k = 0; k < talus::kLanes; ++k) {
                double v = r.w * a[k];
                for (int d = 0; d < D; ++d)
                    v += r.grad[d] * grad[d][k] + r.w * r.off[d] * offs[d][k];
                expect[talus::node::kRecord * r.slot + static_cast<std::size_t>(k)] += v;
            }
        for (std::size_t i = 0; i < records.size(); ++i)
            ASSERT_NEAR(records[i], expect[i], 1e-13 * (1.0 + 1.0 / g.h))
                << "scatter, record value " << i << " trial " << trial;

        // Gather of random records.
        for (double &v : records)
            v = unit(rng);
        Lanes sum, dsum[D], osum[D];
        st.template gather<true, true, Lanes>(g, records.data(), sum, dsum, osum);
        for (int k = 0; k < talus::kLanes; ++k) {
            double s0 = 0.0, sg[3] = {}, so[3] = {};
            for (const auto &r : ref) {
                const double v =
                    records[talus::node::kRecord * r.slot + static_cast<std::size_t>(k)];
                s0 += r.w * v;
                for (int d = 0; d < D; ++d) {
                    sg[d] += r.grad[d] * v;
                    so[d] += r.w * r.off[d] * v;
                }
            }
            ASSERT_NEAR(sum[k], s0, 1e-13) << "gather, lane " << k << " trial " << trial;
            for (int d = 0; d < D; ++d) {
                ASSERT_NEAR(dsum[d][k], sg[d], 1e-13 / g.h) << "gradient, axis " << d;
                ASSERT_NEAR(osum[d][k], so[d], 1e-13 * g.h) << "offset, axis " << d;
            }
        }
    }
}

// Both node-record types the kernels are compiled with (stencil.hpp).
template <int D, class S>
void check(talus::ShapeKind kind) {
    check_with<talus::Arr8, D, S>(kind);
    check_with<talus::Vec8, D, S>(kind);
}

} // namespace

TEST(Stencil, LinearMatchesTheNodeByNodeSums2D) {
    check<2, talus::LinearShape>(talus::ShapeKind::linear);
}
TEST(Stencil, LinearMatchesTheNodeByNodeSums3D) {
    check<3, talus::LinearShape>(talus::ShapeKind::linear);
}
TEST(Stencil, GimpMatchesTheNodeByNodeSums2D) {
    check<2, talus::GimpShape>(talus::ShapeKind::gimp);
}
TEST(Stencil, GimpMatchesTheNodeByNodeSums3D) {
    check<3, talus::GimpShape>(talus::ShapeKind::gimp);
}
TEST(Stencil, QuadraticBSplineMatchesTheNodeByNodeSums2D) {
    check<2, talus::BSpline2Shape>(talus::ShapeKind::bspline2);
}
TEST(Stencil, QuadraticBSplineMatchesTheNodeByNodeSums3D) {
    check<3, talus::BSpline2Shape>(talus::ShapeKind::bspline2);
}
TEST(Stencil, CubicBSplineMatchesTheNodeByNodeSums2D) {
    check<2, talus::BSpline3Shape>(talus::ShapeKind::bspline3);
}
TEST(Stencil, CubicBSplineMatchesTheNodeByNodeSums3D) {
    check<3, talus::BSpline3Shape>(talus::ShapeKind::bspline3);
}
