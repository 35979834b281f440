// The P2G kernels as templates of the dimension, shape and pass: each
// dimension's instances are compiled in a file of their own (p2g_2d.cpp,
// p2g_3d.cpp), so that the two build in parallel. Internal to p2g*.cpp.
#pragma once

#include "isa.hpp"
#include "p2g.hpp"
#include "parallel.hpp"
#include "stencil.hpp"

#include <cstdint>
#include <type_traits>

namespace talus::p2g_kernels {

// Asks for the lines a pack of particles from p on will read (one line of
// each column holds 8 of them; the stress, 48 bytes each, six), a few packs
// ahead. The slabs' particles are contiguous runs in memory, but the
// hardware's prefetch did not keep up with the ten streams of a pass
// that visits them through an index list: with this, P2G took 0.26 s per
// 25M particle-steps in 2D (one thread) against 0.33 s. Two, three or six
// packs ahead measured alike. (The lines lie within the arrays: a slab's
// indices increase, so the pack's last one is at least p + 7, and p + 7 < n.)
inline constexpr long kPacksAhead = 3;
[[gnu::always_inline]] inline void prefetch_pack(const ParticleSet &s, std::size_t p) {
    for (int d = 0; d < s.dim; ++d) {
        __builtin_prefetch(&s.x[static_cast<std::size_t>(d)][p], 0, 3);
        __builtin_prefetch(&s.v[static_cast<std::size_t>(d)][p], 0, 3);
    }
    __builtin_prefetch(&s.mass[p], 0, 3);
    __builtin_prefetch(&s.J[p], 0, 3);
    __builtin_prefetch(&s.vol0[p], 0, 3);
    for (std::size_t k = 0; k < 48; k += 8)
        __builtin_prefetch(&s.stress[6 * p + k], 0, 3);
}

// The particles [begin, end) of set s (indices), with the node-record
// arithmetic in L (stencil.hpp).
template <class L, Isa I, int D, class S, bool Mass, bool Momentum, bool Affine, bool Forces>
[[gnu::always_inline]] inline void p2g_particles(const P2gSources &src, double *acc,
                                                 const ParticleSet &s, const std::uint32_t *begin,
                                                 const std::uint32_t *end) {
    const GridGeometry &g = src.geo;
    const double *grav = src.loads.gravity();
    using St = Stencil<D, S>;
    // One particle's contributions, scattered through its stencil st (a
    // Stencil or a lane of a StencilPack), by record halves (stencil.hpp):
    // mass and momentum in the first, the force in the second.
    using H = typename HalfRecord<L>::type;
    constexpr std::size_t half = node::kRecord / 2;
    static_assert(node::kMass < half && node::kMomentum + 3 <= half && node::kForce == half,
                  "mass and momentum fill a record's first half, the force its second");
    constexpr std::size_t f = node::kForce - half; // the force's first lane in the second half
    // The nodes a fixed particle reaches carry its fixity
    // (Boundary::apply): a constraint the grid sees.
    auto fixity = [&](const auto &st, std::size_t p) __attribute__((always_inline)) {
        if (const std::uint32_t fixed = Mass ? s.fix_mask[p] : 0u) [[unlikely]]
            st.for_each_reached_node(g, [&](std::size_t slot) {
                double &bits = acc[node::kRecord * slot + node::kFixity];
                bits = static_cast<double>(static_cast<std::uint32_t>(bits) | fixed);
            });
    };
    // The scatter of records made already (pack_records).
    auto scatter_made = [&](const auto &st, std::size_t p, const H &a_lo, const H &a_hi,
                            const H(&grad)[D]) __attribute__((always_inline)) {
        const H offs[D]{};
        st.template scatter<Forces, Forces, Affine>(g, acc, a_lo, a_hi, grad, offs);
        fixity(st, p);
    };
    auto scatter = [&](const auto &st, std::size_t p) __attribute__((always_inline)) {
        const double m = s.mass[p];
        // Per unit weight: mass and momentum (eqs. 28-29) and the
        // external force (eq. 21); per unit gradient along c: the
        // internal force -V sigma[:, c] (eq. 20); per unit weight
        // and offset along c: the affine momentum m C[:, c].
        H a_lo{}, a_hi{}, grad[D]{}, offs[D]{};
        if constexpr (Mass) set_lane(a_lo, node::kMass, m);
        if constexpr (Momentum)
            for (int d = 0; d < D; ++d)
                set_lane(a_lo, node::kMomentum + static_cast<std::size_t>(d),
                         m * s.v[static_cast<std::size_t>(d)][p]);
        if constexpr (Affine)
            for (int r = 0; r < D; ++r)
                for (int c = 0; c < D; ++c)
                    set_lane(offs[c], node::kMomentum + static_cast<std::size_t>(r),
                             m * s.C[9 * p + static_cast<std::size_t>(3 * r + c)]);
        if constexpr (Forces) {
            const double V = s.J[p] * s.vol0[p];
            const double *sg = &s.stress[6 * p];
            // Voigt (xx, yy, zz, xy, yz, zx); the in-plane part for D = 2.
            set_lane(grad[0], f, -V * sg[0]);
            set_lane(grad[1], f + 1, -V * sg[1]);
            set_lane(grad[0], f + 1, -V * sg[3]);
            set_lane(grad[1], f, -V * sg[3]);
            if constexpr (D == 3) {
                set_lane(grad[2], f + 2, -V * sg[2]);
                set_lane(grad[1], f + 2, -V * sg[4]);
                set_lane(grad[2], f + 1, -V * sg[4]);
                set_lane(grad[0], f + 2, -V * sg[5]);
                set_lane(grad[2], f, -V * sg[5]);
            }
            double fext[D] = {};
            if (s.load_mask[p]) src.loads.particle_force<D>(s.load_mask[p], s.group[p], fext);
            for (int d = 0; d < D; ++d)
                set_lane(a_hi, f + static_cast<std::size_t>(d), fext[d] + m * grav[d]);
        }
        st.template scatter<Forces, Forces, Affine>(g, acc, a_lo, a_hi, grad, offs);
        fixity(st, p);
    };
    auto body = [&](auto near, std::size_t p) __attribute__((always_inline)) {
        St st;
        st.template eval<decltype(near)::value, Affine>(g, s, p);
        scatter(st, p);
    };
    auto near_face = [&](std::size_t p) __attribute__((always_inline)) {
        body(std::true_type{}, p);
    };
    auto one = [&](std::size_t p) __attribute__((always_inline)) {
        if (St::interior(g, s, p)) [[likely]]
            body(std::false_type{}, p);
        else
            OutOfLine<I>::call(near_face, p);
    };
    // The records of a pack of 8 consecutive particles from p0 (AVX-512):
    // each quantity for the 8 in the lanes of one vector (the same products
    // as scatter's, lane by lane), then turned into the particles' half
    // records by 4 x 8 transposes (lanes_to_quads). Particle by particle,
    // the scalar loads and the lane inserts that build the records took
    // more of P2G than their arithmetic. False, with nothing made, if a
    // particle of the pack has a load of its own (Loads::particle_force).
    struct Made {
        alignas(64) double lo[32], hi[32], grad[D][32];
    } made;
    auto pack_records = [&](std::size_t p0) __attribute__((always_inline)) {
#if TALUS_HAS_SHUFFLEVECTOR
        if constexpr (I == Isa::avx512) {
            static_assert(kPointLanes<I> == 8, "a pack is one 8-lane vector a quantity");
            using V = Lanes<8>::V;
            std::uint32_t loaded = 0;
            if constexpr (Forces)
                for (std::size_t j = 0; j < 8; ++j)
                    loaded |= s.load_mask[p0 + j];
            if (loaded != 0) return false;
            const V zero{};
            V m, lo[4] = {zero, zero, zero, zero};
            load_vector<8>(&s.mass[p0], m);
            if constexpr (Mass) lo[node::kMass] = m;
            if constexpr (Momentum)
                for (int d = 0; d < D; ++d) {
                    V v;
                    load_vector<8>(&s.v[static_cast<std::size_t>(d)][p0], v);
                    lo[node::kMomentum + static_cast<std::size_t>(d)] = m * v;
                }
            lanes_to_quads(lo, made.lo);
            if constexpr (Forces) {
                V J, vol0, sg[6];
                load_vector<8>(&s.J[p0], J);
                load_vector<8>(&s.vol0[p0], vol0);
                load_points<8>(&s.stress[6 * p0], sg);
                const V nV = -(J * vol0);
                V hi[4] = {zero, zero, zero, zero};
                for (int d = 0; d < D; ++d)
                    hi[f + static_cast<std::size_t>(d)] = zero + m * grav[d];
                lanes_to_quads(hi, made.hi);
                // Voigt (xx, yy, zz, xy, yz, zx), as in scatter.
                const V xx = nV * sg[0], yy = nV * sg[1], xy = nV * sg[3];
                if constexpr (D == 2) {
                    const V g0[4] = {xx, xy, zero, zero}, g1[4] = {xy, yy, zero, zero};
                    lanes_to_quads(g0, made.grad[0]);
                    lanes_to_quads(g1, made.grad[1]);
                } else {
                    const V zz = nV * sg[2], yz = nV * sg[4], zx = nV * sg[5];
                    const V g0[4] = {xx, xy, zx, zero}, g1[4] = {xy, yy, yz, zero},
                            g2[4] = {zx, yz, zz, zero};
                    lanes_to_quads(g0, made.grad[0]);
                    lanes_to_quads(g1, made.grad[1]);
                    lanes_to_quads(g2, made.grad[2]);
                }
            }
            return true;
        }
#endif
        (void)p0;
        return false;
    };
    const std::uint32_t *k = begin;
    if constexpr (requires { S::interior_margin; }) {
        // Packs of N particles, their stencils evaluated together; with the
        // affine transfers a pack with a particle near a face goes one by
        // one (StencilPack::eval).
        constexpr int N = kPointLanes<I>;
        StencilPack<D, S, N> pack;
        for (; end - k >= N; k += N) {
            if (end - k >= (kPacksAhead + 1) * N) prefetch_pack(s, k[kPacksAhead * N]);
            // A slab's particles are mostly runs of consecutive indices:
            // then the positions are one vector load an axis.
            const bool run = k[N - 1] - k[0] == N - 1;
            if (run ? pack.template eval_run<Affine>(g, s, k[0])
                    : pack.template eval<Affine>(g, s, k)) [[likely]] {
                if constexpr (I == Isa::avx512 && !Affine && TALUS_HAS_SHUFFLEVECTOR) {
                    if (run && pack_records(k[0])) {
                        for (int j = 0; j < N; ++j) {
                            const std::size_t at = quad_at(static_cast<std::size_t>(j));
                            // Without forces the scatter reads a_lo alone.
                            H a_lo, a_hi{}, grad[D]{};
                            load_record(made.lo + at, a_lo);
                            if constexpr (Forces) {
                                load_record(made.hi + at, a_hi);
                                for (int d = 0; d < D; ++d)
                                    load_record(made.grad[d] + at, grad[d]);
                            }
                            scatter_made(pack.lane(static_cast<std::size_t>(j)), k[j], a_lo, a_hi,
                                         grad);
                        }
                        continue;
                    }
                }
                for (int j = 0; j < N; ++j)
                    scatter(pack.lane(static_cast<std::size_t>(j)), k[j]);
            } else {
                for (int j = 0; j < N; ++j)
                    one(k[j]);
            }
        }
    }
    for (; k != end; ++k)
        one(*k);
}

template <int D, class S, bool Mass, bool Momentum, bool Affine, bool Forces>
struct P2gKernel {
    struct Args {
        const P2gSources *src;
        double *acc;
        const ParticleSet *s;
        const std::uint32_t *begin, *end;
    };
    template <class L, Isa I>
    [[gnu::always_inline]] static void run(const Args &a) {
        p2g_particles<L, I, D, S, Mass, Momentum, Affine, Forces>(*a.src, a.acc, *a.s, a.begin,
                                                                  a.end);
    }
};

template <int D, class S, bool Mass, bool Momentum, bool Affine, bool Forces>
void p2g_pass(const P2gSources &src, double *acc) {
    using K = P2gKernel<D, S, Mass, Momentum, Affine, Forces>;
    const auto kernel = IsaVersions<K>::pick(src.isa);
    par::for_each_slab_by_colour(src.order.n_slabs(), [&](int slab) {
        for (std::size_t si = 0; si < src.sets.size(); ++si) {
            const Ordering::Range r = src.order.slab(si, slab);
            kernel(typename K::Args{&src, acc, &src.sets[si], r.begin, r.end});
        }
    });
}

// The passes of p2g.hpp, one function each.
enum class Pass {
    momentum,
    momentum_affine,
    forces,
    momentum_and_forces,
    momentum_affine_and_forces,
    remap
};

template <int D>
void run(Pass pass, const P2gSources &src, double *acc) {
    with_shape<D>(src.shape, [&]<class S>() {
        switch (pass) {
        case Pass::momentum: p2g_pass<D, S, true, true, false, false>(src, acc); break;
        case Pass::momentum_affine: p2g_pass<D, S, true, true, true, false>(src, acc); break;
        case Pass::forces: p2g_pass<D, S, false, false, false, true>(src, acc); break;
        case Pass::momentum_and_forces: p2g_pass<D, S, true, true, false, true>(src, acc); break;
        case Pass::momentum_affine_and_forces:
            p2g_pass<D, S, true, true, true, true>(src, acc);
            break;
        case Pass::remap: p2g_pass<D, S, false, true, false, false>(src, acc); break;
        }
    });
}

extern template void run<2>(Pass, const P2gSources &, double *);
extern template void run<3>(Pass, const P2gSources &, double *);

} // namespace talus::p2g_kernels
