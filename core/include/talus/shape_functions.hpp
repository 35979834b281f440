// Grid shape functions on a uniform Cartesian grid: one-dimensional kernels
// whose tensor products give the nodal weights w_ip and gradients grad w_ip
// (seed 000, eqs. 24-27).
//
// Every kernel works in grid units: xi = (x - origin) / h is the particle's
// coordinate measured in cells, node k sits at xi = k. eval() returns the
// first node of the stencil (`base`) and, for the `width` nodes base ..
// base + width - 1, the weights N(xi - k) and their derivatives dN/dxi (to be
// divided by h for a spatial gradient).
#pragma once

#include <cmath>
#include <string_view>

namespace talus {

// floor() for the kernels: a truncating cast plus a correction, because
// std::floor is a library call on baseline x86-64 (no SSE4.1 roundsd) and
// sits in the innermost loop of P2G and G2P.
inline double fast_floor(double x) {
    const double t = static_cast<double>(static_cast<long long>(x));
    return t > x ? t - 1.0 : t;
}

enum class ShapeKind { linear, gimp, bspline2, bspline3 };

// Linear ("tent") functions, the original MPM of Sulsky et al. (1994).
struct LinearShape {
    static constexpr int width = 2;
    static inline void eval(double xi, double /*lp*/, int &base, double *w, double *dw) {
        const double fl = fast_floor(xi);
        base = static_cast<int>(fl);
        const double r = xi - fl; // in [0, 1)
        w[0] = 1.0 - r;
        w[1] = r;
        dw[0] = -1.0;
        dw[1] = 1.0;
    }
};

// Uniform GIMP (Bardenhagen & Kober 2004): the tent function convolved with a
// particle characteristic function of half-width lp (in cells, lp <= 1/2),
// lp fixed at its initial value 1/(2 ppc) ("u" for undeformed).
struct GimpShape {
    static constexpr int width = 3;
    static inline double n(double r, double lp) {
        const double a = std::abs(r);
        if (a < lp) return 1.0 - (r * r + lp * lp) / (2.0 * lp);
        if (a < 1.0 - lp) return 1.0 - a;
        if (a < 1.0 + lp) return (1.0 + lp - a) * (1.0 + lp - a) / (4.0 * lp);
        return 0.0;
    }
    static inline double dn(double r, double lp) {
        const double a = std::abs(r);
        const double s = r < 0.0 ? -1.0 : 1.0;
        if (a < lp) return -r / lp;
        if (a < 1.0 - lp) return -s;
        if (a < 1.0 + lp) return -s * (1.0 + lp - a) / (2.0 * lp);
        return 0.0;
    }
    static inline void eval(double xi, double lp, int &base, double *w, double *dw) {
        // Support radius 1 + lp <= 1.5: the nearest node and its neighbours.
        base = static_cast<int>(fast_floor(xi + 0.5)) - 1;
        for (int k = 0; k < 3; ++k) {
            const double r = xi - (base + k);
            w[k] = n(r, lp);
            dw[k] = dn(r, lp);
        }
    }
};

// Quadratic B-spline (Steffen et al. 2008; seed 000 eqs. 24-25), node-centred.
struct BSpline2Shape {
    static constexpr int width = 3;
    static inline void eval(double xi, double /*lp*/, int &base, double *w, double *dw) {
        const double fl = fast_floor(xi - 0.5);
        base = static_cast<int>(fl);
        const double r0 = xi - fl;  // distance to node base, in [0.5, 1.5)
        const double a = 1.5 - r0;  // in (0, 1]
        const double r1 = r0 - 1.0; // in [-0.5, 0.5)
        const double c = r0 - 0.5;  // 1.5 + r2, in [0, 1)
        w[0] = 0.5 * a * a;
        w[1] = 0.75 - r1 * r1;
        w[2] = 0.5 * c * c;
        dw[0] = -a;
        dw[1] = -2.0 * r1;
        dw[2] = c;
    }
};

// Cubic B-spline (Steffen et al. 2008), node-centred.
struct BSpline3Shape {
    static constexpr int width = 4;
    static inline void eval(double xi, double /*lp*/, int &base, double *w, double *dw) {
        const double fl = fast_floor(xi);
        base = static_cast<int>(fl) - 1;
        const double t = xi - fl; // in [0, 1)
        const double u = 1.0 - t;
        // r = xi - node: 1 + t, t, t - 1, t - 2.
        w[0] = u * u * u / 6.0;
        w[1] = 2.0 / 3.0 - t * t + 0.5 * t * t * t;
        w[2] = 2.0 / 3.0 - u * u + 0.5 * u * u * u;
        w[3] = t * t * t / 6.0;
        dw[0] = -0.5 * u * u;
        dw[1] = -2.0 * t + 1.5 * t * t;
        dw[2] = 2.0 * u - 1.5 * u * u;
        dw[3] = 0.5 * t * t;
    }
};

// Nodes of the stencil beyond the domain on each side: the grid carries this
// many ghost layers so that every kernel keeps partition of unity near a
// boundary.
inline constexpr int kGhostLayers = 2;

constexpr std::string_view shape_name(ShapeKind k) {
    switch (k) {
    case ShapeKind::linear: return "linear";
    case ShapeKind::gimp: return "gimp";
    case ShapeKind::bspline2: return "bspline2";
    case ShapeKind::bspline3: return "bspline3";
    }
    return "?";
}

} // namespace talus
