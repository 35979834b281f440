// One particle's stencil as the product of its per-axis factors, and the
// two kernels every transfer is made of: the scatter of a particle's
// values to its nodes (P2G) and the gather of node records to the particle
// (G2P).
//
// The weights of a tensor-product kernel are w_i = w_x(a) w_y(b) w_z(c) and
// their gradients (dw_x w_y w_z, w_x dw_y w_z, w_x w_y dw_z); the nodes'
// offsets from the particle (the affine transfers) are per axis too. The
// kernels never form the W^D node weights: they sum by factors (the sum
// factorisation of spectral elements), a row of W nodes along x at a time,
// with one to three multiply-adds of a node record (8 doubles, node::) or
// of its halves per node. A record is 8 consecutive doubles and a row is W
// consecutive records; the record arithmetic is written on vector types
// (Vec8, Quad8, Arr8 and their halves below), and each kernel is compiled
// once per instruction set (IsaVersions, isa.hpp): on AVX-512 a record is
// one instruction.
//
// The stencils themselves are evaluated for N particles at once where the
// kernel allows (StencilPack: the B-splines away from the faces), one
// particle a vector lane; the sums then run particle by particle.
//
// The kernels see the domain's bounds (eval_bounded): the B-splines are
// clamped at the faces (docs/theory.md, "Boundaries"); the clamped weights
// are still per-axis products, so the same sums serve both.
#pragma once

#include "kernels/isa.hpp"
#include "kernels/lanes.hpp"
#include "state/grid.hpp"

#include <talus/mpm/particles.hpp>
#include <talus/mpm/shape_functions.hpp>

#include <cstddef>
#include <cstdint>
#include <cstring>
#include <type_traits>

