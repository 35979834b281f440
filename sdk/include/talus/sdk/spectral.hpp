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
#pragma once

#include "talus/sdk/voigt.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

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

// The largest root of y^3 - 3 y - 2 s for s in [0, 1], in [sqrt(3), 2]
// (2 cos(acos(s) / 3), Smith's formula, without its acos and cos): a
// least-squares quintic in s (within 1.2e-6 on [0, 1]) and one step of
// Halley's method, whose error is about the cube of the start's (the
// derivative 3 y^2 - 3 is at least 6 there): within an ulp at 20001
// points of [0, 1], tested against Smith's formula.
inline double largest_cubic_root(double s) {
    // Estrin's scheme: three independent pairs, then two levels.
    const double s2 = s * s, s4 = s2 * s2;
    const double y = (1.7320519648963821 + 0.3332451278684757 * s) +
                     s2 * (-0.095107251581874 + 0.043955570613302984 * s) +
                     s4 * (-0.018108343307837876 + 0.003963812960511424 * s);
    const double f = y * (y * y - 3.0) - 2.0 * s, d1 = 3.0 * (y * y - 1.0), d2 = 6.0 * y;
    return y - 2.0 * f * d1 / (2.0 * d1 * d1 - f * d2);
}

} // namespace detail

// The ordered spectral decomposition of the symmetric matrix a (its upper
// triangle is read). NaN in a gives NaN out.
inline SymmetricEigen symmetric_eigen(const Mat3 &a) {
    SymmetricEigen out;
    // Products by the constants 1/3 and 1/6 rather than divisions: these
    // start the chain of dependent operations. (Any shift q serves; p2 only
    // scales the cubic.)
    const double q = (a(0, 0) + a(1, 1) + a(2, 2)) * (1.0 / 3.0);
    double c00 = a(0, 0) - q, c11 = a(1, 1) - q, c22 = a(2, 2) - q;
    double c01 = a(0, 1), c02 = a(0, 2), c12 = a(1, 2);
    const double m = std::max(
        {std::abs(c00), std::abs(c11), std::abs(c22), std::abs(c01), std::abs(c02), std::abs(c12)});
    // q I has any basis. (The sum is NaN when an entry is, which max does
    // not see: that case goes on and gives NaN.)
    if (m == 0.0 && c00 + c11 + c22 + c01 + c02 + c12 == 0.0) {
        out.values.setConstant(q);
        out.vectors.setIdentity();
        return out;
    }
    // The squares of squares below (the cross products' norms, ~m^4)
    // neither under- nor overflow for m in [1e-60, 1e60]; beyond, C is
    // scaled to m = 1 (rarely: that division is then on the critical path).
    double scale = 1.0;
    if (!(m > 1e-60 && m < 1e60)) {
        scale = m;
        const double inv = 1.0 / m;
        c00 *= inv;
        c11 *= inv;
        c22 *= inv;
        c01 *= inv;
        c02 *= inv;
        c12 *= inv;
    }
    const double p2 =
        (c00 * c00 + c11 * c11 + c22 * c22 + 2.0 * (c01 * c01 + c02 * c02 + c12 * c12)) *
        (1.0 / 6.0);
    const double p = std::sqrt(p2);
    const double det = c00 * (c11 * c22 - c12 * c12) - c01 * (c01 * c22 - c12 * c02) +
                       c02 * (c01 * c12 - c11 * c02);
    // det(C / p) / 2 in [-1, 1] (up to round-off), as det p / (2 p2^2) so
    // that the square root and the division run side by side; for det < 0
    // the largest root of -C's cubic, negated.
    const double r = std::clamp(det * p * (1.0 / (2.0 * p2 * p2)), -1.0, 1.0);
    const double x = std::copysign(detail::largest_cubic_root(std::abs(r)) * p, r);
    // The rows of C - x I; their largest cross product is along the vector.
    // In scalars: as small Eigen vectors they went through the stack.
    const double d0 = c00 - x, d1 = c11 - x, d2 = c22 - x;
    // r0 x r1, r0 x r2, r1 x r2 for the rows r0 = (d0, c01, c02), r1 =
    // (c01, d1, c12), r2 = (c02, c12, d2).
    const double a0 = c01 * c12 - c02 * d1, a1 = c02 * c01 - d0 * c12, a2 = d0 * d1 - c01 * c01;
    const double b0 = c01 * d2 - c02 * c12, b1 = c02 * c02 - d0 * d2, b2 = d0 * c12 - c01 * c02;
    const double e0 = d1 * d2 - c12 * c12, e1 = c12 * c02 - c01 * d2, e2 = c01 * c12 - d1 * c02;
    const double na = a0 * a0 + a1 * a1 + a2 * a2, nb = b0 * b0 + b1 * b1 + b2 * b2,
                 ne = e0 * e0 + e1 * e1 + e2 * e2;
    const bool pick_a = na >= nb && na >= ne, pick_b = !pick_a && nb >= ne;
    const double y0 = pick_a ? a0 : pick_b ? b0 : e0;
    const double y1 = pick_a ? a1 : pick_b ? b1 : e1;
    const double y2 = pick_a ? a2 : pick_b ? b2 : e2;
    const double ny = pick_a ? na : pick_b ? nb : ne;
    // An orthonormal basis u, w of the plane normal to v = y / |y|: u
    // leaves out a component of y that is not the largest, so its norm is
    // at least |y| / sqrt(2). Both norms from y, so that their square roots
    // run side by side.
    const bool drop1 = std::abs(y0) > std::abs(y1);
    const double iy = 1.0 / std::sqrt(ny);
    const double iu = 1.0 / std::sqrt((drop1 ? y0 * y0 : y1 * y1) + y2 * y2);
    const double v0 = y0 * iy, v1 = y1 * iy, v2 = y2 * iy;
    const double u0 = drop1 ? -y2 * iu : 0.0, u1 = drop1 ? 0.0 : y2 * iu,
                 u2 = drop1 ? y0 * iu : -y1 * iu;
    const double w0 = v1 * u2 - v2 * u1, w1 = v2 * u0 - v0 * u2, w2 = v0 * u1 - v1 * u0;
    // C u, C w, C v and the Rayleigh quotients.
    const double cu0 = c00 * u0 + c01 * u1 + c02 * u2, cu1 = c01 * u0 + c11 * u1 + c12 * u2,
                 cu2 = c02 * u0 + c12 * u1 + c22 * u2;
    const double cw0 = c00 * w0 + c01 * w1 + c02 * w2, cw1 = c01 * w0 + c11 * w1 + c12 * w2,
                 cw2 = c02 * w0 + c12 * w1 + c22 * w2;
    const double cv0 = c00 * v0 + c01 * v1 + c02 * v2, cv1 = c01 * v0 + c11 * v1 + c12 * v2,
                 cv2 = c02 * v0 + c12 * v1 + c22 * v2;
    const double m00 = u0 * cu0 + u1 * cu1 + u2 * cu2, m01 = u0 * cw0 + u1 * cw1 + u2 * cw2,
                 m11 = w0 * cw0 + w1 * cw1 + w2 * cw2, lv = v0 * cv0 + v1 * cv1 + v2 * cv2;
    // The 2 x 2 problem [m00 m01; m01 m11] in closed form: values mean +- g,
    // g = hypot(h, m01), h = (m11 - m00) / 2, and the vector of the value
    // on h's side, (m01, h + sign(h) g) in the basis (u, w), whose second
    // component has no cancellation; its norm^2 is 2 g (g + |h|). g = 0 is
    // a double value, any basis of the plane.
    const double h = 0.5 * (m11 - m00), mean = 0.5 * (m00 + m11);
    const double g = std::sqrt(h * h + m01 * m01);
    const double k = g > 0.0 ? 1.0 / std::sqrt(2.0 * g * (g + std::abs(h))) : 0.0;
    const double s0 = g > 0.0 ? m01 * k : 0.0, s1 = g > 0.0 ? (h + std::copysign(g, h)) * k : 1.0;
    // side = s0 u + s1 w belongs to mean + sign(h) g; other = s1 u - s0 w to
    // mean - sign(h) g.
    const double l_side = mean + std::copysign(g, h), l_other = mean - std::copysign(g, h);
    const double l[3] = {lv, l_side, l_other};
    const double vec[3][3] = {{v0, v1, v2},
                              {s0 * u0 + s1 * w0, s0 * u1 + s1 * w1, s0 * u2 + s1 * w2},
                              {s1 * u0 - s0 * w0, s1 * u1 - s0 * w1, s1 * u2 - s0 * w2}};
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
    return out;
}

} // namespace talus::sdk
