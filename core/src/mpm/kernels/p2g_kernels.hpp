// The P2G kernels as templates of the dimension, shape and pass: each
// dimension's instances are compiled in a file of their own (p2g_2d.cpp,
// p2g_3d.cpp), so that the two build in parallel. Internal to p2g*.cpp.
#pragma once

#include "kernels/isa.hpp"
#include "kernels/stencil.hpp"
#include "method/p2g.hpp"
#include "parallel/parallel.hpp"

#include <cstdint>
#include <type_traits>

namespace talus::p2g_kernels {

// Asks for the lines a pack of particles from p on will read (one line of
// each column holds 8 of them; the stress, 48 bytes each, six), a few packs
// ahead. The slabs' particles are contiguous runs in memory, but the
// hardware's prefetch does not keep up with the ten streams of a pass that
// visits them through an index list. Two, three or six packs ahead do
// alike. (The lines lie within the arrays: a slab's indices increase, so
// the pack's last one is at least p + 7, and p + 7 < n.)
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
// arithmetic in L (stencil.hpp): each particle's contributions (p2g.hpp),
// scattered through its stencil by record halves, mass and momentum in the
// first, the force in the second.
template <class L, Isa I, int D, class S, bool Mass, bool Momentum, bool Affine, bool Forces>
class P2gParticles {
  public:
    [[gnu::always_inline]] P2gParticles(const P2gSources &src, double *acc, const ParticleSet &s)
        : src_(src), g_(src.geo), acc_(acc), s_(s), grav_(src.loads.gravity()) {}

