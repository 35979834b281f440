// The G2P kernels as templates of the dimension, shape, transfer and pass:
// each dimension's instances are compiled in a file of their own
// (g2p_2d.cpp, g2p_3d.cpp), so that the two build in parallel. Internal
// to g2p*.cpp.
#pragma once

#include "kernels/isa.hpp"
#include "kernels/stencil.hpp"
#include "method/g2p.hpp"
#include "method/transfer.hpp"
#include "parallel/parallel.hpp"

#include <algorithm>
#include <type_traits>

namespace talus::g2p_kernels {

// With the material update fused in, the block's update reads each point's
// F, stress, state, J and stress work (and the initial volume) for the
// first time in the step and writes them and the wave speed: about 300
// bytes a point in 3D, from memory. Asked for while the gather computes (a prefetch, for writing,
// per cache line they start in), they arrive while it works instead of stalling the update, which
// would wait for them at the memory's rate.
[[gnu::always_inline]] inline void prefetch_material(const ParticleSet &s, std::size_t p) {
    auto lines = [](const double *a, std::size_t n) __attribute__((always_inline)) {
        // The lines of [a, a + n): each starts within 8 doubles of the last.
        for (std::size_t k = 0; k < n; k += 8)
            __builtin_prefetch(a + k, 1, 3);
        __builtin_prefetch(a + n - 1, 1, 3);
    };
    lines(&s.F[s.F_size() * p], s.F_size());
    lines(&s.stress[6 * p], 6);
    if (s.state_size) lines(&s.state[s.state_size * p], s.state_size);
    if (p % 8 == 0) {
        __builtin_prefetch(&s.J[p], 1, 3);
        __builtin_prefetch(&s.work[p], 1, 3);
        __builtin_prefetch(&s.c[p], 1, 3);
        __builtin_prefetch(&s.vol0[p], 0, 3); // the stress work's volume, read only
    }
}

// The lines a pack of particles from p on reads and writes first in the
// fused pass (positions, velocities, the fixity mask; one line of each
// column holds 8 of them), asked for kMotionPacksAhead packs ahead. With
// the material block's columns the pass runs more than a dozen streams,
// more than the hardware's prefetch keeps up with once a second thread (or
// another tenant of the host) loads the memory: docs/performance.md, "On
// an AMD EPYC (Zen 5)".
inline constexpr std::size_t kMotionPacksAhead = 2;
[[gnu::always_inline]] inline void prefetch_motion(const ParticleSet &s, std::size_t p) {
    for (int d = 0; d < s.dim; ++d) {
        __builtin_prefetch(&s.x[static_cast<std::size_t>(d)][p], 1, 3);
        __builtin_prefetch(&s.v[static_cast<std::size_t>(d)][p], 1, 3);
    }
    __builtin_prefetch(&s.fix_mask[p], 0, 3);
}

// The fused pass's chunk for a set of n particles and material blocks of
// B. Whole blocks, so that every block starts at a multiple of B, as the
// blocks' partial results are filed (StepEndBlocks). And long ones, as
// the set allows: the chunks are dealt out in turn, and at the end of each
// a thread's dozen streams jump past the other thread's chunk, where the
// hardware's prefetch starts again. 8192 particles (64 KB of each double
// column) where the set has 16 such chunks a thread, down to 512 where it
// has not (a small set still splits across the threads). 512 -> 8192,
// the 1M 2D block at 2 threads: ahead in five of six interleaved rounds,
// median 33.4 -> 36.9 M (docs/performance.md, "On an AMD EPYC (Zen 5)").
inline std::size_t fused_chunk(std::size_t n, std::size_t B) {
    const std::size_t threads = static_cast<std::size_t>(std::max(1, par::max_threads()));
    const std::size_t shortest = (par::kDefaultChunk + B - 1) / B, longest = (8192 + B - 1) / B;
    return B * std::max(shortest, std::min(longest, n / (16 * threads * B)));
}

// The particles [begin, end) of one set (g2p_motion_pass).
template <int D, class S, class T, bool StoreGradient, bool Kinematics>
struct G2pMotionKernel {
    struct Args {
        const G2pTargets *t;
        const double *vel;
        double dt;
        Motion motion;
        GradientBlocks *blocks;
        std::size_t set, begin, end;
    };
    template <class Lanes, Isa I>
    [[gnu::always_inline]] static void run(const Args &args) {
        Chunk<Lanes, I> chunk(args);
        chunk.run();
    }

  private:
    static constexpr bool Gradient = StoreGradient || Kinematics || T::gradient;

