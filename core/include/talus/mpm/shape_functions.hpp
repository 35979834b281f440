// Grid shape functions on a uniform Cartesian grid: one-dimensional kernels
// whose tensor products give the nodal weights w_ip and gradients grad w_ip
// (seed 000, eqs. 24-27).
//
// Every kernel works in grid units: xi = (x - origin) / h is the particle's
// coordinate measured in cells, node k sits at xi = k. eval() returns the
// first node of the stencil (`base`) and, for the `width` nodes base ..
// base + width - 1, the weights N(xi - k) and their derivatives dN/dxi (to be
// divided by h for a spatial gradient).
//
// eval_bounded() does the same on a domain of n cells, 0 <= xi <= n. For the
// B-splines it uses the clamped (open-knot) basis there: docs/theory.md,
// "Boundaries".
#pragma once

#include <algorithm>
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

// One B-spline basis function of degree P (P <= 3) with knots t[0..P+1],
// non-decreasing, and its derivative, at u (Cox-de Boor recursion, de Boor
// 1978, ch. IX; 0/0 = 0 for repeated knots). Intervals are half-open
// [t_j, t_j+1) except at u == end, the right end of the domain, which
// belongs to the last non-empty interval ending there.
template <int P>
inline double bspline_basis(const double *t, double u, double end, double &dN) {
    double N[P + 1];
    for (int j = 0; j <= P; ++j) {
        const bool inside = t[j] <= u && u < t[j + 1];
        const bool right_end = u == end && t[j + 1] == end && t[j] < t[j + 1];
        N[j] = inside || right_end ? 1.0 : 0.0;
    }
    auto ratio = [](double a, double b) { return b > 0.0 ? a / b : 0.0; };
    for (int k = 1; k <= P; ++k) {
        if (k == P) dN = P * (ratio(N[0], t[P] - t[0]) - ratio(N[1], t[P + 1] - t[1]));
        for (int j = 0; j <= P - k; ++j)
            N[j] = ratio(u - t[j], t[j + k] - t[j]) * N[j] +
                   ratio(t[j + k + 1] - u, t[j + k + 1] - t[j + 1]) * N[j + 1];
    }
    if constexpr (P == 0) dN = 0.0;
    return N[0];
}

// The clamped node-centred B-splines of degree P on a domain of n cells.
// Node k's function has the knots of the uniform node-centred spline, k - (P
// + 1)/2 ... k + (P + 1)/2, each clamped into [0, n]. This is the open-knot
// basis of the same spline space restricted to the domain (de Boor 1978;
// Piegl & Tiller 1997, sec. 2.2): partition of unity and linear completeness
// hold, and at a face exactly one function is non-zero (it equals 1), the
// one of the node half a support outside (k = -1 and k = n + 1), so a
// condition on that node's velocity is the condition at the face itself.
// Nodes further out have identically zero functions. Steffen, Kirby &
// Berzins (2008, IJNME 76:922) modify the quadratic B-spline at a boundary
// for the same reason. Also returns each node's Greville abscissa (the mean
// of its P inner knots), the point the node's coefficient represents
// (sum_k g_k N_k(u) = u), for the affine transfers and node selection.
template <int P>
constexpr void clamped_knots(int k, int n, double *t) {
    for (int j = 0; j < P + 2; ++j)
        t[j] = std::clamp(k - 0.5 * (P + 1) + j, 0.0, static_cast<double>(n));
}
template <int P>
inline double clamped_greville(int k, int n) {
    double t[P + 2], s = 0.0;
    clamped_knots<P>(k, n, t);
    for (int j = 1; j <= P; ++j)
        s += t[j];
    return s / P;
}
template <int P, int W>
inline void clamped_bsplines(double u, int n, int base, double *w, double *dw, double *g) {
    for (int a = 0; a < W; ++a) {
        double t[P + 2];
        clamped_knots<P>(base + a, n, t);
        w[a] = bspline_basis<P>(t, u, static_cast<double>(n), dw[a]);
        g[a] = clamped_greville<P>(base + a, n);
    }
}

