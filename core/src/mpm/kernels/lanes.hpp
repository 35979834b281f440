// Vectors of N doubles with one material point a lane: the types and the
// loads and stores the kernels that compute N points at once share
// (kinematics.cpp; the stencil packs of stencil.hpp).
#pragma once

#include "kernels/isa.hpp"

#include <cstddef>
#include <cstdint>
#include <utility>

namespace talus {

// A vector of N doubles (V), of N 64-bit integers (I), and V at a double's
// alignment (U: the type of a vector load or store at any double).
// N = 1 serves the last few points of a block in the same code as its
// packs. Explicit per N: the compiler does not take a dependent vector_size in a
// template as a vector.
template <int N>
struct Lanes;
template <>
struct Lanes<1> {
    typedef double V __attribute__((vector_size(sizeof(double))));
    typedef long long I __attribute__((vector_size(sizeof(long long))));
    typedef double U __attribute__((vector_size(sizeof(double)), aligned(8), may_alias));
};
template <>
struct Lanes<2> {
    typedef double V __attribute__((vector_size(2 * sizeof(double))));
    typedef long long I __attribute__((vector_size(2 * sizeof(long long))));
    typedef double U __attribute__((vector_size(2 * sizeof(double)), aligned(8), may_alias));
};
template <>
struct Lanes<4> {
    typedef double V __attribute__((vector_size(4 * sizeof(double))));
    typedef long long I __attribute__((vector_size(4 * sizeof(long long))));
    typedef double U __attribute__((vector_size(4 * sizeof(double)), aligned(8), may_alias));
};
template <>
struct Lanes<8> {
    typedef double V __attribute__((vector_size(8 * sizeof(double))));
    typedef long long I __attribute__((vector_size(8 * sizeof(long long))));
    typedef double U __attribute__((vector_size(8 * sizeof(double)), aligned(8), may_alias));
};

// The points per vector of each instruction set's registers.
template <Isa I>
inline constexpr int kPointLanes = I == Isa::avx512 ? 8
                                   : I == Isa::avx2 ? 4
                                                    : 2;

// Lane k of v from base[k * stride] (load_lanes) or base[index[k]]
// (load_indexed), and back. (Vectors by reference: by value they would
// change the calling convention with the target.) The vector is built whole
// from its lanes, which the compiler does with inserts in registers;
// through an array on the stack, a vector load of eight scalar stores waits
// for them (no store forwarding), which makes the kinematics' packs slower
// than its scalar code. GCC reports the whole-vector assignment as a read
// of an unset value, wrongly.
#if defined(__GNUC__) && !defined(__clang__)
#pragma GCC diagnostic push
#pragma GCC diagnostic ignored "-Wmaybe-uninitialized"
#endif
template <int N, class V>
[[gnu::always_inline]] inline void load_lanes(const double *base, std::size_t stride, V &v) {
    [&]<std::size_t... k>(std::index_sequence<k...>) __attribute__((always_inline)) {
        v = V{base[k * stride]...};
    }
    (std::make_index_sequence<N>{});
}
template <int N, class V>
[[gnu::always_inline]] inline void load_indexed(const double *base, const std::uint32_t *index,
                                                V &v) {
    [&]<std::size_t... k>(std::index_sequence<k...>) __attribute__((always_inline)) {
        v = V{base[index[k]]...};
    }
    (std::make_index_sequence<N>{});
}
#if defined(__GNUC__) && !defined(__clang__)
#pragma GCC diagnostic pop
#endif
template <int N, class V>
[[gnu::always_inline]] inline void store_lanes(double *base, std::size_t stride, const V &v) {
    for (int k = 0; k < N; ++k)
        base[static_cast<std::size_t>(k) * stride] = v[k];
}

// The N doubles at a, as one vector load or store.
template <int N>
[[gnu::always_inline]] inline void load_vector(const double *a, typename Lanes<N>::V &v) {
    v = *reinterpret_cast<const typename Lanes<N>::U *>(a);
}
template <int N>
[[gnu::always_inline]] inline void store_vector(double *a, const typename Lanes<N>::V &v) {
    *reinterpret_cast<typename Lanes<N>::U *>(a) = v;
}

#if defined(__has_builtin)
#if __has_builtin(__builtin_shufflevector)
#define TALUS_HAS_SHUFFLEVECTOR 1
#endif
#endif
#ifndef TALUS_HAS_SHUFFLEVECTOR
#define TALUS_HAS_SHUFFLEVECTOR 0
#endif

// N points of C consecutive doubles each (an array of structures: point
// k's component c at base[C k + c], N C doubles in all) as C vectors with
// lane k of vector c that value (load_points), and back (store_points): a
// transpose. Element by element (load_lanes) a lane costs an insert or an
// extract on the one shuffle port besides its load or store; for the
// kinematics' 24 components a point that was about two thirds of its time
// (measured with the transposes made free). With 8 lanes and 4, 6 or 9
// components the transposes below take whole-vector loads and stores and
// 8 (C = 4), 18 (C = 6) or about 40 (C = 9) two-vector shuffles for 8
// points. The
// values are only moved: the results are the same bits either way.
namespace lanes_detail {
#if TALUS_HAS_SHUFFLEVECTOR
using V8 = Lanes<8>::V;
// Each 128-bit lane's even or odd elements, from a then from b. (Macros:
// a function returning a 512-bit vector, compiled for the baseline, would
// have another calling convention; -Wpsabi says so.)
#define TALUS_UNPACK_LO(a, b) __builtin_shufflevector(a, b, 0, 8, 2, 10, 4, 12, 6, 14)
#define TALUS_UNPACK_HI(a, b) __builtin_shufflevector(a, b, 1, 9, 3, 11, 5, 13, 7, 15)
// An 8 x 8 transpose in place: r[k][c] becomes r[c][k] (three rounds of 8
// shuffles: pairs, quads, halves).
[[gnu::always_inline]] inline void transpose8(V8 (&r)[8]) {
    V8 t[8], u[8];
    for (int i = 0; i < 8; i += 2) {
        t[i] = TALUS_UNPACK_LO(r[i], r[i + 1]);
        t[i + 1] = TALUS_UNPACK_HI(r[i], r[i + 1]);
    }
    // u[0]: components 0 and 4 of rows 0-3; u[1]: 2 and 6; u[2]: 1 and 5;
    // u[3]: 3 and 7; u[4..7] the same of rows 4-7.
    for (int h = 0; h < 8; h += 4)
        for (int j = 0; j < 2; ++j) {
            u[h + 2 * j] =
                __builtin_shufflevector(t[h + j], t[h + j + 2], 0, 1, 8, 9, 4, 5, 12, 13);
            u[h + 2 * j + 1] =
                __builtin_shufflevector(t[h + j], t[h + j + 2], 2, 3, 10, 11, 6, 7, 14, 15);
        }
    constexpr int first[4] = {0, 2, 1, 3}; // the component in u[j]'s first half
    for (int j = 0; j < 4; ++j) {
        r[first[j]] = __builtin_shufflevector(u[j], u[j + 4], 0, 1, 2, 3, 8, 9, 10, 11);
        r[first[j] + 4] = __builtin_shufflevector(u[j], u[j + 4], 4, 5, 6, 7, 12, 13, 14, 15);
    }
}
// Point k's component c at v[C k + c]: a vector per component (C = 9).
// Point k's components 0-7 start at lane k of v[k] (9 k = 8 k + k): a row
// each from two vectors; component 8 is lane k of v[k + 1].
[[gnu::always_inline]] inline void aos9_to_lanes(const V8 (&v)[9], V8 (&c)[9]) {
    V8 r[8];
    r[0] = v[0];
    r[1] = __builtin_shufflevector(v[1], v[2], 1, 2, 3, 4, 5, 6, 7, 8);
    r[2] = __builtin_shufflevector(v[2], v[3], 2, 3, 4, 5, 6, 7, 8, 9);
    r[3] = __builtin_shufflevector(v[3], v[4], 3, 4, 5, 6, 7, 8, 9, 10);
    r[4] = __builtin_shufflevector(v[4], v[5], 4, 5, 6, 7, 8, 9, 10, 11);
    r[5] = __builtin_shufflevector(v[5], v[6], 5, 6, 7, 8, 9, 10, 11, 12);
    r[6] = __builtin_shufflevector(v[6], v[7], 6, 7, 8, 9, 10, 11, 12, 13);
    r[7] = __builtin_shufflevector(v[7], v[8], 7, 8, 9, 10, 11, 12, 13, 14);
    // Lane k of v[k + 1], k = 0..7: blends.
    const V8 a = __builtin_shufflevector(v[1], v[2], 0, 9, 2, 3, 4, 5, 6, 7);
    const V8 b = __builtin_shufflevector(v[3], v[4], 0, 1, 2, 11, 4, 5, 6, 7);
    const V8 c4 = __builtin_shufflevector(v[5], v[6], 0, 1, 2, 3, 4, 13, 6, 7);
    const V8 d = __builtin_shufflevector(v[7], v[8], 0, 1, 2, 3, 4, 5, 6, 15);
    const V8 ab = __builtin_shufflevector(a, b, 0, 1, 10, 11, 4, 5, 6, 7);
    const V8 cd = __builtin_shufflevector(c4, d, 0, 1, 2, 3, 4, 5, 14, 15);
    c[8] = __builtin_shufflevector(ab, cd, 0, 1, 2, 3, 12, 13, 14, 15);
    transpose8(r);
    for (int i = 0; i < 8; ++i)
        c[i] = r[i];
}
// The inverse: vector j of the stream holds point j - 1's last j
// components (its 9 - j .. 7 from its row, 8 from c[8]) and point j's
// first 8 - j.
[[gnu::always_inline]] inline void lanes_to_aos9(const V8 (&c)[9], V8 (&v)[9]) {
    V8 r[8];
    for (int i = 0; i < 8; ++i)
        r[i] = c[i];
    transpose8(r);
    const V8 &e = c[8];
    v[0] = r[0];
    // Point j - 1's row from lane 9 - j on, its component 8 (lane j - 1 of
    // e) at lane j - 1, point j's row from lane 0 at lane j.
    v[1] = __builtin_shufflevector(__builtin_shufflevector(r[0], e, 8, 0, 0, 0, 0, 0, 0, 0), r[1],
                                   0, 8, 9, 10, 11, 12, 13, 14);
    v[2] = __builtin_shufflevector(__builtin_shufflevector(r[1], e, 7, 9, 0, 0, 0, 0, 0, 0), r[2],
                                   0, 1, 8, 9, 10, 11, 12, 13);
    v[3] = __builtin_shufflevector(__builtin_shufflevector(r[2], e, 6, 7, 10, 0, 0, 0, 0, 0), r[3],
                                   0, 1, 2, 8, 9, 10, 11, 12);
    v[4] = __builtin_shufflevector(__builtin_shufflevector(r[3], e, 5, 6, 7, 11, 0, 0, 0, 0), r[4],
                                   0, 1, 2, 3, 8, 9, 10, 11);
    v[5] = __builtin_shufflevector(__builtin_shufflevector(r[4], e, 4, 5, 6, 7, 12, 0, 0, 0), r[5],
                                   0, 1, 2, 3, 4, 8, 9, 10);
    v[6] = __builtin_shufflevector(__builtin_shufflevector(r[5], e, 3, 4, 5, 6, 7, 13, 0, 0), r[6],
                                   0, 1, 2, 3, 4, 5, 8, 9);
    v[7] = __builtin_shufflevector(__builtin_shufflevector(r[6], e, 2, 3, 4, 5, 6, 7, 14, 0), r[7],
                                   0, 1, 2, 3, 4, 5, 6, 8);
    v[8] = __builtin_shufflevector(r[7], e, 1, 2, 3, 4, 5, 6, 7, 15);
}
// C = 6: the 48 doubles as 12 quarters Y0..Y11 of 4 (points 0-3 in Y0-Y5,
// 4-7 in Y6-Y11, the same layout); z[a] = (Y_a, Y_a+6) makes the two
// 4-point problems one. In a quarter-problem, with pairs of components
// (p01 = components 0 and 1 of point p): Y0 = (A01 A23), Y1 = (A45 B01),
// Y2 = (B23 B45), Y3 = (C01 C23), Y4 = (C45 D01), Y5 = (D23 D45); w gathers
// (A01 C01), (B01 D01), ... and an unpack makes (A0 B0 C0 D0).
[[gnu::always_inline]] inline void aos6_to_lanes(const V8 (&v)[6], V8 (&c)[6]) {
    V8 z[6];
    for (int a = 0; a < 6; ++a) {
        const V8 &lo = v[a / 2], &hi = v[(a + 6) / 2];
        z[a] = a % 2 == 0 ? __builtin_shufflevector(lo, hi, 0, 1, 2, 3, 8, 9, 10, 11)
                          : __builtin_shufflevector(lo, hi, 4, 5, 6, 7, 12, 13, 14, 15);
    }
    // (pair from z[i] at chunk ci, pair from z[j] at chunk cj) in each half.
    const V8 w01a = __builtin_shufflevector(z[0], z[3], 0, 1, 8, 9, 4, 5, 12, 13);   // A01 C01
    const V8 w01b = __builtin_shufflevector(z[1], z[4], 2, 3, 10, 11, 6, 7, 14, 15); // B01 D01
    const V8 w23a = __builtin_shufflevector(z[0], z[3], 2, 3, 10, 11, 6, 7, 14, 15); // A23 C23
    const V8 w23b = __builtin_shufflevector(z[2], z[5], 0, 1, 8, 9, 4, 5, 12, 13);   // B23 D23
    const V8 w45a = __builtin_shufflevector(z[1], z[4], 0, 1, 8, 9, 4, 5, 12, 13);   // A45 C45
    const V8 w45b = __builtin_shufflevector(z[2], z[5], 2, 3, 10, 11, 6, 7, 14, 15); // B45 D45
    c[0] = TALUS_UNPACK_LO(w01a, w01b);
    c[1] = TALUS_UNPACK_HI(w01a, w01b);
    c[2] = TALUS_UNPACK_LO(w23a, w23b);
    c[3] = TALUS_UNPACK_HI(w23a, w23b);
    c[4] = TALUS_UNPACK_LO(w45a, w45b);
    c[5] = TALUS_UNPACK_HI(w45a, w45b);
}
[[gnu::always_inline]] inline void lanes_to_aos6(const V8 (&c)[6], V8 (&v)[6]) {
    const V8 w01a = TALUS_UNPACK_LO(c[0], c[1]), w01b = TALUS_UNPACK_HI(c[0], c[1]);
    const V8 w23a = TALUS_UNPACK_LO(c[2], c[3]), w23b = TALUS_UNPACK_HI(c[2], c[3]);
    const V8 w45a = TALUS_UNPACK_LO(c[4], c[5]), w45b = TALUS_UNPACK_HI(c[4], c[5]);
    V8 z[6];
    z[0] = __builtin_shufflevector(w01a, w23a, 0, 1, 8, 9, 4, 5, 12, 13);   // A01 A23
    z[3] = __builtin_shufflevector(w01a, w23a, 2, 3, 10, 11, 6, 7, 14, 15); // C01 C23
    z[1] = __builtin_shufflevector(w45a, w01b, 0, 1, 8, 9, 4, 5, 12, 13);   // A45 B01
    z[4] = __builtin_shufflevector(w45a, w01b, 2, 3, 10, 11, 6, 7, 14, 15); // C45 D01
    z[2] = __builtin_shufflevector(w23b, w45b, 0, 1, 8, 9, 4, 5, 12, 13);   // B23 B45
    z[5] = __builtin_shufflevector(w23b, w45b, 2, 3, 10, 11, 6, 7, 14, 15); // D23 D45
    for (int i = 0; i < 6; ++i) {
        const V8 &a = z[(2 * i) % 6], &b = z[(2 * i + 1) % 6];
        v[i] = i < 3 ? __builtin_shufflevector(a, b, 0, 1, 2, 3, 8, 9, 10, 11)
                     : __builtin_shufflevector(a, b, 4, 5, 6, 7, 12, 13, 14, 15);
    }
}
// C = 4 (plane strain's F): v[j] holds points 2j and 2j + 1. Pairs of
// vectors give (A0 B0 C0 D0 A1 B1 C1 D1) and the like, whose halves then
// make the components: eight two-vector shuffles each way.
[[gnu::always_inline]] inline void aos4_to_lanes(const V8 (&v)[4], V8 (&c)[4]) {
    const V8 t0 = __builtin_shufflevector(v[0], v[1], 0, 4, 8, 12, 1, 5, 9, 13);
    const V8 t1 = __builtin_shufflevector(v[0], v[1], 2, 6, 10, 14, 3, 7, 11, 15);
    const V8 t2 = __builtin_shufflevector(v[2], v[3], 0, 4, 8, 12, 1, 5, 9, 13);
    const V8 t3 = __builtin_shufflevector(v[2], v[3], 2, 6, 10, 14, 3, 7, 11, 15);
    c[0] = __builtin_shufflevector(t0, t2, 0, 1, 2, 3, 8, 9, 10, 11);
    c[1] = __builtin_shufflevector(t0, t2, 4, 5, 6, 7, 12, 13, 14, 15);
    c[2] = __builtin_shufflevector(t1, t3, 0, 1, 2, 3, 8, 9, 10, 11);
    c[3] = __builtin_shufflevector(t1, t3, 4, 5, 6, 7, 12, 13, 14, 15);
}
[[gnu::always_inline]] inline void lanes_to_aos4(const V8 (&c)[4], V8 (&v)[4]) {
    const V8 t0 = __builtin_shufflevector(c[0], c[1], 0, 1, 2, 3, 8, 9, 10, 11);
    const V8 t2 = __builtin_shufflevector(c[0], c[1], 4, 5, 6, 7, 12, 13, 14, 15);
    const V8 t1 = __builtin_shufflevector(c[2], c[3], 0, 1, 2, 3, 8, 9, 10, 11);
    const V8 t3 = __builtin_shufflevector(c[2], c[3], 4, 5, 6, 7, 12, 13, 14, 15);
    v[0] = __builtin_shufflevector(t0, t1, 0, 4, 8, 12, 1, 5, 9, 13);
    v[1] = __builtin_shufflevector(t0, t1, 2, 6, 10, 14, 3, 7, 11, 15);
    v[2] = __builtin_shufflevector(t2, t3, 0, 4, 8, 12, 1, 5, 9, 13);
    v[3] = __builtin_shufflevector(t2, t3, 2, 6, 10, 14, 3, 7, 11, 15);
}
#undef TALUS_UNPACK_LO
#undef TALUS_UNPACK_HI
#endif
} // namespace lanes_detail

namespace lanes_detail {
// load_points, and with Copy the N C doubles copied to `copy` as they are
// (from the vectors the transpose starts from, with no second read of
// base).
template <int N, bool Copy, int C, class V>
[[gnu::always_inline]] inline void load_points(const double *base, double *copy, V (&out)[C]) {
#if TALUS_HAS_SHUFFLEVECTOR
    if constexpr (N == 8 && (C == 4 || C == 6 || C == 9)) {
        V v[C];
        for (int j = 0; j < C; ++j) {
            load_vector<8>(base + 8 * j, v[j]);
            if constexpr (Copy) store_vector<8>(copy + 8 * j, v[j]);
        }
        if constexpr (C == 4)
            aos4_to_lanes(v, out);
        else if constexpr (C == 6)
            aos6_to_lanes(v, out);
        else
            aos9_to_lanes(v, out);
        return;
    }
#endif
    if constexpr (Copy)
        for (int j = 0; j < N * C; ++j)
            copy[j] = base[j];
    for (int c = 0; c < C; ++c)
        load_lanes<N>(base + c, C, out[c]);
}
} // namespace lanes_detail

template <int N, int C, class V>
[[gnu::always_inline]] inline void load_points(const double *base, V (&out)[C]) {
    lanes_detail::load_points<N, false>(base, nullptr, out);
}
// load_points, and the N C doubles copied to `copy` as they are, from the
// vectors the transpose starts from (no second read of base).
template <int N, int C, class V>
[[gnu::always_inline]] inline void load_points_copying(const double *base, double *copy,
                                                       V (&out)[C]) {
    lanes_detail::load_points<N, true>(base, copy, out);
}
template <int N, int C, class V>
[[gnu::always_inline]] inline void store_points(double *base, const V (&in)[C]) {
#if TALUS_HAS_SHUFFLEVECTOR
    if constexpr (N == 8 && (C == 4 || C == 6 || C == 9)) {
        V v[C];
        if constexpr (C == 4)
            lanes_detail::lanes_to_aos4(in, v);
        else if constexpr (C == 6)
            lanes_detail::lanes_to_aos6(in, v);
        else
            lanes_detail::lanes_to_aos9(in, v);
        for (int j = 0; j < C; ++j)
            store_vector<8>(base + 8 * j, v[j]);
        return;
    }
#endif
    for (int c = 0; c < C; ++c)
        store_lanes<N>(base + c, C, in[c]);
}

#if TALUS_HAS_SHUFFLEVECTOR
// Four quantities of 8 points, one vector each (q[i] lane j: point j), as
// the points' groups of four (q[0..3][j] together: a node's half record),
// and back: 4 x 8 transposes of eight two-vector shuffles. Point j's four
// lie at out + quad_at(j), the order the shuffles leave them in. The
// values only move.
constexpr std::size_t quad_at(std::size_t j) { return 8 * (j % 4) + 4 * (j / 4); }
[[gnu::always_inline]] inline void lanes_to_quads(const Lanes<8>::V (&q)[4], double *out) {
    using V = Lanes<8>::V;
    const V t0 = __builtin_shufflevector(q[0], q[1], 0, 8, 2, 10, 4, 12, 6, 14);
    const V t1 = __builtin_shufflevector(q[0], q[1], 1, 9, 3, 11, 5, 13, 7, 15);
    const V t2 = __builtin_shufflevector(q[2], q[3], 0, 8, 2, 10, 4, 12, 6, 14);
    const V t3 = __builtin_shufflevector(q[2], q[3], 1, 9, 3, 11, 5, 13, 7, 15);
    // Points (0, 4), (1, 5), (2, 6), (3, 7).
    store_vector<8>(out, __builtin_shufflevector(t0, t2, 0, 1, 8, 9, 4, 5, 12, 13));
    store_vector<8>(out + 8, __builtin_shufflevector(t1, t3, 0, 1, 8, 9, 4, 5, 12, 13));
    store_vector<8>(out + 16, __builtin_shufflevector(t0, t2, 2, 3, 10, 11, 6, 7, 14, 15));
    store_vector<8>(out + 24, __builtin_shufflevector(t1, t3, 2, 3, 10, 11, 6, 7, 14, 15));
}
[[gnu::always_inline]] inline void quads_to_lanes(const double *in, Lanes<8>::V (&q)[4]) {
    using V = Lanes<8>::V;
    V u0, u1, u2, u3;
    load_vector<8>(in, u0);
    load_vector<8>(in + 8, u1);
    load_vector<8>(in + 16, u2);
    load_vector<8>(in + 24, u3);
    const V t0 = __builtin_shufflevector(u0, u2, 0, 1, 8, 9, 4, 5, 12, 13);
    const V t2 = __builtin_shufflevector(u0, u2, 2, 3, 10, 11, 6, 7, 14, 15);
    const V t1 = __builtin_shufflevector(u1, u3, 0, 1, 8, 9, 4, 5, 12, 13);
    const V t3 = __builtin_shufflevector(u1, u3, 2, 3, 10, 11, 6, 7, 14, 15);
    q[0] = __builtin_shufflevector(t0, t1, 0, 8, 2, 10, 4, 12, 6, 14);
    q[1] = __builtin_shufflevector(t0, t1, 1, 9, 3, 11, 5, 13, 7, 15);
    q[2] = __builtin_shufflevector(t2, t3, 0, 8, 2, 10, 4, 12, 6, 14);
    q[3] = __builtin_shufflevector(t2, t3, 1, 9, 3, 11, 5, 13, 7, 15);
}
#endif

// Whether any lane of v is positive (v: lanes of ones and zeros, from
// selects with vector arms). Summed by halves within the vector: a test per
// lane, or an AND of compare masks, the compiler builds from scalar compares
// one lane at a time when the target has no 64-bit mask vectors (AVX-512
// without DQ).
template <int N>
[[gnu::always_inline]] inline bool any_lane(const typename Lanes<N>::V &lanes) {
    typename Lanes<N>::V v = lanes;
#if TALUS_HAS_SHUFFLEVECTOR
    if constexpr (N == 8) {
        v += __builtin_shufflevector(v, v, 4, 5, 6, 7, 0, 1, 2, 3);
        v += __builtin_shufflevector(v, v, 2, 3, 0, 1, 6, 7, 4, 5);
        v += __builtin_shufflevector(v, v, 1, 0, 3, 2, 5, 4, 7, 6);
    } else if constexpr (N == 4) {
        v += __builtin_shufflevector(v, v, 2, 3, 0, 1);
        v += __builtin_shufflevector(v, v, 1, 0, 3, 2);
    } else {
        v += __builtin_shufflevector(v, v, 1, 0);
    }
    return v[0] > 0.0;
#else
    // Compilers without it (GCC before 12): the lanes one by one.
    double sum = 0.0;
    for (int i = 0; i < N; ++i)
        sum += v[i];
    return sum > 0.0;
#endif
}

// floor(x) in every lane, as fast_floor (shape_functions.hpp) does it for
// one: the truncation, less one where it rounded up. (Out through a
// reference, as every vector here.)
template <int N>
[[gnu::always_inline]] inline void floor_lanes(const typename Lanes<N>::V &x,
                                               typename Lanes<N>::V &fl) {
    using V = typename Lanes<N>::V;
    const V t = __builtin_convertvector(__builtin_convertvector(x, typename Lanes<N>::I), V);
    fl = t > x ? t - 1.0 : t;
}

} // namespace talus