    // One chunk of particles: the gather of each particle's sums over its
    // nodes, the particle's update from them (gathered), and with the
    // kinematics fused in the hand-off of each finished block.
    template <class Lanes, Isa I>
    class Chunk {
      public:
        [[gnu::always_inline]] explicit Chunk(const Args &args)
            : args_(args), g_(args.t->geo), vel_(args.vel), dt_(args.dt), alpha_(args.t->alpha),
              second_(args.motion == Motion::mean_velocity), move_(args.motion != Motion::none),
              bspline_(g_.affine_dinv > 0.0), loads_(args.t->loads), s_(args.t->sets[args.set]),
              L_block_(Kinematics ? args.blocks->buffer() : nullptr),
              L_column_(Kinematics ? args.blocks->block_size() : 0), block_begin_(args.begin) {}

        [[gnu::always_inline]] void run() {
            if constexpr (Kinematics) {
                const std::size_t B = args_.blocks->block_size();
                for (; block_begin_ < args_.end; block_begin_ += B) {
                    const std::size_t block_end = std::min(args_.end, block_begin_ + B);
                    points(block_begin_, block_end);
                    args_.blocks->take(args_.set, block_begin_, block_end - block_begin_);
                }
            } else {
                points(args_.begin, args_.end);
            }
        }

      private:
        using St = Stencil<D, S>;
        // The gradient and offset sums read v~ alone, a record's first
        // half; in 2D v is in that half too (node::kEndVelocity).
        using H = typename HalfRecord<Lanes>::type;
        using R = std::conditional_t<D == 2, H, Lanes>;
        static constexpr std::size_t ve = node::kEndVelocity, vs = node::velocity(D);

        // One particle (st: a Stencil or a lane of a StencilPack) from its
        // sums over the nodes of the records (v, v~): by the weight, the
        // gradient and the weighted offset.
        template <class Point>
        [[gnu::always_inline]] void gathered(const Point &st, std::size_t p, const R &sum,
                                             const H (&dsum)[D], const H (&osum)[D]) {
            double vpic[D], vold[D], L[D][D], B[D][D], step[D];
            for (int d = 0; d < D; ++d) {
                vpic[d] = sum[ve + static_cast<std::size_t>(d)];
                vold[d] = sum[vs + static_cast<std::size_t>(d)];
                for (int c = 0; c < D; ++c) {
                    L[d][c] = Gradient ? dsum[c][ve + static_cast<std::size_t>(d)] : 0.0;
                    B[d][c] = T::moments ? osum[c][ve + static_cast<std::size_t>(d)] : 0.0;
                }
            }
            double vnew[D];
            for (int d = 0; d < D; ++d) {
                const std::size_t dd = static_cast<std::size_t>(d);
                blended_velocity(vpic[d], vold[d], s_.v[dd][p], alpha_, vnew[d]);
                position_step(vpic[d], vold[d], dt_, second_, step[d]);
            }
            if constexpr (Kinematics) {
                double *Lp = L_block_ + (p - block_begin_);
                for (int r = 0; r < D; ++r)
                    for (int c = 0; c < D; ++c)
                        Lp[static_cast<std::size_t>(3 * r + c) * L_column_] = L[r][c];
            } else if constexpr (StoreGradient) {
                for (int r = 0; r < D; ++r)
                    for (int c = 0; c < D; ++c)
                        s_.L[9 * p + static_cast<std::size_t>(3 * r + c)] = L[r][c];
            }
            if constexpr (T::affine)
                T::template affine_matrix<D>(B, L, st.inverse_moments(), bspline_, &s_.C[9 * p]);
            // Particle velocity fixities override the grid's answer.
            if (const std::uint32_t mask = s_.fix_mask[p]) {
                loads_.fix_velocity<D>(mask, vnew);
                loads_.fixity_step<D>(mask, dt_, step);
            }
            for (int d = 0; d < D; ++d) {
                const std::size_t dd = static_cast<std::size_t>(d);
                s_.v[dd][p] = vnew[d];
                // With the kinematics fused in nothing later in the step
                // needs the start position: move the particle now.
                if constexpr (Kinematics)
                    s_.x[dd][p] += step[d];
                else if (move_)
                    s_.dx[dd][p] = step[d];
            }
        }

        // One particle: its sums, then the rest.
        template <class Point>
        [[gnu::always_inline]] void finish(const Point &st, std::size_t p) {
            R sum;
            H dsum[D], osum[D];
            st.template gather<Gradient, T::moments>(g_, vel_, sum, dsum, osum);
            gathered(st, p, sum, dsum, osum);
        }