// sum_a w_a (g_a - xi)^2 over a stencil of W nodes with points g (cells^2):
// the one-axis entry of APIC's D_p.
template <int W>
inline double second_moment(const double *w, const double *g, double xi) {
    double m2 = 0.0;
    for (int k = 0; k < W; ++k)
        m2 += w[k] * (g[k] - xi) * (g[k] - xi);
    return m2;
}

// The clamped functions next to the face u = 0 as polynomials, for a
// domain long enough that the other face's clamping does not reach them:
// on the two knot intervals within interior_margin of the face, [0, a)
// and [a, a + 1) (a = 1/2 for the quadratic, 1 for the cubic), where the
// stencil's first node is -1 and 0, the W functions' coefficients in
// r = u - start. Built by the Cox-de Boor recursion of bspline_basis with
// polynomials in place of numbers (a product with the linear factors
// (u - t_j) / (t_j+k - t_j), the same divisions by knot spans), so they
// are the clamped functions to the round-off of those divisions; the face
// at u = n is their mirror image (node k <-> n - k, u <-> n - u). Horner's
// rule then costs a few multiply-adds where the recursion takes dozens of
// divisions and branches per node
// (bench/results/2026-11-27-epyc-zen4-target-machine.md).
template <int P>
struct ClampedPieces {
    static constexpr int W = P + 1;
    // Intervals' starts, and the domain length from which the faces are
    // independent: the knots of the stencils within the margin of u = 0
    // reach 3.5 (quadratic) and 5 (cubic) cells.
    static constexpr double start[2] = {0.0, P == 2 ? 0.5 : 1.0};
    static constexpr int min_cells = 8;
    // A domain long enough that only the face u = 0 clamps the knots.
    static constexpr int kFar = 1 << 20;
    double c[2][W][P + 1]; // [interval][node of the stencil][power of r]

    constexpr ClampedPieces() : c{} {
        for (int i = 0; i < 2; ++i)
            for (int a = 0; a < W; ++a)
                piece(i - 1 + a, start[i], c[i][a]);
    }

    // Node k's function on the knot interval starting at u0, in r = u - u0.
    static constexpr void piece(int k, double u0, double (&out)[P + 1]) {
        double t[P + 2] = {};
        clamped_knots<P>(k, kFar, t);
        double N[P + 1][P + 1] = {}; // N[j]: coefficients of r^0 .. r^P
        for (int j = 0; j <= P; ++j)
            N[j][0] = t[j] <= u0 && u0 < t[j + 1] ? 1.0 : 0.0;
        for (int k2 = 1; k2 <= P; ++k2)
            for (int j = 0; j <= P - k2; ++j) {
                double next[P + 1] = {};
                const double left = t[j + k2] - t[j], right = t[j + k2 + 1] - t[j + 1];
                // (u0 - t_j + r) / left times N_j, (t_j+k+1 - u0 - r) / right
                // times N_j+1 (0/0 = 0 for repeated knots).
                for (int q = 0; q < P; ++q) {
                    if (left > 0.0) {
                        next[q] += (u0 - t[j]) / left * N[j][q];
                        next[q + 1] += N[j][q] / left;
                    }
                    if (right > 0.0) {
                        next[q] += (t[j + k2 + 1] - u0) / right * N[j + 1][q];
                        next[q + 1] -= N[j + 1][q] / right;
                    }
                }
                for (int q = 0; q <= P; ++q)
                    N[j][q] = next[q];
            }
        for (int q = 0; q <= P; ++q)
            out[q] = N[0][q];
    }

    // The W functions and their derivatives (d/du) at r of interval i, for
    // nodes in order (mirror: the upper face's order and sign).
    void eval(int i, double r, bool mirror, double *w, double *dw) const {
        for (int a = 0; a < W; ++a) {
            const double *q = c[i][mirror ? W - 1 - a : a];
            double v = q[P], d = P * q[P];
            for (int j = P - 1; j >= 0; --j) {
                v = q[j] + r * v;
                if (j > 0) d = j * q[j] + r * d;
            }
            w[a] = v;
            dw[a] = mirror ? -d : d;
        }
    }
};
template <int P>
inline constexpr ClampedPieces<P> kClampedPieces{};