namespace talus {

inline constexpr int kLanes = static_cast<int>(node::kRecord);

// A node record's worth of values: what a particle adds to each field of a
// node per unit weight, gradient or offset, or what it gathers. Three types
// with the same arithmetic, one per instruction set the kernels are
// compiled for:
//
//   Vec8:  one vector of the compiler's vector extension, which it maps onto
//          one AVX-512 register. Used in the AVX-512 kernels (isa.hpp);
//          plain loops over 8 doubles compile to scalar and half-register
//          code there.
//   Split: 8 / N vectors of N doubles, the target's own registers: N = 2
//          (Arr8) for the baseline target (SSE2), N = 4 (Quad8) for AVX2.
//          Vec8 on those targets is lowered through the stack: setting one
//          lane stores it there and the next use loads the whole vector
//          back, which waits on the store: the kernels run much slower than
//          with Split (bench/results/2026-11-24-stencil-packs-avx2-kernels-epyc-zen4.md).
//
// All are passed by reference only: a vector by value would change the
// calling convention with the target's vector width.
//
// Sums that need only a record's first four doubles run on half records
// (HalfRecord below: Vec4, Split<N, 4>): the G2P's gradient and offset
// sums, which read v~ alone (node::kEndVelocity), and in 2D all of its
// sums (v~ and v fit a half). Half the multiply-adds and loads of a whole
// record, and on a processor that splits a 512-bit operation in two (AMD
// Zen 4), half the cycles. The sums are the same, lane by lane.
typedef double Vec8 __attribute__((vector_size(8 * sizeof(double))));
typedef double Vec4 __attribute__((vector_size(4 * sizeof(double))));

// Lane i of vector v becomes x.
template <class V>
[[gnu::always_inline]] inline void blend_lane(V &v, std::size_t i, double x) {
    V lane{};
    for (std::size_t j = 0; j < sizeof(V) / sizeof(double); ++j)
        lane[j] = static_cast<double>(j);
    v = lane == static_cast<double>(i) ? V{} + x : v;
}

template <int N, int K = kLanes>
struct Split {
    typedef double Part __attribute__((vector_size(N * sizeof(double))));
    // The same vector at a double's alignment, for the loads and stores of
    // node records (a memcpy of the whole struct was lowered in 16-byte
    // pieces in the AVX2 kernels, the target attribute notwithstanding).
    typedef double Unaligned
        __attribute__((vector_size(N * sizeof(double)), aligned(8), may_alias));
    Part q[K / N];
    [[gnu::always_inline]] double operator[](std::size_t k) const { return q[k / N][k % N]; }
    // Lane k becomes x: a blend of x into its part (the compiler reports an
    // element assignment as a read of an uninitialised part).
    [[gnu::always_inline]] void set(std::size_t k, double x) { blend_lane(q[k / N], k % N, x); }
    [[gnu::always_inline]] void load(const double *r) {
        for (int i = 0; i < K / N; ++i)
            q[i] = *reinterpret_cast<const Unaligned *>(r + N * i);
    }
    [[gnu::always_inline]] void store(double *r) const {
        for (int i = 0; i < K / N; ++i)
            *reinterpret_cast<Unaligned *>(r + N * i) = q[i];
    }
    [[gnu::always_inline]] Split &operator+=(const Split &o) {
        for (int i = 0; i < K / N; ++i)
            q[i] += o.q[i];
        return *this;
    }
    [[gnu::always_inline]] friend Split operator*(double s, const Split &a) {
        Split r;
        for (int i = 0; i < K / N; ++i)
            r.q[i] = s * a.q[i];
        return r;
    }
};
using Arr8 = Split<2>;
using Quad8 = Split<4>;

// The first half of a record, in the registers of the type's target.
template <class Lanes>
struct HalfRecord;
template <>
struct HalfRecord<Vec8> {
    using type = Vec4;
};
template <int N>
struct HalfRecord<Split<N>> {
    using type = Split<N, kLanes / 2>;
};

// The doubles of a record a type holds (8, or 4 for a half record).
template <class Lanes>
inline constexpr std::size_t kRecordLanes = sizeof(Lanes) / sizeof(double);

// h = the first half of v (the values only move).
[[gnu::always_inline]] inline void first_half(const Vec8 &v, Vec4 &h) {
#if TALUS_HAS_SHUFFLEVECTOR // lanes.hpp
    h = __builtin_shufflevector(v, v, 0, 1, 2, 3);
#else
    std::memcpy(&h, &v, sizeof h);
#endif
}
template <int N>
[[gnu::always_inline]] inline void first_half(const Split<N> &v, Split<N, kLanes / 2> &h) {
    for (int i = 0; i < kLanes / 2 / N; ++i)
        h.q[i] = v.q[i];
}

// Lane k of a record's worth of values, for any of the types.
[[gnu::always_inline]] inline void set_lane(Vec8 &v, std::size_t k, double x) { v[k] = x; }
[[gnu::always_inline]] inline void set_lane(Vec4 &v, std::size_t k, double x) { v[k] = x; }
template <int N, int K>
[[gnu::always_inline]] inline void set_lane(Split<N, K> &v, std::size_t k, double x) {
    v.set(k, x);
}

// The record at r, or its first half: one vector load, no aliasing question.
[[gnu::always_inline]] inline void load_record(const double *r, Vec8 &v) {
    std::memcpy(&v, r, sizeof v);
}
[[gnu::always_inline]] inline void store_record(double *r, const Vec8 &v) {
    std::memcpy(r, &v, sizeof v);
}
[[gnu::always_inline]] inline void load_record(const double *r, Vec4 &v) {
    std::memcpy(&v, r, sizeof v);
}
[[gnu::always_inline]] inline void store_record(double *r, const Vec4 &v) {
    std::memcpy(r, &v, sizeof v);
}
template <int N, int K>
[[gnu::always_inline]] inline void load_record(const double *r, Split<N, K> &v) {
    v.load(r);
}
template <int N, int K>
[[gnu::always_inline]] inline void store_record(double *r, const Split<N, K> &v) {
    v.store(r);
}

// The sums every transfer is made of, over one particle's stencil: written
// once on the stencil's per-axis factors, read through Self (a Stencil, or
// one lane of a StencilPack): weight(d, k), slope(d, k) (dw/dx, 1/m),
// weighted_offset(d, k) (w (x_i - x_p), m) and first(d) (the first node's
// global number along d).
template <class Self, int D, int W>
struct StencilSums {
    [[gnu::always_inline]] const Self &self() const { return static_cast<const Self &>(*this); }