        // With the kinematics fused in (FLIP/PIC, AVX-512): the particle
        // side of a pack of 8 across the vector lanes (finish_lanes).
        static constexpr bool kLaneFinish =
            I == Isa::avx512 && Kinematics && !T::moments && !T::affine && TALUS_HAS_SHUFFLEVECTOR;

        template <class Pack>
        [[gnu::always_inline]] void finish_pack(const Pack &pack, std::size_t p) {
            if constexpr (kLaneFinish) {
                finish_lanes(pack, p);
            } else {
                for (std::size_t j = 0; j < pack.size(); ++j) {
                    if constexpr (Kinematics) prefetch_material(s_, p + j);
                    finish(pack.lane(j), p + j);
                }
            }
        }

        // Each particle's sums go to a buffer as groups of four (v~ and, in
        // 2D, v; in 3D v in a second buffer; a column of L each), 4 x 8
        // transposes turn them into one vector per quantity, and the
        // velocity, the position step and the gradient's columns are
        // computed and stored for the 8 at once, with gathered()'s
        // arithmetic lane by lane. Particle by particle, the extracts from
        // the sums and the scalar loads and stores took more than that
        // arithmetic. A pack with a velocity fixity goes through gathered()
        // particle by particle.
        struct Sums {
            alignas(64) double pic[32], old[D == 3 ? 32 : 1], grad[D][32];
        };
        template <class Pack>
        [[gnu::always_inline]] void finish_lanes([[maybe_unused]] const Pack &pack,
                                                 [[maybe_unused]] std::size_t p) {
#if TALUS_HAS_SHUFFLEVECTOR
            static_assert(Pack::size() == 8, "a pack is one 8-lane vector a quantity");
            Sums q;
            gather_lanes(pack, p, q);
            std::uint32_t fixed = 0;
            for (std::size_t j = 0; j < 8; ++j)
                fixed |= s_.fix_mask[p + j];
            if (fixed != 0) [[unlikely]] {
                fixed_lanes(pack, p, q);
                return;
            }
            using V = talus::Lanes<8>::V;
            V pic[4], old[4], grad[D][4];
            quads_to_lanes(q.pic, pic);
            if constexpr (D == 3) quads_to_lanes(q.old, old);
            for (int c = 0; c < D; ++c)
                quads_to_lanes(q.grad[c], grad[c]);
            double *Lp = L_block_ + (p - block_begin_);
            for (int r = 0; r < D; ++r)
                for (int c = 0; c < D; ++c)
                    store_vector<8>(Lp + static_cast<std::size_t>(3 * r + c) * L_column_,
                                    grad[c][r]);
            for (int d = 0; d < D; ++d) {
                const std::size_t dd = static_cast<std::size_t>(d);
                const V vp = pic[d];
                V vo;
                if constexpr (D == 3)
                    vo = old[d];
                else
                    vo = pic[vs + dd];
                V v, x;
                load_vector<8>(&s_.v[dd][p], v);
                load_vector<8>(&s_.x[dd][p], x);
                V vnew, step;
                blended_velocity(vp, vo, v, alpha_, vnew);
                store_vector<8>(&s_.v[dd][p], vnew);
                position_step(vp, vo, dt_, second_, step);
                // The step rounded before it is added, as in gathered()
                // (where a fixity may change it): the empty asm keeps the
                // compiler from fusing its product into the add.
                __asm__("" : "+v"(step));
                store_vector<8>(&s_.x[dd][p], x + step);
            }
#endif
        }

#if TALUS_HAS_SHUFFLEVECTOR
        // The 8 particles' sums, gathered one by one, into q by quads.
        template <class Pack>
        [[gnu::always_inline]] void gather_lanes(const Pack &pack, std::size_t p, Sums &q) {
            for (std::size_t j = 0; j < 8; ++j) {
                prefetch_material(s_, p + j);
                R sum;
                H dsum[D], osum[D];
                pack.lane(j).template gather<Gradient, false>(g_, vel_, sum, dsum, osum);
                const std::size_t at = quad_at(j);
                if constexpr (D == 2) {
                    store_record(q.pic + at, sum);
                } else {
                    H lo, hi;
                    first_half(sum, lo);
                    hi = __builtin_shufflevector(sum, sum, 4, 5, 6, 7);
                    store_record(q.pic + at, lo);
                    store_record(q.old + at, hi);
                }
                for (int c = 0; c < D; ++c)
                    store_record(q.grad[c] + at, dsum[c]);
            }
        }