    [[gnu::always_inline]] void run(const std::uint32_t *begin, const std::uint32_t *end) {
        const std::uint32_t *k = begin;
        if constexpr (requires { S::interior_margin; }) {
            // Packs of N particles, their stencils evaluated together; with
            // the affine transfers a pack with a particle near a face goes
            // one by one (StencilPack::eval).
            constexpr int N = kPointLanes<I>;
            StencilPack<D, S, N> pack;
            for (; end - k >= N; k += N) {
                if (end - k >= (kPacksAhead + 1) * N) prefetch_pack(s_, k[kPacksAhead * N]);
                // A slab's particles are mostly runs of consecutive indices:
                // then the positions are one vector load an axis.
                const bool run = k[N - 1] - k[0] == N - 1;
                if (run ? pack.template eval_run<Affine>(g_, s_, k[0])
                        : pack.template eval<Affine>(g_, s_, k)) [[likely]] {
                    if constexpr (kPackRecords)
                        if (run && scatter_pack(pack, k)) continue;
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

  private:
    using St = Stencil<D, S>;
    using H = typename HalfRecord<L>::type;
    static constexpr std::size_t half = node::kRecord / 2;
    static_assert(node::kMass < half && node::kMomentum + 3 <= half && node::kForce == half,
                  "mass and momentum fill a record's first half, the force its second");
    static constexpr std::size_t f =
        node::kForce - half; // the force's first lane in the second half

    // The nodes a fixed particle reaches carry its fixity
    // (Boundary::apply): a constraint the grid sees.
    template <class Point>
    [[gnu::always_inline]] void fixity(const Point &st, std::size_t p) {
        if (const std::uint32_t fixed = Mass ? s_.fix_mask[p] : 0u) [[unlikely]]
            st.for_each_reached_node(g_, [&](std::size_t slot) {
                double &bits = acc_[node::kRecord * slot + node::kFixity];
                bits = static_cast<double>(static_cast<std::uint32_t>(bits) | fixed);
            });
    }

    // One particle through its stencil st (a Stencil or a lane of a
    // StencilPack): per unit weight mass, momentum and the external force,
    // per unit gradient along c the internal force, per unit weight and
    // offset along c the affine momentum m C[:, c].
    template <class Point>
    [[gnu::always_inline]] void scatter(const Point &st, std::size_t p) {
        const double m = s_.mass[p];
        H a_lo{}, a_hi{}, grad[D]{}, offs[D]{};
        if constexpr (Mass) set_lane(a_lo, node::kMass, m);
        if constexpr (Momentum)
            for (int d = 0; d < D; ++d) {
                double mv;
                particle_momentum(m, s_.v[static_cast<std::size_t>(d)][p], mv);
                set_lane(a_lo, node::kMomentum + static_cast<std::size_t>(d), mv);
            }
        if constexpr (Affine)
            for (int r = 0; r < D; ++r)
                for (int c = 0; c < D; ++c)
                    set_lane(offs[c], node::kMomentum + static_cast<std::size_t>(r),
                             m * s_.C[9 * p + static_cast<std::size_t>(3 * r + c)]);
        if constexpr (Forces) {
            double per_gradient[D][D];
            internal_force<D>(s_.J[p] * s_.vol0[p], &s_.stress[6 * p], per_gradient);
            for (int c = 0; c < D; ++c)
                for (int r = 0; r < D; ++r)
                    set_lane(grad[c], f + static_cast<std::size_t>(r), per_gradient[c][r]);
            double fext[D] = {};
            if (s_.load_mask[p]) src_.loads.particle_force<D>(s_.load_mask[p], s_.group[p], fext);
            for (int d = 0; d < D; ++d) {
                double force;
                external_force(m, grav_[d], fext[d], force);
                set_lane(a_hi, f + static_cast<std::size_t>(d), force);
            }
        }
        st.template scatter<Forces, Forces, Affine>(g_, acc_, a_lo, a_hi, grad, offs);
        fixity(st, p);
    }

    template <bool Near>
    [[gnu::always_inline]] void body(std::size_t p) {
        St st;
        st.template eval<Near, Affine>(g_, s_, p);
        scatter(st, p);
    }

    // The uniform kernel inline, the clamped one near a face out of line.
    [[gnu::always_inline]] void one(std::size_t p) {
        if (St::interior(g_, s_, p)) [[likely]] {
            body<false>(p);
        } else {
            auto near_face = [this](std::size_t q) __attribute__((always_inline)) {
                body<true>(q);
            };
            OutOfLine<I>::call(near_face, p);
        }
    }

    // The records of a run of 8 consecutive particles (AVX-512): each
    // quantity for the 8 in the lanes of one vector (scatter's
    // contributions, lane by lane), then turned into the particles' half
    // records by 4 x 8 transposes (lanes_to_quads) and scattered. Particle
    // by particle, the scalar loads and the lane inserts that build the
    // records took more of P2G than their arithmetic. False, with nothing
    // scattered, if a particle of the pack has a load of its own
    // (Loads::particle_force).
    static constexpr bool kPackRecords = I == Isa::avx512 && !Affine && TALUS_HAS_SHUFFLEVECTOR;
    struct Made {
        alignas(64) double lo[32], hi[32], grad[D][32];
    };
    template <class Pack>
    [[gnu::always_inline]] bool scatter_pack([[maybe_unused]] const Pack &pack,
                                             [[maybe_unused]] const std::uint32_t *k) {
#if TALUS_HAS_SHUFFLEVECTOR
        if constexpr (kPackRecords) {
            static_assert(kPointLanes<I> == 8, "a pack is one 8-lane vector a quantity");
            Made made;
            if (!pack_records(k[0], made)) return false;
            for (int j = 0; j < 8; ++j) {
                const std::size_t at = quad_at(static_cast<std::size_t>(j));
                // Without forces the scatter reads a_lo alone.
                H a_lo, a_hi{}, grad[D]{};
                load_record(made.lo + at, a_lo);
                if constexpr (Forces) {
                    load_record(made.hi + at, a_hi);
                    for (int d = 0; d < D; ++d)
                        load_record(made.grad[d] + at, grad[d]);
                }
                const H offs[D]{};
                const auto &st = pack.lane(static_cast<std::size_t>(j));
                st.template scatter<Forces, Forces, Affine>(g_, acc_, a_lo, a_hi, grad, offs);
                fixity(st, k[j]);
            }
            return true;
        }
#endif
        return false;
    }

#if TALUS_HAS_SHUFFLEVECTOR
    [[gnu::always_inline]] bool pack_records(std::size_t p0, Made &made) {
        using V = Lanes<8>::V;
        std::uint32_t loaded = 0;
        if constexpr (Forces)
            for (std::size_t j = 0; j < 8; ++j)
                loaded |= s_.load_mask[p0 + j];
        if (loaded != 0) return false;
        const V zero{};
        V m, lo[4] = {zero, zero, zero, zero};
        load_vector<8>(&s_.mass[p0], m);
        if constexpr (Mass) lo[node::kMass] = m;
        if constexpr (Momentum)
            for (int d = 0; d < D; ++d) {
                V v;
                load_vector<8>(&s_.v[static_cast<std::size_t>(d)][p0], v);
                particle_momentum(m, v, lo[node::kMomentum + static_cast<std::size_t>(d)]);
            }
        lanes_to_quads(lo, made.lo);
        if constexpr (Forces) {
            V J, vol0, sg[6];
            load_vector<8>(&s_.J[p0], J);
            load_vector<8>(&s_.vol0[p0], vol0);
            load_points<8>(&s_.stress[6 * p0], sg);
            V hi[4] = {zero, zero, zero, zero};
            for (int d = 0; d < D; ++d)
                external_force(m, grav_[d], zero, hi[f + static_cast<std::size_t>(d)]);
            lanes_to_quads(hi, made.hi);
            V per_gradient[D][D];
            internal_force<D>(J * vol0, sg, per_gradient);
            for (int c = 0; c < D; ++c) {
                V column[4] = {zero, zero, zero, zero};
                for (int r = 0; r < D; ++r)
                    column[r] = per_gradient[c][r];
                lanes_to_quads(column, made.grad[c]);
            }
        }
        return true;
    }
#endif

    const P2gSources &src_;
    const GridGeometry &g_;
    double *const acc_;
    const ParticleSet &s_;
    const double *const grav_;
};

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
        P2gParticles<L, I, D, S, Mass, Momentum, Affine, Forces> particles(*a.src, a.acc, *a.s);
        particles.run(a.begin, a.end);
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
