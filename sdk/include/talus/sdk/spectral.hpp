// talus/sdk/spectral.hpp -- the spectral decomposition of a symmetric 3 x 3
// matrix (a stress or a strain), ordered, for models written in principal
// space.
//
// Without iteration, and as accurate as an iterative solver: the residual
// |V diag(l) V^T - A| and the values' errors are a few units of round-off
// of |A|, V is orthonormal to round-off, whatever the spacing of the values
// (two or three equal included, where the closed form of the characteristic
// cubic alone loses half the digits).
//
// The method (as in D. Eberly, "A robust eigensolver for 3 x 3 symmetric
// matrices", Geometric Tools, 2014): with A = q I + C (q the mean of the
// diagonal, so C has trace 0), the value of C farthest from the other two
// is the largest root of its characteristic cubic when det C >= 0, else the
// smallest (O. K. Smith, Comm. ACM 4 (1961) 168). That root is simple and
// at least sqrt(3) p from the other two (p^2 = tr(C^2) / 6), so the cubic
// gives it to round-off and C - x I has rank 2: its eigenvector is the
// largest cross product of two of its rows (the rows of adj(C - x I) are
// multiples of it). The two remaining values and vectors are those of C
// restricted to the plane normal to it, a 2 x 2 symmetric problem solved in
// closed form without cancellation. The values are Rayleigh quotients of C.
//
// A matrix whose entries (0, 2) and (1, 2) are exactly zero (a plane-strain
// or plane-stress stress or strain: the out-of-plane shears vanish) is
// block diagonal: its third entry is a value with the axis e_z, and the
// in-plane 2 x 2 block is solved by the same closed form, without the
// cubic (a fifth of the work).
#pragma once

#include "talus/sdk/voigt.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

#if defined(__SSE2__)
#include <emmintrin.h>
#endif