        // A pack with a fixity: each particle through gathered() from its
        // sums in q.
        template <class Pack>
        [[gnu::always_inline]] void fixed_lanes(const Pack &pack, std::size_t p, const Sums &q) {
            for (std::size_t j = 0; j < 8; ++j) {
                const std::size_t at = quad_at(j);
                R sum;
                H dsum[D];
                const H osum[D]{};
                if constexpr (D == 2) {
                    load_record(q.pic + at, sum);
                } else {
                    H lo, hi;
                    load_record(q.pic + at, lo);
                    load_record(q.old + at, hi);
                    sum = __builtin_shufflevector(lo, hi, 0, 1, 2, 3, 4, 5, 6, 7);
                }
                for (int c = 0; c < D; ++c)
                    load_record(q.grad[c] + at, dsum[c]);
                gathered(pack.lane(j), p + j, sum, dsum, osum);
            }
        }
#endif

        template <bool Near>
        [[gnu::always_inline]] void body(std::size_t p) {
            St st;
            st.template eval<Near, T::moments>(g_, s_, p);
            finish(st, p);
        }

        // The uniform kernel inline, the clamped one near a face out of line.
        [[gnu::always_inline]] void one(std::size_t p) {
            if constexpr (Kinematics) prefetch_material(s_, p);
            if (St::interior(g_, s_, p)) [[likely]] {
                body<false>(p);
            } else {
                auto near_face = [this](std::size_t q) __attribute__((always_inline)) {
                    body<true>(q);
                };
                OutOfLine<I>::call(near_face, p);
            }
        }

        [[gnu::always_inline]] void points(std::size_t begin, std::size_t end) {
            std::size_t p = begin;
            if constexpr (requires { S::interior_margin; }) {
                // Packs of N particles, their stencils evaluated together
                // (as in P2G).
                constexpr std::size_t N = kPointLanes<I>;
                StencilPack<D, S, static_cast<int>(N)> pack;
                for (; end - p >= N; p += N) {
                    // Within the chunk (the lines past it are another
                    // thread's to write).
                    if constexpr (Kinematics)
                        if (args_.end - p >= (kMotionPacksAhead + 1) * N)
                            prefetch_motion(s_, p + kMotionPacksAhead * N);
                    if (pack.template eval_run<T::moments>(g_, s_, p)) [[likely]] {
                        finish_pack(pack, p);
                    } else {
                        for (std::size_t j = 0; j < N; ++j)
                            one(p + j);
                    }
                }
            }
            for (; p < end; ++p)
                one(p);
        }