    // The local slot of the stencil's first node, and the slot strides of
    // its rows (y) and layers (z).
    struct Slots {
        std::size_t first, row, layer;
    };
    [[gnu::always_inline]] Slots slots(const GridGeometry &g) const {
        const std::size_t ex = static_cast<std::size_t>(g.extent[0]);
        const std::size_t exy = ex * static_cast<std::size_t>(g.extent[1]);
        std::size_t first = static_cast<std::size_t>(self().first(0) - g.first[0]) +
                            ex * static_cast<std::size_t>(self().first(1) - g.first[1]);
        if constexpr (D == 3) first += exy * static_cast<std::size_t>(self().first(2) - g.first[2]);
        return {first, ex, exy};
    }
    // The slot of the first node of row b of layer c.
    [[gnu::always_inline]] static std::size_t row_slot(const Slots &sl, int b, int c) {
        return sl.first + static_cast<std::size_t>(b) * sl.row +
               static_cast<std::size_t>(c) * sl.layer;
    }

    // Scatter: every node record gets
    //   w_i a + sum_d (dw_i/dx_d) grad[d] + w_i sum_d (x_i - x_p)_d off[d]
    // where the gradient terms (P2G: the internal force, node::kForce) fall
    // on the record's second half alone and the offset terms (the affine
    // momentum, node::kMomentum) on its first: each half is summed in its
    // own vectors (half records, H), without the multiply-adds of zeros a
    // whole record would do (a quarter of them; on Zen 4, whose 512-bit
    // operations take two 256-bit ones, a quarter of the cycles). a is given
    // as its halves a_lo, a_hi; grad the second halves, offs the first.
    // Upper: whether the second half gets anything (a_hi and grad nonzero);
    // Gradients, Offsets: whether grad and offs are used.
    template <bool Upper, bool Gradients, bool Offsets, class H>
    [[gnu::always_inline]] void scatter(const GridGeometry &g, double *records, const H &a_lo,
                                        const H &a_hi, const H (&grad)[D],
                                        const H (&offs)[D]) const {
        static_assert(Upper || !Gradients, "the gradient terms are the second half's");
        constexpr std::size_t half = node::kRecord / 2;
        const Self &st = self();
        const Slots sl = slots(g);
        for (int c = 0; c < (D == 3 ? W : 1); ++c)
            for (int b = 0; b < W; ++b) {
                // The row's factors: what node x of the row gets is
                // w_x(x) P + w_x(x) off_x(x) R (first half) and
                // w_x(x) U + dw_x(x) Q (second half).
                const double wz = D == 3 ? st.weight(D - 1, c) : 1.0;
                const double wyz = st.weight(1, b) * wz;
                H P = wyz * a_lo, R{}, U{}, Q{};
                if constexpr (Offsets) {
                    P += (wyz * st.offset(1, b)) * offs[1];
                    if constexpr (D == 3) P += (wyz * st.offset(2, c)) * offs[2];
                    R = wyz * offs[0];
                }
                if constexpr (Upper) U = wyz * a_hi;
                if constexpr (Gradients) {
                    U += (st.slope(1, b) * wz) * grad[1];
                    if constexpr (D == 3) U += (st.weight(1, b) * st.slope(2, c)) * grad[2];
                    Q = wyz * grad[0];
                }
                double *row = records + node::kRecord * row_slot(sl, b, c);
                for (int x = 0; x < W; ++x) {
                    double *rec = row + node::kRecord * static_cast<std::size_t>(x);
                    H lo;
                    load_record(rec, lo);
                    lo += st.weight(0, x) * P;
                    if constexpr (Offsets) lo += st.weighted_offset(0, x) * R;
                    store_record(rec, lo);
                    if constexpr (Upper) {
                        H hi;
                        load_record(rec + half, hi);
                        hi += st.weight(0, x) * U;
                        if constexpr (Gradients) hi += st.slope(0, x) * Q;
                        store_record(rec + half, hi);
                    }
                }
            }
    }

