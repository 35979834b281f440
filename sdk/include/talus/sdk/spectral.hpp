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
#include <cstddef>
#include <limits>

#if defined(__SSE2__)
#include <emmintrin.h>
#endif

// Eight decompositions a vector where the processor has AVX-512 (F and
// DQ), chosen at run time: with GCC on x86-64 (the region below needs its
// target and optimize pragmas), and not where the model's own build may
// fuse multiplies and adds (an FMA target: -march=native and the like),
// since the other paths then round differently from these lanes.
// Elsewhere, and on other processors, the lane pairs.
#if defined(__GNUC__) && !defined(__clang__) && defined(__x86_64__) && __GNUC__ >= 10 &&           \
    !defined(__FMA__)
#define TALUS_SDK_HAS_OCTET 1
#include <immintrin.h>
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

// The most matrices symmetric_eigen_group takes.
inline constexpr std::size_t kEigenGroup = 8;

// Up to kEigenGroup ordered decompositions side by side, one lane each
// (structure of arrays, for a model that goes on with them across vector
// lanes): what SymmetricEigen holds, lane by lane.
struct EigenLanes {
    // values[k][lane]: value k, descending in k.
    alignas(64) double values[3][kEigenGroup];
    // vectors[i][k][lane]: component i of direction k (of value k).
    alignas(64) double vectors[3][3][kEigenGroup];
    // Lane `lane` as a SymmetricEigen (the same bits).
    void get(std::size_t lane, SymmetricEigen &e) const {
        for (int k = 0; k < 3; ++k) {
            e.values[k] = values[k][lane];
            for (int i = 0; i < 3; ++i)
                e.vectors(i, k) = vectors[i][k][lane];
        }
    }
    void set(std::size_t lane, const SymmetricEigen &e) {
        for (int k = 0; k < 3; ++k) {
            values[k][lane] = e.values[k];
            for (int i = 0; i < 3; ++i)
                vectors[i][k][lane] = e.vectors(i, k);
        }
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
#include "talus/sdk/detail/spectral_kernel.inc"

// One lane's result, ordered (is_above), each value stored at its
// place as an index.
inline void order_lane(double q, double scale, const double l[3], const double vec[3][3],
                       SymmetricEigen &out) {
    const int rank[3] = {int(is_above(l, 1, 0)) + int(is_above(l, 2, 0)),
                         int(is_above(l, 0, 1)) + int(is_above(l, 2, 1)),
                         int(is_above(l, 0, 2)) + int(is_above(l, 1, 2))};
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
    order_lane(0.0, 1.0, l, vec, out);
}

} // namespace detail

namespace detail {

// Up to eight matrices' upper triangles (a00, a11, a22, a01, a02, a12, one
// array of eight per entry; unused lanes hold anything finite).
struct OctetIn {
    double a[6][8];
    void set(std::size_t lane, const Mat3 &m) {
        a[0][lane] = m(0, 0);
        a[1][lane] = m(1, 1);
        a[2][lane] = m(2, 2);
        a[3][lane] = m(0, 1);
        a[4][lane] = m(0, 2);
        a[5][lane] = m(1, 2);
    }
};

} // namespace detail
} // namespace talus::sdk

