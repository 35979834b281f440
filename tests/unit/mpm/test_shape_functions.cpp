// Properties every MPM kernel must have, checked at many positions: partition
// of unity, linear precision (sum N_i x_i = x), gradient consistency
// (sum dN_i = 0, sum dN_i x_i = 1), non-negativity, and for the B-splines the
// second moment sum N_i (x_i - x)^2 that APIC's D_p relies on (Jiang et al.
// 2015). Together, in tensor product, these are what makes a uniform
// velocity gradient reproduced exactly. All identities are exact in exact
// arithmetic; 1e-13 allows a few roundings of terms of order one.
#include <talus/mpm/shape_functions.hpp>

#include <gtest/gtest.h>

#include <array>
#include <random>

namespace {

template <class S>
void check_kernel(double lp, double second_moment) {
    std::mt19937_64 rng(7);
    std::uniform_real_distribution<double> u(2.0, 40.0);
    for (int trial = 0; trial < 2000; ++trial) {
        const double xi = trial < 3 ? 5.0 + 0.5 * trial : u(rng); // include exact nodes / midpoints
        int base = 0;
        double w[S::width], dw[S::width];
        S::eval(xi, lp, base, w, dw);
        double sw = 0, swx = 0, sdw = 0, sdwx = 0, sm2 = 0;
        for (int k = 0; k < S::width; ++k) {
            const double xk = base + k;
            EXPECT_GE(w[k], 0.0) << "xi " << xi;
            sw += w[k];
            swx += w[k] * xk;
            sdw += dw[k];
            sdwx += dw[k] * xk;
            sm2 += w[k] * (xk - xi) * (xk - xi);
        }
        EXPECT_NEAR(sw, 1.0, 1e-13) << "partition of unity at " << xi;
        EXPECT_NEAR(swx, xi, 1e-13 * xi) << "linear precision at " << xi;
        EXPECT_NEAR(sdw, 0.0, 1e-13) << "gradient sum at " << xi;
        EXPECT_NEAR(sdwx, 1.0, 1e-13 * xi) << "gradient consistency at " << xi;
        if (second_moment > 0.0) {
            EXPECT_NEAR(sm2, second_moment, 1e-13 * xi * xi) << "second moment at " << xi;
        }
    }
}

// The kernels' weights match their closed forms (seed 000 eq. 24 for the
// quadratic B-spline) at a few hand-picked points.
TEST(ShapeFunctions, QuadraticBSplineValues) {
    int base = 0;
    double w[3], dw[3];
    talus::BSpline2Shape::eval(10.0, 0.0, base, w, dw); // on node 10
    EXPECT_EQ(base, 9);
    EXPECT_DOUBLE_EQ(w[0], 0.125);
    EXPECT_DOUBLE_EQ(w[1], 0.75);
    EXPECT_DOUBLE_EQ(w[2], 0.125);
    EXPECT_DOUBLE_EQ(dw[0], -0.5);
    EXPECT_DOUBLE_EQ(dw[1], 0.0);
    EXPECT_DOUBLE_EQ(dw[2], 0.5);
    talus::BSpline2Shape::eval(10.5, 0.0, base, w, dw); // mid-cell: r = 0.5 and 1.5
    EXPECT_EQ(base, 10);
    EXPECT_DOUBLE_EQ(w[0], 0.5);
    EXPECT_DOUBLE_EQ(w[1], 0.5);
    EXPECT_DOUBLE_EQ(w[2], 0.0);
}

TEST(ShapeFunctions, LinearHasAllProperties) { check_kernel<talus::LinearShape>(0.0, 0.0); }
TEST(ShapeFunctions, GimpHasAllProperties) {
    check_kernel<talus::GimpShape>(0.25, 0.0); // 2 particles per cell
    check_kernel<talus::GimpShape>(0.125, 0.0);
    check_kernel<talus::GimpShape>(0.5, 0.0);
}
TEST(ShapeFunctions, QuadraticBSplineHasAllProperties) {
    check_kernel<talus::BSpline2Shape>(0.0, 0.25);
}
TEST(ShapeFunctions, CubicBSplineHasAllProperties) {
    check_kernel<talus::BSpline3Shape>(0.0, 1.0 / 3.0);
}

// The clamped B-splines on a bounded domain of n cells (eval_bounded), at
// many points including the faces and points near them: partition of
// unity, linear precision with the Greville points (sum N_k g_k = xi),
// gradient consistency, non-negativity, derivatives that match central
// differences of the values (1e-6: the O(e^2) = 1e-12 truncation divided by
// e = 1e-6 and the values' round-off 1e-16 / 1e-6), the uniform kernel
// exactly where interior() says so (the solver's fast path relies on it; to
// the recursion's round-off, 1e-15) and not elsewhere, and at each face exactly one non-zero
// function, equal to 1, on the node one layer outside the face.
template <class S, int P>
void check_bounded(int n) {
    std::mt19937_64 rng(11);
    std::uniform_real_distribution<double> u(0.0, static_cast<double>(n));
    for (int trial = 0; trial < 4000; ++trial) {
        double xi = u(rng);
        if (trial < 4)
            xi = std::array<double, 4>{0.0, static_cast<double>(n), 1e-14, n - 1e-14}[trial];
        int base = 0;
        double w[S::width], dw[S::width], g[S::width];
        S::eval_bounded(xi, 0.0, n, base, w, dw, g);
        double sw = 0, swg = 0, sdw = 0, sdwg = 0;
        for (int k = 0; k < S::width; ++k) {
            EXPECT_GE(w[k], 0.0) << "xi " << xi;
            sw += w[k];
            swg += w[k] * g[k];
            sdw += dw[k];
            sdwg += dw[k] * g[k];
        }
        EXPECT_NEAR(sw, 1.0, 1e-13) << "partition of unity at " << xi;
        EXPECT_NEAR(swg, xi, 1e-13 * n) << "linear precision at " << xi;
        EXPECT_NEAR(sdw, 0.0, 1e-12) << "gradient sum at " << xi;
        EXPECT_NEAR(sdwg, 1.0, 1e-12 * n) << "gradient consistency at " << xi;
        const double e = 1e-6;
        if (xi > e && xi < n - e) {
            int b1 = 0, b2 = 0;
            double w1[S::width], w2[S::width], d1[S::width], d2[S::width], g1[S::width],
                g2[S::width];
            S::eval_bounded(xi - e, 0.0, n, b1, w1, d1, g1);
            S::eval_bounded(xi + e, 0.0, n, b2, w2, d2, g2);
            if (b1 == base && b2 == base) {
                for (int k = 0; k < S::width; ++k)
                    EXPECT_NEAR(dw[k], (w2[k] - w1[k]) / (2 * e), 1e-6) << "xi " << xi;
            }
        }
        // The clamped functions by their definition (the Cox-de Boor
        // recursion on the clamped knots, wherever xi is): eval_bounded
        // must give them, also where it takes the uniform formulas (the
        // solver's fast path relies on interior()) or, on domains of 8
        // cells and more, the polynomial pieces next to a face
        // (ClampedPieces; round-off of the recursion and of the pieces'
        // coefficients: 1e-15 on values, 1e-14 on derivatives of order
        // one).
        {
            double wr[S::width], dr[S::width], gr[S::width];
            talus::clamped_bsplines<P, S::width>(xi, n, base, wr, dr, gr);
            for (int k = 0; k < S::width; ++k) {
                EXPECT_NEAR(wr[k], w[k], 1e-15) << "xi " << xi;
                EXPECT_NEAR(dr[k], dw[k], 1e-14) << "xi " << xi;
                EXPECT_DOUBLE_EQ(gr[k], g[k]) << "xi " << xi;
            }
            // ... and interior() claims no more than is true: 0.1 cells off
            // its region (where the C1, for the cubic C2, match makes the
            // difference vanish smoothly, like 0.1^3 / 6 ~ 2e-4 for the
            // cubic) the uniform kernel differs.
            if (!S::interior(xi - 0.1, n) && !S::interior(xi + 0.1, n) && n >= 4) {
                int bu = 0;
                double wu[S::width], du[S::width], diff = 0.0;
                S::eval(xi, 0.0, bu, wu, du);
                for (int k = 0; k < S::width; ++k)
                    diff = std::max(diff, std::abs(wu[k] - wr[k]));
                EXPECT_GT(diff, 1e-5) << "xi " << xi << ": uniform outside interior()";
            }
        }
        if (xi >= 3.0 && xi <= n - 3.0) { // far from both faces: the uniform kernel
            int bu = 0;
            double wu[S::width], du[S::width];
            S::eval(xi, 0.0, bu, wu, du);
            EXPECT_EQ(bu, base);
            for (int k = 0; k < S::width; ++k) {
                EXPECT_EQ(wu[k], w[k]);
                EXPECT_EQ(g[k], base + k);
            }
        }
        if (xi == 0.0 || xi == n) {
            const int face_node = xi == 0.0 ? -1 : n + 1;
            for (int k = 0; k < S::width; ++k) {
                EXPECT_DOUBLE_EQ(w[k], base + k == face_node ? 1.0 : 0.0) << "face at " << xi;
                if (base + k == face_node) {
                    EXPECT_DOUBLE_EQ(g[k], xi);
                }
            }
        }
    }
}

TEST(ShapeFunctions, ClampedQuadraticBSplineOnABoundedDomain) {
    for (int n : {1, 2, 3, 5, 7, 8, 40})
        check_bounded<talus::BSpline2Shape, 2>(n);
}
TEST(ShapeFunctions, ClampedCubicBSplineOnABoundedDomain) {
    for (int n : {1, 2, 3, 5, 7, 8, 40})
        check_bounded<talus::BSpline3Shape, 3>(n);
}

// The clamped quadratic basis next to the face x = 0 against its closed form
// on the knots {0, 0, 0, 1/2, 3/2, 5/2, ...}, worked out by hand from the
// Cox-de Boor recursion: node -1: (1 - 2u)^2 on [0, 1/2]; node 0: 4u -
// 16u^2/3 on [0, 1/2], 2(3/2 - u)^2/3 on [1/2, 3/2]; node 1: 4u^2/3 on [0,
// 1/2], u(3/2 - u)/(3/2) + (5/2 - u)(u - 1/2)/2 on [1/2, 3/2]. Greville
// points 0, 1/4, 1.
TEST(ShapeFunctions, ClampedQuadraticBSplineValues) {
    int base = 0;
    double w[3], dw[3], g[3];
    talus::BSpline2Shape::eval_bounded(0.25, 0.0, 10, base, w, dw, g);
    EXPECT_EQ(base, -1);
    EXPECT_DOUBLE_EQ(w[0], 0.25);
    EXPECT_DOUBLE_EQ(w[1], 1.0 - 1.0 / 3.0);
    EXPECT_DOUBLE_EQ(w[2], 1.0 / 12.0);
    EXPECT_DOUBLE_EQ(dw[0], -2.0);              // -4 (1 - 2u)
    EXPECT_DOUBLE_EQ(dw[1], 4.0 - 32.0 / 12.0); // 4 - 32u/3
    EXPECT_DOUBLE_EQ(g[0], 0.0);
    EXPECT_DOUBLE_EQ(g[1], 0.25);
    EXPECT_DOUBLE_EQ(g[2], 1.0);
    talus::BSpline2Shape::eval_bounded(1.0, 0.0, 10, base, w, dw, g);
    EXPECT_EQ(base, 0);
    EXPECT_DOUBLE_EQ(w[0], 2.0 / 3.0 * 0.25);
    EXPECT_DOUBLE_EQ(w[1], 1.0 / 3.0 + 0.375);
    EXPECT_DOUBLE_EQ(w[2], 0.125); // node 2 is uniform: (3/2 - 1)^2 / 2
    // The upper face mirrors the lower one.
    talus::BSpline2Shape::eval_bounded(9.75, 0.0, 10, base, w, dw, g);
    EXPECT_EQ(base, 9);
    EXPECT_DOUBLE_EQ(w[2], 0.25);
    EXPECT_DOUBLE_EQ(w[1], 1.0 - 1.0 / 3.0);
    EXPECT_DOUBLE_EQ(w[0], 1.0 / 12.0);
    EXPECT_DOUBLE_EQ(dw[2], 2.0);
    EXPECT_DOUBLE_EQ(g[2], 10.0);
    EXPECT_DOUBLE_EQ(g[1], 9.75);
}

// uGIMP is continuous with a continuous gradient: compare across the
// breakpoints |r| = lp and 1 - lp and 1 + lp against its closed form.
TEST(ShapeFunctions, GimpIsContinuousAtItsBreakpoints) {
    const double lp = 0.25;
    for (double r : {lp, 1.0 - lp, 1.0 + lp}) {
        const double e = 1e-9;
        EXPECT_NEAR(talus::GimpShape::n(r - e, lp), talus::GimpShape::n(r + e, lp), 1e-8);
        EXPECT_NEAR(talus::GimpShape::dn(r - e, lp), talus::GimpShape::dn(r + e, lp), 1e-8);
    }
    EXPECT_DOUBLE_EQ(talus::GimpShape::n(0.0, lp), 1.0 - lp / 2.0);
    EXPECT_DOUBLE_EQ(talus::GimpShape::n(1.0 + lp, lp), 0.0);
}

TEST(ShapeFunctions, FastFloorIsFloor) {
    for (double x : {0.0, 0.5, 1.0, 1.999999, 7.0, -0.5, -1.0, -2.25, 1e9 + 0.5})
        EXPECT_EQ(talus::fast_floor(x), std::floor(x)) << x;
}

} // namespace