    // Gather: sum_i w_i r_i into `value`, sum_i (dw_i/dx_d) r_i into
    // grad[d], and sum_i w_i (x_i - x_p)_d r_i into offs[d], over the node
    // records r_i (Gradients, Offsets: whether grad and off are wanted).
    // G: the type of grad and offs, Lanes or its half record (the sums of
    // the records' first halves alone).
    template <bool Gradients, bool Offsets, class Lanes, class G>
    [[gnu::always_inline]] void gather(const GridGeometry &g, const double *records, Lanes &value,
                                       G (&grad)[D], G (&offs)[D]) const {
        constexpr bool half = !std::is_same_v<Lanes, G>;
        const Self &st = self();
        const Slots sl = slots(g);
        value = Lanes{};
        for (int d = 0; d < D; ++d)
            grad[d] = offs[d] = G{};
        for (int c = 0; c < (D == 3 ? W : 1); ++c)
            for (int b = 0; b < W; ++b) {
                const double *row = records + node::kRecord * row_slot(sl, b, c);
                // The row's sums over x: by w_x, dw_x and w_x off_x.
                Lanes S0{};
                G S1{}, S2{};
                for (int x = 0; x < W; ++x) {
                    const double *rec = row + node::kRecord * static_cast<std::size_t>(x);
                    Lanes r;
                    load_record(rec, r);
                    S0 += st.weight(0, x) * r;
                    G rg;
                    if constexpr (half)
                        load_record(rec, rg);
                    else
                        rg = r;
                    if constexpr (Gradients) S1 += st.slope(0, x) * rg;
                    if constexpr (Offsets) S2 += st.weighted_offset(0, x) * rg;
                }
                const double wz = D == 3 ? st.weight(D - 1, c) : 1.0;
                const double wyz = st.weight(1, b) * wz;
                value += wyz * S0;
                G S0g;
                if constexpr (half)
                    first_half(S0, S0g);
                else
                    S0g = S0;
                if constexpr (Gradients) {
                    grad[0] += wyz * S1;
                    grad[1] += (st.slope(1, b) * wz) * S0g;
                    if constexpr (D == 3) grad[2] += (st.weight(1, b) * st.slope(2, c)) * S0g;
                }
                if constexpr (Offsets) {
                    offs[0] += wyz * S2;
                    offs[1] += (wyz * st.offset(1, b)) * S0g;
                    if constexpr (D == 3) offs[2] += (wyz * st.offset(2, c)) * S0g;
                }
            }
    }

    // Calls f(slot) for every node with w_i > 0 (the rare per-node work:
    // the fixity a fixed particle gives the nodes it reaches).
    template <class F>
    void for_each_reached_node(const GridGeometry &g, F &&f) const {
        const Self &st = self();
        const Slots sl = slots(g);
        for (int c = 0; c < (D == 3 ? W : 1); ++c)
            for (int b = 0; b < W; ++b)
                for (int x = 0; x < W; ++x)
                    if (st.weight(0, x) * st.weight(1, b) * (D == 3 ? st.weight(D - 1, c) : 1.0) >
                        0.0)
                        f(row_slot(sl, b, c) + static_cast<std::size_t>(x));
    }
};

// One particle's stencil.
template <int D, class S>
struct Stencil : StencilSums<Stencil<D, S>, D, S::width> {
    static constexpr int W = S::width;
    int base[D];        // first node per axis (global node numbers)
    double w[D][W];     // weights per axis
    double dw[D][W];    // their derivatives, 1/m
    double off[D][W];   // x_i - x_p per axis, m (x_i: the node's Greville point)
    double w_off[D][W]; // w * off per axis
    // 1 / D_p per axis, 1/m^2: D_p = sum_i w_ip (x_i - x_p)(x_i - x_p)^T is
    // diagonal for a tensor-product kernel with linear precision (the cross
    // terms factor into sum_a w_a (x_a - x_p) = 0), h^2/4 (quadratic) or
    // h^2/3 (cubic) away from the faces (Jiang et al. 2015).
    double dinv[D];