#if defined(TALUS_SDK_HAS_OCTET)
// The lane code again, compiled for AVX-512 with eight doubles a vector.
// Without contraction: with an AVX-512 target GCC fuses multiplies and
// adds (also under -std=c++20), which would round differently from the
// SSE2 pair and the scalar code; without it every lane's operations are
// theirs, so a matrix has the same bits whichever path decomposed it.
#pragma GCC push_options
#pragma GCC target("avx512f,avx512dq")
#pragma GCC optimize("fp-contract=off")
namespace talus::sdk::detail::octet {

// The lane pair's helpers (above) for eight lanes, defined again inside
// the region: a helper from outside it would be compiled for the baseline
// target, and GCC does not inline the region's intrinsics into it.
using Lanes = double __attribute__((vector_size(64)));
using LanesMask = decltype(Lanes{} < Lanes{});

inline Lanes lane_select(LanesMask c, Lanes a, Lanes b) {
    return (Lanes)(((LanesMask)a & c) | ((LanesMask)b & ~c));
}
inline LanesMask lane_and(LanesMask a, LanesMask b) { return a & b; }
inline LanesMask lane_not(LanesMask a) { return ~a; }
inline bool lane_any(LanesMask a) { return _mm512_test_epi64_mask((__m512i)a, (__m512i)a) != 0; }
inline Lanes lane_abs(Lanes x) {
    return (Lanes)((LanesMask)x & (LanesMask{} + 0x7fffffffffffffffLL));
}
inline Lanes lane_copysign(Lanes magnitude, Lanes sign) {
    const LanesMask bit = LanesMask{} + static_cast<long long>(0x8000000000000000ULL);
    return (Lanes)(((LanesMask)magnitude & ~bit) | ((LanesMask)sign & bit));
}
// All lanes (the masked form: the plain one starts from an undefined
// vector, which GCC reports as used uninitialised).
inline Lanes lane_sqrt(Lanes x) { return (Lanes)_mm512_mask_sqrt_pd((__m512d)x, 0xff, (__m512d)x); }

#include "talus/sdk/detail/spectral_kernel.inc"

// The eight matrices' decompositions (unordered_eigen), ordered by the
// rule order_lane follows (is_above), as selects per place, and the
// same q + scale l. For general matrices only (not is_plane), so none is a
// multiple of the identity (whose entries (0, 2) and (1, 2) are zero).
// Ordering each lane apart, through a SymmetricEigen, costs much of what a
// group takes beyond the lanes' arithmetic
// (bench/results/2026-11-28-mohr-coulomb-ordered-decompositions-ice-lake.md).
inline void ordered_octet(const OctetIn &in, EigenLanes &out) {
    Lanes e[6];
    for (int c = 0; c < 6; ++c)
        e[c] = (Lanes)_mm512_loadu_pd(in.a[c]);
    const Unordered<Lanes> u = unordered_eigen<Lanes>(e[0], e[1], e[2], e[3], e[4], e[5]);
    const Lanes nan = Lanes{} + std::numeric_limits<double>::quiet_NaN();
    Lanes val[3] = {nan, nan, nan}, vec[3][3];
    for (int i = 0; i < 3; ++i)
        for (int k = 0; k < 3; ++k)
            vec[i][k] = nan;
    for (int i = 0; i < 3; ++i) {
        const LanesMask a = is_above(u.l, i == 0 ? 1 : 0, i), b = is_above(u.l, i == 2 ? 1 : 2, i);
        // At place 0 when neither is above, 1 when one is, 2 when both are.
        const LanesMask at[3] = {~a & ~b, a ^ b, a & b};
        const Lanes value = u.q + u.scale * u.l[i];
        for (int r = 0; r < 3; ++r) {
            val[r] = lane_select(at[r], value, val[r]);
            for (int c = 0; c < 3; ++c)
                vec[c][r] = lane_select(at[r], u.vec[i][c], vec[c][r]);
        }
    }
    for (int r = 0; r < 3; ++r) {
        _mm512_storeu_pd(out.values[r], (__m512d)val[r]);
        for (int c = 0; c < 3; ++c)
            _mm512_storeu_pd(out.vectors[c][r], (__m512d)vec[c][r]);
    }
}

} // namespace talus::sdk::detail::octet
#pragma GCC pop_options
#endif

namespace talus::sdk::detail {

// Whether this processor runs the AVX-512 lanes (read once). A test may
// turn them off to compare the paths.
inline bool &octet_enabled() {
#if defined(TALUS_SDK_HAS_OCTET)
    static bool on = [] {
        __builtin_cpu_init();
        return __builtin_cpu_supports("avx512f") && __builtin_cpu_supports("avx512dq");
    }();
#else
    static bool on = false;
#endif
    return on;
}

} // namespace talus::sdk::detail

namespace talus::sdk {
namespace detail {

// The decompositions of a and b, side by side where the compiler has the
// lane pair; eb may be null (a alone). For general matrices only (not
// is_plane), so neither is a multiple of the identity, which has no order
// of its own (plane_eigen gives it the axes).
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
        order_lane(u.q[lane], u.scale[lane], l, vec, lane == 0 ? ea : *eb);
    }
#else
    for (int lane = 0; lane < (eb ? 2 : 1); ++lane) {
        const Mat3 &m = lane == 0 ? a : b;
        const Unordered<double> u =
            unordered_eigen<double>(m(0, 0), m(1, 1), m(2, 2), m(0, 1), m(0, 2), m(1, 2));
        order_lane(u.q, u.scale, u.l, u.vec, lane == 0 ? ea : *eb);
    }
#endif
}

} // namespace detail

