// Properties every MPM kernel must have, checked at many positions: partition
// of unity, linear precision (sum N_i x_i = x), gradient consistency
// (sum dN_i = 0, sum dN_i x_i = 1), non-negativity, and for the B-splines the
// second moment sum N_i (x_i - x)^2 that APIC's D_p relies on (Jiang et al.
// 2015). Together, in tensor product, these are what makes a uniform
// velocity gradient reproduced exactly. All identities are exact in exact
// arithmetic; 1e-13 allows a few roundings of terms of order one.
#include <talus/shape_functions.hpp>

#include <gtest/gtest.h>

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