// eval_bounded() of the B-splines: the uniform kernel where interior() says
// it holds (almost everywhere), the clamped functions next to the faces.
template <class S, int P>
inline void bounded_bspline(double xi, int n, int &base, double *w, double *dw, double *g) {
    xi = std::clamp(xi, 0.0, static_cast<double>(n));
    S::eval(xi, 0.0, base, w, dw);
    if (S::interior(xi, n)) {
        for (int k = 0; k < S::width; ++k)
            g[k] = base + k;
        return;
    }
    // Next to one face only, the pieces: interval 0 or 1 where the
    // stencil's first node is -1 or 0 counted from the face (at the upper
    // face, back from n). At a face's exact point for the cubic (a stencil
    // one node further out) and on short domains, the recursion.
    using Pieces = ClampedPieces<P>;
    const int lower = base + 1, upper = n - (base + S::width - 1) + 1;
    const bool at_lower = lower == 0 || lower == 1, at_upper = upper == 0 || upper == 1;
    if (n >= Pieces::min_cells && (at_lower || at_upper)) {
        const bool mirror = !at_lower;
        const int i = mirror ? upper : lower;
        const double u = mirror ? n - xi : xi;
        kClampedPieces<P>.eval(i, u - Pieces::start[i], mirror, w, dw);
        for (int a = 0; a < S::width; ++a)
            g[a] = clamped_greville<P>(base + a, n);
        return;
    }
    clamped_bsplines<P, S::width>(xi, n, base, w, dw, g);
}

// Linear ("tent") functions, the original MPM of Sulsky et al. (1994).
struct LinearShape {
    static constexpr int width = 2;
    static constexpr bool half_width = false;
    static inline void eval(double xi, double /*lp*/, int &base, double *w, double *dw) {
        const double fl = fast_floor(xi);
        base = static_cast<int>(fl);
        const double r = xi - fl; // in [0, 1)
        w[0] = 1.0 - r;
        w[1] = r;
        dw[0] = -1.0;
        dw[1] = 1.0;
    }
    // Where eval() is also eval_bounded() (the kernels' hot paths test this
    // once per particle and leave the rest out of line).
    static constexpr bool interior(double /*xi*/, int /*n*/) { return true; }
    // Already interpolating at the faces: the node on a face carries it.
    static inline void eval_bounded(double xi, double lp, int /*n*/, int &base, double *w,
                                    double *dw, double *g) {
        eval(xi, lp, base, w, dw);
        g[0] = base;
        g[1] = base + 1;
    }
};

// Uniform GIMP (Bardenhagen & Kober 2004): the tent function convolved with a
// particle characteristic function of half-width lp (in cells, lp <= 1/2),
// lp fixed at its initial value 1/(2 ppc) ("u" for undeformed).
struct GimpShape {
    static constexpr int width = 3;
    static constexpr bool half_width = true; // eval reads lp
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
    static constexpr bool interior(double /*xi*/, int /*n*/) { return true; }
    // Unchanged at the faces: a particle's domain may reach into the ghost
    // layer; the face and ghost nodes carry the face's condition.
    static inline void eval_bounded(double xi, double lp, int /*n*/, int &base, double *w,
                                    double *dw, double *g) {
        eval(xi, lp, base, w, dw);
        for (int k = 0; k < 3; ++k)
            g[k] = base + k;
    }
};

// What the uniform B-splines share, from Self's floor_shift, base_offset,
// interior_margin and pieces: eval() in two parts, the second for a double
// or a vector of them (one point a lane, the transfer kernels' packs):
// fl = floor(xi - floor_shift), the first node base = fl + base_offset,
// and the polynomial pieces; and interior(), where the clamped functions
// are these uniform ones (xi at least interior_margin from either face).
template <class Self>
struct UniformBSpline {
    static inline void eval(double xi, double /*lp*/, int &base, double *w, double *dw) {
        const double fl = fast_floor(xi - Self::floor_shift);
        base = static_cast<int>(fl) + Self::base_offset;
        Self::pieces(xi, fl, w, dw);
    }
    static bool interior(double xi, int n) {
        return xi >= Self::interior_margin && xi < n - Self::interior_margin;
    }
};