        const Args &args_;
        const GridGeometry &g_;
        const double *vel_;
        const double dt_, alpha_;
        const bool second_, move_, bspline_;
        const Loads &loads_;
        ParticleSet &s_;
        // With the update fused in: the block's gradients, by columns
        // (MaterialUpdate::gradient_buffer).
        double *const L_block_;
        const std::size_t L_column_;
        std::size_t block_begin_;
    };
};

// Velocity (the FLIP/PIC blend or PIC with an affine matrix), the position
// step (first order, or second order: x + dt v~ - dt^2/2 a = x + dt (v +
// v~)/2, see docs/theory.md on eq. 37) and the velocity gradient from v~.
template <int D, class S, class T, bool StoreGradient, bool Kinematics>
void g2p_motion_pass(const G2pTargets &t, const double *vel, double dt, Motion motion,
                     GradientBlocks *blocks) {
    using K = G2pMotionKernel<D, S, T, StoreGradient, Kinematics>;
    const auto kernel = IsaVersions<K>::pick(t.isa);
    for (std::size_t si = 0; si < t.sets.size(); ++si)
        par::for_each_chunk(
            t.sets[si].n,
            [&](std::size_t begin, std::size_t end) {
                kernel(typename K::Args{&t, vel, dt, motion, blocks, si, begin, end});
            },
            Kinematics ? par::Schedule::dynamic : par::Schedule::equal_shares,
            Kinematics ? fused_chunk(t.sets[si].n, blocks->block_size()) : par::kDefaultChunk);
}

template <int D, class S, bool Positions>
struct G2pGradientKernel {
    struct Args {
        const G2pTargets *t;
        const double *field;
        std::size_t offset, move_offset;
        double move_dt;
        std::size_t set, begin, end;
    };
    template <class Lanes, Isa I>
    [[gnu::always_inline]] static void run(const Args &args) {
        const G2pTargets &t = *args.t;
        const GridGeometry &g = t.geo;
        const double *field = args.field;
        const std::size_t offset = args.offset, move_offset = args.move_offset;
        const double move_dt = args.move_dt;
        ParticleSet &s = t.sets[args.set];
        using St = Stencil<D, S>;
        auto body = [&](auto near, std::size_t p) __attribute__((always_inline)) {
            St st;
            st.template eval<decltype(near)::value, false>(g, s, p);
            Lanes sum, dsum[D], osum[D];
            st.template gather<true, false>(g, field, sum, dsum, osum);
            double L[D][D], vk[D];
            for (int d = 0; d < D; ++d) {
                vk[d] = sum[move_offset + static_cast<std::size_t>(d)];
                for (int c = 0; c < D; ++c)
                    L[d][c] = dsum[c][offset + static_cast<std::size_t>(d)];
            }
            for (int r = 0; r < D; ++r)
                for (int c = 0; c < D; ++c)
                    s.L[9 * p + static_cast<std::size_t>(3 * r + c)] = L[r][c];
            if constexpr (Positions) {
                double step[D];
                for (int d = 0; d < D; ++d)
                    step[d] = move_dt * vk[d];
                if (const std::uint32_t mask = s.fix_mask[p])
                    t.loads.fixity_step<D>(mask, move_dt, step);
                for (int d = 0; d < D; ++d)
                    s.dx[static_cast<std::size_t>(d)][p] = step[d];
            }
        };
        // As in the motion kernel: the uniform kernel inline, the clamped
        // one out of line (a stencil evaluation left to the compiler is not
        // inlined for the cubic B-spline, and the call costs a USAVG step).
        auto near_face = [&](std::size_t p) __attribute__((always_inline)) {
            body(std::true_type{}, p);
        };
        for (std::size_t p = args.begin; p < args.end; ++p) {
            if (St::interior(g, s, p)) [[likely]]
                body(std::false_type{}, p);
            else
                OutOfLine<I>::call(near_face, p);
        }
    }
};

template <int D, class S, bool Positions>
void g2p_gradient_pass(const G2pTargets &t, const double *field, std::size_t offset,
                       std::size_t move_offset, double move_dt) {
    using K = G2pGradientKernel<D, S, Positions>;
    const auto kernel = IsaVersions<K>::pick(t.isa);
    for (std::size_t si = 0; si < t.sets.size(); ++si)
        par::for_each_chunk(t.sets[si].n, [&](std::size_t begin, std::size_t end) {
            kernel(typename K::Args{&t, field, offset, move_offset, move_dt, si, begin, end});
        });
}

// The passes of g2p.hpp in dimension D. Defined outside the class, so not
// inline: the extern declarations below then keep g2p.cpp from compiling
// them again.
template <int D>
struct Passes {
    static void velocity(const G2pTargets &t, const double *vel, double dt, Motion motion,
                         bool store_gradient);
    static void velocity_and_update(const G2pTargets &t, const double *vel, double dt,
                                    Motion motion, GradientBlocks &blocks);
    static void gradient(const G2pTargets &t, const double *field, std::size_t offset,
                         std::size_t move_offset, double move_dt);
};

template <int D>
void Passes<D>::velocity(const G2pTargets &t, const double *vel, double dt, Motion motion,
                         bool store_gradient) {
    with_shape<D>(t.shape, [&]<class S>() {
        with_transfer(t.transfer, [&]<class T>() {
            if (store_gradient)
                g2p_motion_pass<D, S, T, true, false>(t, vel, dt, motion, nullptr);
            else
                g2p_motion_pass<D, S, T, false, false>(t, vel, dt, motion, nullptr);
        });
    });
}

template <int D>
void Passes<D>::velocity_and_update(const G2pTargets &t, const double *vel, double dt,
                                    Motion motion, GradientBlocks &blocks) {
    with_shape<D>(t.shape, [&]<class S>() {
        with_transfer(t.transfer, [&]<class T>() {
            g2p_motion_pass<D, S, T, false, true>(t, vel, dt, motion, &blocks);
        });
    });
}

template <int D>
void Passes<D>::gradient(const G2pTargets &t, const double *field, std::size_t offset,
                         std::size_t move_offset, double move_dt) {
    with_shape<D>(t.shape, [&]<class S>() {
        if (move_dt > 0.0)
            g2p_gradient_pass<D, S, true>(t, field, offset, move_offset, move_dt);
        else
            g2p_gradient_pass<D, S, false>(t, field, offset, 0, 0.0);
    });
}

extern template struct Passes<2>;
extern template struct Passes<3>;

} // namespace talus::g2p_kernels
