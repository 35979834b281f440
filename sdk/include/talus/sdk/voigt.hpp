// talus/sdk/voigt.hpp -- Voigt <-> tensor conversions and stress invariants,
// in the conventions of talus/material_abi.h: order xx, yy, zz, xy, yz, xz;
// stress with tensor shear components, strain with engineering shear.
#pragma once

#include <Eigen/Core>
#include <cmath>

namespace talus::sdk {

using Vec6 = Eigen::Matrix<double, 6, 1>;
using Mat6 = Eigen::Matrix<double, 6, 6>;
using Mat3 = Eigen::Matrix3d;

// Voigt index of the tensor component (i, j), symmetric.
constexpr int voigt_index(int i, int j) {
    if (i == j) return i;
    const int s = i + j; // xy -> 1, yz -> 3, xz -> 2
    return s == 1 ? 3 : (s == 3 ? 4 : 5);
}

// Stress-like (tensor shear) Voigt vector to a symmetric matrix.
inline Mat3 stress_to_matrix(const Vec6 &s) {
    Mat3 m;
    m << s[0], s[3], s[5], //
        s[3], s[1], s[4],  //
        s[5], s[4], s[2];
    return m;
}

// Symmetric part of a matrix to a stress-like Voigt vector.
inline Vec6 matrix_to_stress(const Mat3 &m) {
    Vec6 s;
    s << m(0, 0), m(1, 1), m(2, 2), 0.5 * (m(0, 1) + m(1, 0)), 0.5 * (m(1, 2) + m(2, 1)),
        0.5 * (m(0, 2) + m(2, 0));
    return s;
}

// Engineering-shear strain Voigt vector to a symmetric (tensor) matrix.
inline Mat3 strain_to_matrix(const Vec6 &e) {
    Mat3 m;
    m << e[0], 0.5 * e[3], 0.5 * e[5], //
        0.5 * e[3], e[1], 0.5 * e[4],  //
        0.5 * e[5], 0.5 * e[4], e[2];
    return m;
}

// Symmetric part of a matrix to an engineering-shear strain Voigt vector.
inline Vec6 matrix_to_strain(const Mat3 &m) {
    Vec6 e;
    e << m(0, 0), m(1, 1), m(2, 2), m(0, 1) + m(1, 0), m(1, 2) + m(2, 1), m(0, 2) + m(2, 0);
    return e;
}

// Mean stress, compression positive (the soil mechanics p): -tr(sigma)/3.
inline double mean_pressure(const Vec6 &s) { return -(s[0] + s[1] + s[2]) / 3.0; }

// Second invariant of the deviatoric stress, J2 = s:s / 2.
inline double j2_invariant(const Vec6 &s) {
    const double m = (s[0] + s[1] + s[2]) / 3.0;
    const double dx = s[0] - m, dy = s[1] - m, dz = s[2] - m;
    return 0.5 * (dx * dx + dy * dy + dz * dz) + s[3] * s[3] + s[4] * s[4] + s[5] * s[5];
}

// Von Mises equivalent (deviator) stress q = sqrt(3 J2).
inline double von_mises(const Vec6 &s) { return std::sqrt(3.0 * j2_invariant(s)); }

} // namespace talus::sdk