    [[gnu::always_inline]] double weight(int d, int k) const { return w[d][k]; }
    [[gnu::always_inline]] double slope(int d, int k) const { return dw[d][k]; }
    [[gnu::always_inline]] double offset(int d, int k) const { return off[d][k]; }
    [[gnu::always_inline]] double weighted_offset(int d, int k) const { return w_off[d][k]; }
    [[gnu::always_inline]] int first(int d) const { return base[d]; }
    [[gnu::always_inline]] const double *inverse_moments() const { return dinv; }

    // Almost every particle is away from the faces, where the uniform kernel
    // holds. The hot kernels test this once per particle and run their
    // per-particle body in two instantiations, the uniform one inline and
    // the clamped one out of line: one branch inside the shared body slows
    // the uniform one through register allocation alone.
    [[gnu::always_inline]] static bool interior(const GridGeometry &g, const ParticleSet &s,
                                                std::size_t p) {
        bool inner = true;
        for (int d = 0; d < D; ++d) {
            const std::size_t dd = static_cast<std::size_t>(d);
            inner = inner && S::interior((s.x[dd][p] - g.origin[dd]) * g.inv_h, g.cells[dd]);
        }
        return inner;
    }

    // Near == false requires interior(g, s, p). Offsets: also off, w_off
    // and dinv (the affine transfers).
    template <bool Near, bool Offsets>
    [[gnu::always_inline]] void eval(const GridGeometry &g, const ParticleSet &s, std::size_t p) {
        for (int d = 0; d < D; ++d) {
            const std::size_t dd = static_cast<std::size_t>(d);
            const double xi = (s.x[dd][p] - g.origin[dd]) * g.inv_h;
            [[maybe_unused]] double node_point[W];
            // Only GIMP has the lp column (ParticleSet::has_lp).
            const double lp = S::half_width ? s.lp[p] : 0.0;
            if constexpr (Near)
                S::eval_bounded(xi, lp, g.cells[dd], base[d], w[d], dw[d], node_point);
            else
                S::eval(xi, lp, base[d], w[d], dw[d]);
            for (int k = 0; k < W; ++k)
                dw[d][k] *= g.inv_h; // d/dx = d/dxi / h, once per axis
            if constexpr (Offsets) {
                for (int k = 0; k < W; ++k) {
                    const double at = Near ? node_point[k] : static_cast<double>(base[d] + k);
                    off[d][k] = (at - xi) * g.h;
                    w_off[d][k] = w[d][k] * off[d][k];
                }
                if constexpr (Near) {
                    const double m2 = second_moment<W>(w[d], node_point, xi) * g.h * g.h;
                    dinv[d] = m2 > 0.0 ? 1.0 / m2 : 0.0;
                } else {
                    dinv[d] = g.affine_dinv;
                }
            }
        }
    }
};

// The stencils of N particles away from the faces, evaluated together with
// one particle a vector lane (lanes.hpp): the weights' arithmetic, the
// same operations as Stencil::eval's, costs a pack what it costs one
// particle. The sums then run particle by particle, each on its lane of
// the pack's factors (lane(j)), read from memory as the broadcasts they
// need anyway. For the kernels whose pieces are the same polynomials
// everywhere away from the faces (the B-splines: S::pieces); a particle
// near a face gets the clamped functions in its lane (clamp_lanes).
template <int D, class S, int N>
struct StencilPack {
    static constexpr int W = S::width;
    using V = typename Lanes<N>::V;
    int base[D][N];
    double w[D][W][N], dw[D][W][N], off[D][W][N], w_off[D][W][N];
    double dinv[D]; // as Stencil's, the same for every particle away from the faces
    static constexpr std::size_t size() { return N; }

    struct Lane : StencilSums<Lane, D, W> {
        const StencilPack *pk;
        std::size_t j;
        [[gnu::always_inline]] double weight(int d, int k) const { return pk->w[d][k][j]; }
        [[gnu::always_inline]] double slope(int d, int k) const { return pk->dw[d][k][j]; }
        [[gnu::always_inline]] double offset(int d, int k) const { return pk->off[d][k][j]; }
        [[gnu::always_inline]] double weighted_offset(int d, int k) const {
            return pk->w_off[d][k][j];
        }
        [[gnu::always_inline]] int first(int d) const { return pk->base[d][j]; }
        [[gnu::always_inline]] const double *inverse_moments() const { return pk->dinv; }
    };
    [[gnu::always_inline]] Lane lane(std::size_t j) const {
        Lane l;
        l.pk = this;
        l.j = j;
        return l;
    }