// Quadratic B-spline (Steffen et al. 2008; seed 000 eqs. 24-25), node-centred.
struct BSpline2Shape : UniformBSpline<BSpline2Shape> {
    static constexpr int width = 3;
    static constexpr bool half_width = false;
    static constexpr double floor_shift = 0.5;
    static constexpr int base_offset = 0;
    template <class T>
    [[gnu::always_inline]] static inline void pieces(const T &xi, const T &fl, T *w, T *dw) {
        const T r0 = xi - fl;  // distance to node base, in [0.5, 1.5)
        const T a = 1.5 - r0;  // in (0, 1]
        const T r1 = r0 - 1.0; // in [-0.5, 0.5)
        const T c = r0 - 0.5;  // 1.5 + r2, in [0, 1)
        w[0] = 0.5 * a * a;
        w[1] = 0.75 - r1 * r1;
        w[2] = 0.5 * c * c;
        dw[0] = -a;
        dw[1] = -2.0 * r1;
        dw[2] = c;
    }
    // Where the clamped functions are the uniform ones: a B-spline's piece
    // on its last knot interval, (t_p+1 - x)^p / prod_j=1..p (t_p+1 - t_j),
    // depends on its inner knots only, and node 1's (1/2, 3/2) are not
    // clamped; the first pieces mirror this at the upper face. So only
    // 0 <= xi < 3/2 (and n - 3/2 <= xi <= n) differ (tested).
    static constexpr double interior_margin = 1.5;
    static void eval_bounded(double xi, double /*lp*/, int n, int &base, double *w, double *dw,
                             double *g) {
        bounded_bspline<BSpline2Shape, 2>(xi, n, base, w, dw, g);
    }
};

// Cubic B-spline (Steffen et al. 2008), node-centred.
struct BSpline3Shape : UniformBSpline<BSpline3Shape> {
    static constexpr int width = 4;
    static constexpr bool half_width = false;
    static constexpr double floor_shift = 0.0;
    static constexpr int base_offset = -1;
    template <class T>
    [[gnu::always_inline]] static inline void pieces(const T &xi, const T &fl, T *w, T *dw) {
        const T t = xi - fl; // in [0, 1)
        const T u = 1.0 - t;
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
    // As for the quadratic: node 1's inner knots (0, 1, 2) are unclamped, so
    // only 0 <= xi < 2 (and n - 2 <= xi <= n) differ (tested).
    static constexpr double interior_margin = 2.0;
    static void eval_bounded(double xi, double /*lp*/, int n, int &base, double *w, double *dw,
                             double *g) {
        bounded_bspline<BSpline3Shape, 3>(xi, n, base, w, dw, g);
    }
};

// Nodes of the stencil beyond the domain on each side: the grid carries this
// many ghost layers so that every kernel keeps partition of unity near a
// boundary.
inline constexpr int kGhostLayers = 2;

// The point node k stands for on a domain of n cells, in cells: the node
// itself, or for the clamped B-splines its Greville abscissa (which moves
// only for the nodes next to a face).
inline double node_greville(ShapeKind kind, int k, int n) {
    if (kind == ShapeKind::bspline2) return clamped_greville<2>(k, n);
    if (kind == ShapeKind::bspline3) return clamped_greville<3>(k, n);
    return k;
}

// The layer of nodes, counted outward from a face (0: the node on the face),
// whose function is the one non-zero at the face: a face condition applies
// to it and to the layers beyond (whose functions vanish in the domain or,
// for GIMP, reach it only through a particle's own extent).
constexpr int face_layer(ShapeKind k) {
    return k == ShapeKind::bspline2 || k == ShapeKind::bspline3 ? 1 : 0;
}

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
