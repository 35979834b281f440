// Vectors of N doubles with one material point a lane: the types and the
// loads and stores the kernels that compute N points at once share
// (kinematics.cpp; the stencil packs of stencil.hpp).
#pragma once

#include "isa.hpp"

#include <cstddef>
#include <cstdint>
#include <utility>

namespace talus {

// A vector of N doubles (V), of N 64-bit integers (I), and V at a double's
// alignment (U: the type of a vector load or store at any double).
// Explicit per N: a dependent vector_size in a template is not a vector in
// GCC 12.
template <int N>
struct Lanes;
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
// for them (no store forwarding): that made the kinematics' packs slower
// than its scalar code. GCC 12 reports the whole-vector assignment as a
// read of an unset value, wrongly.
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

// Whether any lane of v is positive (v: lanes of ones and zeros, from
// selects with vector arms). Summed by halves within the vector: a test per
// lane, or an AND of compare masks, GCC 12 builds from scalar compares one
// lane at a time when the target has no 64-bit mask vectors (AVX-512
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