    // The pack of particles index[0..N) of s (eval), or first .. first + N
    // (eval_run). Offsets: also off, w_off and dinv; then false, with
    // nothing done, if one of them is near a face (Stencil::interior),
    // whose offsets and moments are its own, not the pack's.
    template <bool Offsets>
    [[gnu::always_inline]] bool eval(const GridGeometry &g, const ParticleSet &s,
                                     const std::uint32_t *index) {
        return eval_with<Offsets>(
            g, [&](std::size_t d, V & x)
                   __attribute__((always_inline)) { load_indexed<N>(s.x[d].data(), index, x); });
    }
    template <bool Offsets>
    [[gnu::always_inline]] bool eval_run(const GridGeometry &g, const ParticleSet &s,
                                         std::size_t first) {
        return eval_with<Offsets>(
            g, [&](std::size_t d, V & x)
                   __attribute__((always_inline)) { load_vector<N>(&s.x[d][first], x); });
    }
    template <bool Offsets, class Load>
    [[gnu::always_inline]] bool eval_with(const GridGeometry &g, const Load &load) {
        V xi[D];
        // Lanes of ones for a particle near a face (or at NaN), tested once
        // for the pack (any_lane, lanes.hpp: a test per lane was built from
        // scalar compares).
        const V zero{}, one = zero + 1.0;
        V near{};
        for (int d = 0; d < D; ++d) {
            const std::size_t dd = static_cast<std::size_t>(d);
            V x;
            load(dd, x);
            xi[d] = (x - g.origin[dd]) * g.inv_h;
            const V lo = zero + static_cast<double>(S::interior_margin);
            const V hi = zero + (g.cells[dd] - S::interior_margin);
            near += xi[d] >= lo ? zero : one;
            near += xi[d] < hi ? zero : one;
        }
        const bool clamped = any_lane<N>(near);
        if constexpr (Offsets)
            if (clamped) return false;
        typedef int Ints __attribute__((vector_size(N * sizeof(int))));
        for (int d = 0; d < D; ++d) {
            V fl;
            floor_lanes<N>(xi[d] - S::floor_shift, fl);
            V wv[W], dwv[W];
            S::pieces(xi[d], fl, wv, dwv);
            const V first = fl + static_cast<double>(S::base_offset);
            // Whole numbers within the grid: the conversion is exact.
            const Ints first_int = __builtin_convertvector(first, Ints);
            std::memcpy(base[d], &first_int, sizeof first_int);
            for (int k = 0; k < W; ++k) {
                store_vector<N>(w[d][k], wv[k]);
                store_vector<N>(dw[d][k], dwv[k] * g.inv_h);
                if constexpr (Offsets) {
                    const V o = (first + static_cast<double>(k) - xi[d]) * g.h;
                    store_vector<N>(off[d][k], o);
                    store_vector<N>(w_off[d][k], wv[k] * o);
                }
            }
            if constexpr (Offsets) dinv[d] = g.affine_dinv;
        }
        if (clamped) [[unlikely]] {
            alignas(64) double at[D][N];
            for (int d = 0; d < D; ++d)
                store_vector<N>(at[d], xi[d]);
            clamp_lanes(g, at);
        }
        return true;
    }