namespace talus::sdk {

struct SymmetricEigen {
    Eigen::Vector3d values; // descending: values[0] >= values[1] >= values[2]
    Mat3 vectors;           // column k: the unit eigenvector of values[k]
    // V diag(s) V^T: a matrix with these principal directions and the
    // principal values s (an isotropic function's result).
    Mat3 compose(const Eigen::Vector3d &s) const {
        return vectors * s.asDiagonal() * vectors.transpose();
    }
    // The same as a stress-like Voigt vector (xx, yy, zz, xy, yz, xz), its
    // six components only.
    Vec6 compose_stress(const Eigen::Vector3d &s) const {
        const Mat3 &v = vectors;
        auto entry = [&](int i, int j) {
            return s[0] * v(i, 0) * v(j, 0) + s[1] * v(i, 1) * v(j, 1) + s[2] * v(i, 2) * v(j, 2);
        };
        Vec6 out;
        out << entry(0, 0), entry(1, 1), entry(2, 2), entry(0, 1), entry(1, 2), entry(0, 2);
        return out;
    }
};

namespace detail {

// The decomposition below is written once over a lane type T: a double (one
// matrix), or with GCC and clang a vector of two doubles (two matrices side
// by side, in the x86-64 baseline's SSE2 registers, so that a pair costs
// about what one matrix did: the decomposition is bound by its instruction
// count, not its latency). Every lane operation is the IEEE operation of the
// scalar code, in the same order, so each lane's bits are those of the
// scalar decomposition. The helpers below give both types one spelling.
#if defined(__GNUC__) || defined(__clang__)
#define TALUS_SDK_HAS_LANE_PAIR 1
using LanePair = double __attribute__((vector_size(16)));
// What comparing two LanePairs gives: all ones or zeros per lane.
using LanePairMask = decltype(LanePair{} < LanePair{});

inline LanePair lane_select(LanePairMask c, LanePair a, LanePair b) {
    return (LanePair)(((LanePairMask)a & c) | ((LanePairMask)b & ~c));
}
inline LanePairMask lane_and(LanePairMask a, LanePairMask b) { return a & b; }
inline LanePairMask lane_not(LanePairMask a) { return ~a; }
inline bool lane_any(LanePairMask a) { return (a[0] | a[1]) != 0; }
inline LanePair lane_abs(LanePair x) {
    return (LanePair)((LanePairMask)x & (LanePairMask{} + 0x7fffffffffffffffLL));
}
inline LanePair lane_copysign(LanePair magnitude, LanePair sign) {
    const LanePairMask bit = LanePairMask{} + static_cast<long long>(0x8000000000000000ULL);
    return (LanePair)(((LanePairMask)magnitude & ~bit) | ((LanePairMask)sign & bit));
}
inline LanePair lane_sqrt(LanePair x) {
    // Correctly rounded in either form. Lane by lane, GCC keeps std::sqrt's
    // errno path (a branch and a call per lane).
#if defined(__SSE2__)
    return (LanePair)_mm_sqrt_pd((__m128d)x);
#else
    return LanePair{std::sqrt(x[0]), std::sqrt(x[1])};
#endif
}
#endif

inline double lane_select(bool c, double a, double b) { return c ? a : b; }
inline bool lane_and(bool a, bool b) { return a && b; }
inline bool lane_not(bool a) { return !a; }
inline bool lane_any(bool a) { return a; }
inline double lane_abs(double x) { return std::abs(x); }
inline double lane_copysign(double magnitude, double sign) {
    return std::copysign(magnitude, sign);
}
inline double lane_sqrt(double x) { return std::sqrt(x); }
// std::max's and std::clamp's comparisons (the same NaN behaviour).
template <class T>
T lane_max(T a, T b) {
    return lane_select(a < b, b, a);
}
template <class T>
T lane_clamp(T v, T lo, T hi) {
    return lane_select(v < lo, lo, lane_select(hi < v, hi, v));
}

// The largest root of y^3 - 3 y - 2 s for s in [0, 1], in [sqrt(3), 2]
// (2 cos(acos(s) / 3), Smith's formula, without its acos and cos): a
// least-squares quintic in s (within 1.2e-6 on [0, 1]) and one step of
// Halley's method, whose error is about the cube of the start's (the
// derivative 3 y^2 - 3 is at least 6 there): within an ulp at 20001
// points of [0, 1], tested against Smith's formula.
template <class T>
T largest_cubic_root(T s) {
    // Estrin's scheme: three independent pairs, then two levels.
    const T s2 = s * s, s4 = s2 * s2;
    const T y = (1.7320519648963821 + 0.3332451278684757 * s) +
                s2 * (-0.095107251581874 + 0.043955570613302984 * s) +
                s4 * (-0.018108343307837876 + 0.003963812960511424 * s);
    const T f = y * (y * y - 3.0) - 2.0 * s, d1 = 3.0 * (y * y - 1.0), d2 = 6.0 * y;
    return y - 2.0 * f * d1 / (2.0 * d1 * d1 - f * d2);
}

// The 2 x 2 symmetric problem [m00 b; b m11] with h = (m11 - m00) / 2, in
// closed form: its values are the mean +- g, g = hypot(h, b), and (s0, s1)
// the unit vector of the value on h's side, mean + sign(h) g: (b, h +
// sign(h) g) normalised, whose second component has no cancellation (its
// norm^2 is 2 g (g + |h|)). g = 0 is a double value, any basis: (0, 1).
// The other value's vector is (s1, -s0).
template <class T>
void rotation_2x2(T h, T b, T &g, T &s0, T &s1) {
    const T zero = T(), one = zero + 1.0;
    g = lane_sqrt(h * h + b * b);
    const auto split = g > 0.0;
    const T k = lane_select(split, 1.0 / lane_sqrt(2.0 * g * (g + lane_abs(h))), zero);
    s0 = lane_select(split, b * k, zero);
    s1 = lane_select(split, (h + lane_copysign(g, h)) * k, one);
}

// The decomposition of the lanes of C = A - q I (upper triangle c..), up to
// the ordering: the values l[3] (Rayleigh quotients of C, unscaled) and
// their vectors vec[3][3], per lane.
template <class T>
struct Unordered {
    T q, scale;
    T l[3];
    T vec[3][3];
};

template <class T>
Unordered<T> unordered_eigen(T a00, T a11, T a22, T a01, T a02, T a12) {
    Unordered<T> out;
    // Products by the constants 1/3 and 1/6 rather than divisions: these
    // start the chain of dependent operations. (Any shift q serves; p2 only
    // scales the cubic.)
    const T q = (a00 + a11 + a22) * (1.0 / 3.0);
    T c00 = a00 - q, c11 = a11 - q, c22 = a22 - q;
    T c01 = a01, c02 = a02, c12 = a12;
    const T m =
        lane_max(lane_max(lane_max(lane_max(lane_max(lane_abs(c00), lane_abs(c11)), lane_abs(c22)),
                                   lane_abs(c01)),
                          lane_abs(c02)),
                 lane_abs(c12));
    // The squares of squares below (the cross products' norms, ~m^4)
    // neither under- nor overflow for m in [1e-60, 1e60]; beyond, C is
    // scaled to m = 1 (rarely: that division is then on the critical path;
    // a lane in range is multiplied by 1, which changes no bit).
    const T one = T() + 1.0, zero = T();
    T scale = one;
    const auto out_of_range = lane_not(lane_and(m > 1e-60, m < 1e60));
    if (lane_any(out_of_range)) {
        scale = lane_select(out_of_range, m, one);
        const T inv = lane_select(out_of_range, 1.0 / m, one);
        c00 *= inv;
        c11 *= inv;
        c22 *= inv;
        c01 *= inv;
        c02 *= inv;
        c12 *= inv;
    }
    const T p2 = (c00 * c00 + c11 * c11 + c22 * c22 + 2.0 * (c01 * c01 + c02 * c02 + c12 * c12)) *
                 (1.0 / 6.0);
    const T p = lane_sqrt(p2);
    const T det = c00 * (c11 * c22 - c12 * c12) - c01 * (c01 * c22 - c12 * c02) +
                  c02 * (c01 * c12 - c11 * c02);
    // det(C / p) / 2 in [-1, 1] (up to round-off), as det p / (2 p2^2) so
    // that the square root and the division run side by side; for det < 0
    // the largest root of -C's cubic, negated.
    const T r = lane_clamp(det * p * (1.0 / (2.0 * p2 * p2)), -one, one);
    const T x = lane_copysign(largest_cubic_root(lane_abs(r)) * p, r);
    // The rows of C - x I; their largest cross product is along the vector.
    const T d0 = c00 - x, d1 = c11 - x, d2 = c22 - x;
    // r0 x r1, r0 x r2, r1 x r2 for the rows r0 = (d0, c01, c02), r1 =
    // (c01, d1, c12), r2 = (c02, c12, d2).
    const T a0 = c01 * c12 - c02 * d1, a1 = c02 * c01 - d0 * c12, a2 = d0 * d1 - c01 * c01;
    const T b0 = c01 * d2 - c02 * c12, b1 = c02 * c02 - d0 * d2, b2 = d0 * c12 - c01 * c02;
    const T e0 = d1 * d2 - c12 * c12, e1 = c12 * c02 - c01 * d2, e2 = c01 * c12 - d1 * c02;
    const T na = a0 * a0 + a1 * a1 + a2 * a2, nb = b0 * b0 + b1 * b1 + b2 * b2,
            ne = e0 * e0 + e1 * e1 + e2 * e2;
    const auto pick_a = lane_and(na >= nb, na >= ne), pick_b = lane_and(lane_not(pick_a), nb >= ne);
    const T y0 = lane_select(pick_a, a0, lane_select(pick_b, b0, e0));
    const T y1 = lane_select(pick_a, a1, lane_select(pick_b, b1, e1));
    const T y2 = lane_select(pick_a, a2, lane_select(pick_b, b2, e2));
    const T ny = lane_select(pick_a, na, lane_select(pick_b, nb, ne));
    // An orthonormal basis u, w of the plane normal to v = y / |y|: u
    // leaves out a component of y that is not the largest, so its norm is
    // at least |y| / sqrt(2). Both norms from y, so that their square roots
    // run side by side.
    const auto drop1 = lane_abs(y0) > lane_abs(y1);
    const T iy = 1.0 / lane_sqrt(ny);
    const T iu = 1.0 / lane_sqrt(lane_select(drop1, y0 * y0, y1 * y1) + y2 * y2);
    const T v0 = y0 * iy, v1 = y1 * iy, v2 = y2 * iy;
    const T u0 = lane_select(drop1, -y2 * iu, zero), u1 = lane_select(drop1, zero, y2 * iu),
            u2 = lane_select(drop1, y0 * iu, -y1 * iu);
    const T w0 = v1 * u2 - v2 * u1, w1 = v2 * u0 - v0 * u2, w2 = v0 * u1 - v1 * u0;
    // C u, C w, C v and the Rayleigh quotients.
    const T cu0 = c00 * u0 + c01 * u1 + c02 * u2, cu1 = c01 * u0 + c11 * u1 + c12 * u2,
            cu2 = c02 * u0 + c12 * u1 + c22 * u2;
    const T cw0 = c00 * w0 + c01 * w1 + c02 * w2, cw1 = c01 * w0 + c11 * w1 + c12 * w2,
            cw2 = c02 * w0 + c12 * w1 + c22 * w2;
    const T cv0 = c00 * v0 + c01 * v1 + c02 * v2, cv1 = c01 * v0 + c11 * v1 + c12 * v2,
            cv2 = c02 * v0 + c12 * v1 + c22 * v2;
    const T m00 = u0 * cu0 + u1 * cu1 + u2 * cu2, m01 = u0 * cw0 + u1 * cw1 + u2 * cw2,
            m11 = w0 * cw0 + w1 * cw1 + w2 * cw2, lv = v0 * cv0 + v1 * cv1 + v2 * cv2;
    // The 2 x 2 problem [m00 m01; m01 m11] in the basis (u, w).
    const T h = 0.5 * (m11 - m00), mean = 0.5 * (m00 + m11);
    T g, s0, s1;
    rotation_2x2(h, m01, g, s0, s1);
    // side = s0 u + s1 w belongs to mean + sign(h) g; other = s1 u - s0 w to
    // mean - sign(h) g.
    out.q = q;
    out.scale = scale;
    out.l[0] = lv;
    out.l[1] = mean + lane_copysign(g, h);
    out.l[2] = mean - lane_copysign(g, h);
    out.vec[0][0] = v0;
    out.vec[0][1] = v1;
    out.vec[0][2] = v2;
    out.vec[1][0] = s0 * u0 + s1 * w0;
    out.vec[1][1] = s0 * u1 + s1 * w1;
    out.vec[1][2] = s0 * u2 + s1 * w2;
    out.vec[2][0] = s1 * u0 - s0 * w0;
    out.vec[2][1] = s1 * u1 - s0 * w1;
    out.vec[2][2] = s1 * u2 - s0 * w2;
    return out;
}

// One lane's result, ordered. `identity`: C = 0 (q I has any basis).
inline void order_lane(double q, double scale, const double l[3], const double vec[3][3],
                       bool identity, SymmetricEigen &out) {
    if (identity) {
        out.values.setConstant(q);
        out.vectors.setIdentity();
        return;
    }
    // Each value's place in descending order (ties by index), without
    // branches.
    const int rank[3] = {int(l[1] > l[0]) + int(l[2] > l[0]), int(l[0] >= l[1]) + int(l[2] > l[1]),
                         int(l[0] >= l[2]) + int(l[1] >= l[2])};
    // A NaN value compares false and two ranks then meet: the place left
    // empty keeps NaN, so that NaN in gives NaN out.
    out.values.setConstant(std::numeric_limits<double>::quiet_NaN());
    out.vectors.setConstant(std::numeric_limits<double>::quiet_NaN());
    for (int i = 0; i < 3; ++i) {
        out.values[rank[i]] = q + scale * l[i];
        for (int j = 0; j < 3; ++j)
            out.vectors(j, rank[i]) = vec[i][j];
    }
}

// C = 0 exactly. (The sum is NaN when an entry is, which the maximum does
// not see: that case goes on and gives NaN.)
inline bool is_multiple_of_identity(const Mat3 &a) {
    const double q = (a(0, 0) + a(1, 1) + a(2, 2)) * (1.0 / 3.0);
    const double c00 = a(0, 0) - q, c11 = a(1, 1) - q, c22 = a(2, 2) - q;
    const double m = std::max({std::abs(c00), std::abs(c11), std::abs(c22), std::abs(a(0, 1)),
                               std::abs(a(0, 2)), std::abs(a(1, 2))});
    return m == 0.0 && c00 + c11 + c22 + a(0, 1) + a(0, 2) + a(1, 2) == 0.0;
}

// The entries (0, 2) and (1, 2) are exactly zero (NaN is not).
inline bool is_plane(const Mat3 &a) { return a(0, 2) == 0.0 && a(1, 2) == 0.0; }

// The decomposition of a plane matrix (is_plane): the value a(2, 2) on the
// axis e_z and the in-plane block [a00 a01; a01 a11] in closed form
// (rotation_2x2). The block's values have the absolute error of a few
// round-offs of its largest entry (backward stable).
inline void plane_eigen(const Mat3 &a, SymmetricEigen &out) {
    if (is_multiple_of_identity(a)) { // q I has any basis: the axes
        out.values.setConstant(a(0, 0));
        out.vectors.setIdentity();
        return;
    }
    const double a00 = a(0, 0), a11 = a(1, 1), a01 = a(0, 1);
    // Halves first: exact, and no overflow near the largest doubles.
    const double h = 0.5 * a11 - 0.5 * a00, mean = 0.5 * a00 + 0.5 * a11;
    // h^2 + a01^2 and the vector's norm neither under- nor overflow for
    // entries in [1e-150, 1e150]; beyond, the block is scaled (rarely; a
    // direction does not depend on the scale).
    const double m = std::max(std::abs(h), std::abs(a01));
    double hs = h, bs = a01, scale = 1.0;
    if (!(m > 1e-150 && m < 1e150) && m > 0.0) {
        scale = m;
        hs = h / m;
        bs = a01 / m;
    }
    // NaN in h or a01 reaches gs (the maximum may have dropped it), and
    // from it the values.
    double gs, s0, s1;
    rotation_2x2(hs, bs, gs, s0, s1);
    const double g = scale * gs;
    const double l[3] = {a(2, 2), mean + std::copysign(g, h), mean - std::copysign(g, h)};
    const double vec[3][3] = {{0.0, 0.0, 1.0}, {s0, s1, 0.0}, {s1, -s0, 0.0}};
    order_lane(0.0, 1.0, l, vec, /*identity=*/false, out);
}

} // namespace detail

namespace detail {

// The decompositions of a and b, side by side where the compiler has the
// lane pair; eb may be null (a alone).
inline void general_eigen_lanes(const Mat3 &a, const Mat3 &b, SymmetricEigen &ea,
                                SymmetricEigen *eb) {
#if defined(TALUS_SDK_HAS_LANE_PAIR)
    using T = LanePair;
    const Unordered<T> u =
        unordered_eigen<T>(T{a(0, 0), b(0, 0)}, T{a(1, 1), b(1, 1)}, T{a(2, 2), b(2, 2)},
                           T{a(0, 1), b(0, 1)}, T{a(0, 2), b(0, 2)}, T{a(1, 2), b(1, 2)});
    for (int lane = 0; lane < (eb ? 2 : 1); ++lane) {
        double l[3], vec[3][3];
        for (int i = 0; i < 3; ++i) {
            l[i] = u.l[i][lane];
            for (int j = 0; j < 3; ++j)
                vec[i][j] = u.vec[i][j][lane];
        }
        const Mat3 &m = lane == 0 ? a : b;
        order_lane(u.q[lane], u.scale[lane], l, vec, is_multiple_of_identity(m),
                   lane == 0 ? ea : *eb);
    }
#else
    for (int lane = 0; lane < (eb ? 2 : 1); ++lane) {
        const Mat3 &m = lane == 0 ? a : b;
        const Unordered<double> u =
            unordered_eigen<double>(m(0, 0), m(1, 1), m(2, 2), m(0, 1), m(0, 2), m(1, 2));
        order_lane(u.q, u.scale, u.l, u.vec, is_multiple_of_identity(m), lane == 0 ? ea : *eb);
    }
#endif
}

inline void symmetric_eigen_lanes(const Mat3 &a, const Mat3 &b, SymmetricEigen &ea,
                                  SymmetricEigen *eb) {
    // Plane matrices in closed form, each by itself, so that a matrix's
    // bits do not depend on its partner; the others as below.
    const bool plane_a = is_plane(a), plane_b = eb && is_plane(b);
    if (plane_a) plane_eigen(a, ea);
    if (plane_b) plane_eigen(b, *eb);
    if (plane_a && (!eb || plane_b)) return;
    if (plane_a) return general_eigen_lanes(b, b, *eb, nullptr);
    if (eb && plane_b) return general_eigen_lanes(a, a, ea, nullptr);
    general_eigen_lanes(a, b, ea, eb);
}

} // namespace detail

// The ordered spectral decomposition of the symmetric matrix a (its upper
// triangle is read). NaN in gives NaN out.
inline SymmetricEigen symmetric_eigen(const Mat3 &a) {
    // In the lane pair's first lane (the second idle), so that a matrix's
    // bits do not depend on whether it was decomposed alone or in a pair,
    // whatever the compiler contracts into fused multiply-adds.
    SymmetricEigen out;
    detail::symmetric_eigen_lanes(a, a, out, nullptr);
    return out;
}

// The ordered spectral decompositions of two symmetric matrices, side by
// side: each is bit for bit what symmetric_eigen gives for it, and the two
// cost about what one does (for models that take points in pairs,
// material.hpp).
inline void symmetric_eigen_pair(const Mat3 &a, const Mat3 &b, SymmetricEigen &ea,
                                 SymmetricEigen &eb) {
    detail::symmetric_eigen_lanes(a, b, ea, &eb);
}

} // namespace talus::sdk