namespace detail {

// The decompositions of *a[k] into *out[k], k < n <= kEigenGroup, each bit
// for bit that of the matrix alone: plane matrices in closed form, each by
// itself; the others eight a vector (from four of them on, with AVX-512),
// else two at a time, an odd one in the pair's first lane with the second
// idle. One matrix alone takes that lane too, so its bits do not depend on
// whether it was decomposed alone, in a pair or in a group, whatever the
// compiler contracts into fused multiply-adds.
inline void eigen_group(const Mat3 *const *a, SymmetricEigen *const *out, std::size_t n) {
    std::size_t general[kEigenGroup];
    std::size_t ng = 0;
    for (std::size_t k = 0; k < n && k < kEigenGroup; ++k) {
        if (is_plane(*a[k]))
            plane_eigen(*a[k], *out[k]);
        else
            general[ng++] = k;
    }
#if defined(TALUS_SDK_HAS_OCTET)
    // A vector of eight costs about what four matrices do in pairs
    // (bench/results/2026-11-27-mohr-coulomb-plane-and-eight-lane-decompositions.md).
    if (ng >= 4 && octet_enabled()) {
        OctetIn in;
        // Idle lanes repeat the last matrix: lanes do not mix.
        for (std::size_t lane = 0; lane < kEigenGroup; ++lane)
            in.set(lane, *a[general[std::min(lane, ng - 1)]]);
        EigenLanes o;
        octet::ordered_octet(in, o);
        for (std::size_t lane = 0; lane < ng; ++lane)
            o.get(lane, *out[general[lane]]);
        return;
    }
#endif
    std::size_t g = 0;
    for (; g + 1 < ng; g += 2)
        general_eigen_lanes(*a[general[g]], *a[general[g + 1]], *out[general[g]],
                            out[general[g + 1]]);
    if (g < ng) general_eigen_lanes(*a[general[g]], *a[general[g]], *out[general[g]], nullptr);
}

} // namespace detail

// The ordered spectral decomposition of the symmetric matrix a (its upper
// triangle is read). NaN in gives NaN out.
inline SymmetricEigen symmetric_eigen(const Mat3 &a) {
    SymmetricEigen out;
    const Mat3 *in[1] = {&a};
    SymmetricEigen *res[1] = {&out};
    detail::eigen_group(in, res, 1);
    return out;
}

// The ordered spectral decompositions of two symmetric matrices, side by
// side: each is bit for bit what symmetric_eigen gives for it, and the two
// cost about what one does (for models that take points in pairs,
// material.hpp).
inline void symmetric_eigen_pair(const Mat3 &a, const Mat3 &b, SymmetricEigen &ea,
                                 SymmetricEigen &eb) {
    const Mat3 *in[2] = {&a, &b};
    SymmetricEigen *res[2] = {&ea, &eb};
    detail::eigen_group(in, res, 2);
}

// The ordered spectral decompositions of the n <= kEigenGroup symmetric
// matrices a[0..n) into out[0..n): each bit for bit what symmetric_eigen
// gives for it; on a processor with AVX-512 (F, DQ) eight a vector, about
// half the cost of the pairs per matrix (for models that take points in
// groups, material.hpp).
inline void symmetric_eigen_group(const Mat3 *a, SymmetricEigen *out, std::size_t n) {
    const Mat3 *in[kEigenGroup];
    SymmetricEigen *res[kEigenGroup];
    for (std::size_t k = 0; k < n && k < kEigenGroup; ++k) {
        in[k] = a + k;
        res[k] = out + k;
    }
    detail::eigen_group(in, res, n);
}

// symmetric_eigen_group's decompositions of a[0..n), 1 <= n <= kEigenGroup,
// as lanes: lane k is a[k]'s, bit for bit what symmetric_eigen gives, and
// the lanes from n on repeat lane n - 1 (a vector over all the lanes then
// meets only real decompositions). Eight matrices none of which is a plane
// one go straight from the vector to the lanes.
inline void symmetric_eigen_lanes(const Mat3 *a, std::size_t n, EigenLanes &out) {
#if defined(TALUS_SDK_HAS_OCTET)
    bool general = n >= 4 && detail::octet_enabled();
    for (std::size_t k = 0; k < n && general; ++k)
        general = !detail::is_plane(a[k]);
    if (general) {
        detail::OctetIn in;
        for (std::size_t lane = 0; lane < kEigenGroup; ++lane)
            in.set(lane, a[std::min(lane, n - 1)]);
        detail::octet::ordered_octet(in, out);
        return;
    }
#endif
    SymmetricEigen e[kEigenGroup];
    symmetric_eigen_group(a, e, n);
    for (std::size_t lane = 0; lane < kEigenGroup; ++lane)
        out.set(lane, e[std::min(lane, n - 1)]);
}

} // namespace talus::sdk