    // The lanes of the particles near a face (S::interior false on an
    // axis, or xi NaN): their weights, slopes and first nodes as
    // Stencil::eval<true> computes them, S::eval_bounded on every axis.
    // On an axis where such a particle is interior that is S::eval, the
    // uniform values above, but computed here, in code for the baseline:
    // the P2G and G2P kernels contract their multiply-adds where the
    // target has them, eval_bounded (baseline) does not, and this keeps a
    // particle's weights the bits they had when such a pack went particle
    // by particle. It did, all N of them, outside the lanes
    // (bench/results/2026-11-29-near-face-packs-ice-lake.md). Out of line and
    // scalar: a function does not inherit the AVX-512 kernel's target
    // (OutOfLine), and this one takes nothing but arrays.
    [[gnu::noinline]] void clamp_lanes(const GridGeometry &g, const double (&at)[D][N]) {
        for (int j = 0; j < N; ++j) {
            bool interior[D], inner = true;
            for (int d = 0; d < D; ++d) {
                interior[d] = S::interior(at[d][j], g.cells[static_cast<std::size_t>(d)]);
                inner = inner && interior[d];
            }
            if (inner) continue;
            for (int d = 0; d < D; ++d) {
                int b;
                double wj[W], dwj[W], node_point[W];
                if (interior[d])
                    S::eval(at[d][j], 0.0, b, wj, dwj);
                else
                    S::eval_bounded(at[d][j], 0.0, g.cells[static_cast<std::size_t>(d)], b, wj, dwj,
                                    node_point);
                base[d][j] = b;
                for (int k = 0; k < W; ++k) {
                    w[d][k][j] = wj[k];
                    dw[d][k][j] = dwj[k] * g.inv_h;
                }
            }
        }
    }
};

// The versions of a kernel for each instruction set (isa.hpp): the same
// source, Impl::run<L, I>(args), inlined into one function per target and
// compiled for it. A pass picks one per call (an indirect call per block
// of particles, never per particle).
template <class Impl>
struct IsaVersions {
    using Args = typename Impl::Args;
    using Fn = void (*)(const Args &);
    static void generic(const Args &a) { Impl::template run<Arr8, Isa::generic>(a); }
    TALUS_TARGET_AVX2 static void avx2(const Args &a) { Impl::template run<Quad8, Isa::avx2>(a); }
    TALUS_TARGET_AVX512 static void avx512(const Args &a) {
        Impl::template run<Vec8, Isa::avx512>(a);
    }
    static Fn pick(Isa isa) {
        if constexpr (TALUS_HAS_ISA_VERSIONS) {
            if (isa == Isa::avx512) return &avx512;
            if (isa == Isa::avx2) return &avx2;
        }
        return &generic;
    }
};

// Calls f(p) in a function of its own compiled for instruction set I: the
// kernels' rare path (a particle near a face) kept out of their loop. A
// function does not inherit its caller's target: a plain noinline lambda in
// the AVX-512 kernel is compiled for the baseline, where Vec8 is lowered
// through the stack, and the particles next to a face would run that slow
// code (bench/results/2026-11-24-material-block-and-what-was-tried-epyc-zen4.md).
// f must be always_inline.
template <Isa I>
struct OutOfLine {
    template <class F>
    [[gnu::noinline]] static void call(const F &f, std::size_t p) {
        f(p);
    }
};
template <>
struct OutOfLine<Isa::avx2> {
    template <class F>
    [[gnu::noinline]] TALUS_TARGET_AVX2 static void call(const F &f, std::size_t p) {
        f(p);
    }
};
template <>
struct OutOfLine<Isa::avx512> {
    template <class F>
    [[gnu::noinline]] TALUS_TARGET_AVX512 static void call(const F &f, std::size_t p) {
        f(p);
    }
};

// Runs f.template operator()<S>() for the run's kernel, in dimension D.
template <int D, class F>
void with_shape(ShapeKind shape, F &&f) {
    switch (shape) {
    case ShapeKind::linear: f.template operator()<LinearShape>(); break;
    case ShapeKind::gimp: f.template operator()<GimpShape>(); break;
    case ShapeKind::bspline2: f.template operator()<BSpline2Shape>(); break;
    case ShapeKind::bspline3: f.template operator()<BSpline3Shape>(); break;
    }
}

// Runs f.template operator()<D, S>() for the run's dimension and kernel:
// the one runtime choice per pass that selects the compiled kernels.
template <class F>
void with_kernel(int dim, ShapeKind shape, F &&f) {
    auto by_shape = [&]<int D>() {
        with_shape<D>(shape, [&]<class S>() { f.template operator()<D, S>(); });
    };
    if (dim == 2)
        by_shape.template operator()<2>();
    else
        by_shape.template operator()<3>();
}

} // namespace talus
