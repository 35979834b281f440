// The factorised transfer kernels (core/src/mpm/kernels/stencil.hpp) against the
// textbook form they replace: every node's weight w_i = prod_d N(xi_d - k_d),
// its gradient and its offset formed one by one from the per-axis shape
// functions, then the scatter sum_i (w_i a + grad w_i . G + w_i off_i . O)
// and the gather sums done node by node. Both are the same sums in another
// order, so they agree to round-off: each result is a sum of at most 64
// nodes of a few products, so 1e-13 of the terms' size bounds the
// reordering's rounding with margin (a few hundred ulps). The size is 1 for
// weights and values, 1/h for gradients (dN/dx ~ 1/h), h for offsets; a
// scattered value mixes weight terms and gradient terms: 1 + 1/h.
#include "kernels/stencil.hpp"
#include "solver_helpers.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <memory>
#include <random>
#include <string>
#include <utility>
#include <vector>

namespace {

using talus::GridGeometry;
using talus::ParticleSet;

template <int D, class S>
struct Case {
    talus::Grid grid;
    ParticleSet set;
    explicit Case(talus::ShapeKind kind) : grid(D, {0.0, 0.0, 0.0}, {1.0, 0.8, 0.6}, 0.1, kind) {
        set.dim = D;
        set.has_L = set.has_dx = set.has_C = set.has_divv = false;
        set.resize(1);
        set.lp[0] = 0.25;
    }
    // The explicit per-node data for the particle at x: slot, weight,
    // gradient, offset.
    struct NodeRef {
        std::size_t slot;
        double w, grad[3], off[3];
    };
    std::vector<NodeRef> nodes(bool near) const {
        const GridGeometry &g = grid.geo;
        constexpr int W = S::width;
        int base[3] = {0, 0, 0};
        double w[3][W], dw[3][W], at[3][W];
        for (int d = 0; d < D; ++d) {
            const double xi = (set.x[static_cast<std::size_t>(d)][0] - g.origin[d]) * g.inv_h;
            if (near)
                S::eval_bounded(xi, set.lp[0], g.cells[d], base[d], w[d], dw[d], at[d]);
            else {
                S::eval(xi, set.lp[0], base[d], w[d], dw[d]);
                for (int k = 0; k < W; ++k)
                    at[d][k] = base[d] + k;
            }
            for (int k = 0; k < W; ++k) {
                dw[d][k] /= g.h;
                at[d][k] = (at[d][k] - xi) * g.h;
            }
        }
        std::vector<NodeRef> out;
        for (int c = 0; c < (D == 3 ? W : 1); ++c)
            for (int b = 0; b < W; ++b)
                for (int a = 0; a < W; ++a) {
                    const int k[3] = {a, b, c};
                    NodeRef r{};
                    std::size_t stride = 1;
                    r.slot = 0;
                    r.w = 1.0;
                    for (int d = 0; d < D; ++d) {
                        r.slot += static_cast<std::size_t>(base[d] + k[d] - g.first[d]) * stride;
                        stride *= static_cast<std::size_t>(g.extent[d]);
                        r.w *= w[d][k[d]];
                        r.off[d] = at[d][k[d]];
                    }
                    for (int d = 0; d < D; ++d) {
                        r.grad[d] = 1.0;
                        for (int e = 0; e < D; ++e)
                            r.grad[d] *= e == d ? dw[e][k[e]] : w[e][k[e]];
                    }
                    out.push_back(r);
                }
        return out;
    }
};

template <class Lanes, int D, class S>
void check_with(talus::ShapeKind kind) {
    Case<D, S> cs(kind);
    const GridGeometry &g = cs.grid.geo;
    std::mt19937_64 rng(11);
    std::uniform_real_distribution<double> unit(-1.0, 1.0);
    for (int trial = 0; trial < 200; ++trial) {
        // Half the positions anywhere in the domain (the clamped kernels near
        // its faces), half within a cell of a face.
        for (int d = 0; d < D; ++d) {
            const double L = g.cells[static_cast<std::size_t>(d)] * g.h;
            const double u = 0.5 * (unit(rng) + 1.0);
            cs.set.x[static_cast<std::size_t>(d)][0] =
                trial % 2 ? u * L : (u < 0.5 ? u * 0.2 * g.h : L - (u - 0.5) * 0.2 * g.h);
        }
        using St = talus::Stencil<D, S>;
        const bool near = !St::interior(g, cs.set, 0);
        St st;
        if (near)
            st.template eval<true, true>(g, cs.set, 0);
        else
            st.template eval<false, true>(g, cs.set, 0);
        const auto ref = cs.nodes(near);

        // A half record (the G2P's) is a record's first K doubles.
        constexpr int K = static_cast<int>(talus::kRecordLanes<Lanes>);
        std::vector<double> records(cs.grid.acc.size(), 0.0);
        // The scatter (P2G), by record halves: random values on every lane
        // of a, on the second half of the gradient terms and the first of
        // the offset terms, zeros elsewhere; and a momentum-only scatter
        // (Upper false), which must leave the second halves alone.
        if constexpr (K == talus::kLanes)
            for (bool upper : {true, false}) {
                using H = typename talus::HalfRecord<Lanes>::type;
                constexpr std::size_t half = talus::node::kRecord / 2;
                double a[8] = {}, grad[D][8] = {}, offs[D][8] = {};
                H a_lo{}, a_hi{}, gh[D]{}, ol[D]{};
                for (std::size_t k = 0; k < 8; ++k) {
                    const bool hi = k >= half;
                    if (hi && !upper) continue;
                    a[k] = unit(rng);
                    talus::set_lane(hi ? a_hi : a_lo, k % half, a[k]);
                    for (int d = 0; d < D; ++d)
                        if (hi) {
                            grad[d][k] = unit(rng);
                            talus::set_lane(gh[d], k - half, grad[d][k]);
                        } else {
                            offs[d][k] = unit(rng) / g.h; // an affine matrix of order 1/h
                            talus::set_lane(ol[d], k, offs[d][k]);
                        }
                }
                std::fill(records.begin(), records.end(), 0.0);
                if (upper)
                    st.template scatter<true, true, true>(g, records.data(), a_lo, a_hi, gh, ol);
                else
                    st.template scatter<false, false, true>(g, records.data(), a_lo, a_hi, gh, ol);
                std::vector<double> expect(records.size(), 0.0);
                for (const auto &r : ref)
                    for (std::size_t k = 0; k < 8; ++k) {
                        double v = r.w * a[k];
                        for (int d = 0; d < D; ++d)
                            v += r.grad[d] * grad[d][k] + r.w * r.off[d] * offs[d][k];
                        expect[talus::node::kRecord * r.slot + k] += v;
                    }
                for (std::size_t i = 0; i < records.size(); ++i)
                    ASSERT_NEAR(records[i], expect[i], 1e-13 * (1.0 + 1.0 / g.h))
                        << "scatter, record value " << i << " trial " << trial
                        << (upper ? "" : ", first halves only");
            }

        // Gather of random records.
        for (double &v : records)
            v = unit(rng);
        Lanes sum, dsum[D], osum[D];
        st.template gather<true, true, Lanes>(g, records.data(), sum, dsum, osum);
        for (int k = 0; k < K; ++k) {
            double s0 = 0.0, sg[3] = {}, so[3] = {};
            for (const auto &r : ref) {
                const double v =
                    records[talus::node::kRecord * r.slot + static_cast<std::size_t>(k)];
                s0 += r.w * v;
                for (int d = 0; d < D; ++d) {
                    sg[d] += r.grad[d] * v;
                    so[d] += r.w * r.off[d] * v;
                }
            }
            ASSERT_NEAR(sum[k], s0, 1e-13) << "gather, lane " << k << " trial " << trial;
            for (int d = 0; d < D; ++d) {
                ASSERT_NEAR(dsum[d][k], sg[d], 1e-13 / g.h) << "gradient, axis " << d;
                ASSERT_NEAR(osum[d][k], so[d], 1e-13 * g.h) << "offset, axis " << d;
            }
        }
        // The G2P's gather: the values whole, the gradient and offset sums
        // of the first halves alone (half records). The same operations on
        // the same lanes: the same bits as the whole gather's.
        if constexpr (K == talus::kLanes) {
            using H = typename talus::HalfRecord<Lanes>::type;
            Lanes hsum;
            H hd[D], ho[D];
            st.template gather<true, true>(g, records.data(), hsum, hd, ho);
            for (int k = 0; k < K; ++k)
                ASSERT_EQ(hsum[k], sum[k]) << "mixed gather, lane " << k << " trial " << trial;
            for (int k = 0; k < K / 2; ++k)
                for (int d = 0; d < D; ++d) {
                    ASSERT_EQ(hd[d][k], dsum[d][k]) << "mixed gradient, axis " << d;
                    ASSERT_EQ(ho[d][k], osum[d][k]) << "mixed offset, axis " << d;
                }
        }
    }
}

// Every node-record type the kernels are compiled with (stencil.hpp), and
// the half records.
template <int D, class S>
void check(talus::ShapeKind kind) {
    check_with<talus::Arr8, D, S>(kind);
    check_with<talus::Quad8, D, S>(kind);
    check_with<talus::Vec8, D, S>(kind);
    check_with<talus::HalfRecord<talus::Arr8>::type, D, S>(kind);
    check_with<talus::HalfRecord<talus::Quad8>::type, D, S>(kind);
    check_with<talus::HalfRecord<talus::Vec8>::type, D, S>(kind);
}

} // namespace

// 2D and 3D of each kernel.
TEST(Stencil, LinearMatchesTheNodeByNodeSums) {
    check<2, talus::LinearShape>(talus::ShapeKind::linear);
    check<3, talus::LinearShape>(talus::ShapeKind::linear);
}
TEST(Stencil, GimpMatchesTheNodeByNodeSums) {
    check<2, talus::GimpShape>(talus::ShapeKind::gimp);
    check<3, talus::GimpShape>(talus::ShapeKind::gimp);
}
TEST(Stencil, QuadraticBSplineMatchesTheNodeByNodeSums) {
    check<2, talus::BSpline2Shape>(talus::ShapeKind::bspline2);
    check<3, talus::BSpline2Shape>(talus::ShapeKind::bspline2);
}
TEST(Stencil, CubicBSplineMatchesTheNodeByNodeSums) {
    check<2, talus::BSpline3Shape>(talus::ShapeKind::bspline3);
    check<3, talus::BSpline3Shape>(talus::ShapeKind::bspline3);
}

namespace {

// A pack's lanes (StencilPack, N particles evaluated together) are the
// per-particle stencils, bit for bit: the same operations in the same order
// in every lane. Exact equality is the claim (the kernels' results do not
// depend on where a particle falls in a pack). A particle near a face gets
// the clamped functions in its lane (StencilPack::clamp_lanes), the same
// bits as its own Stencil::eval<true>; with the offsets (the affine
// transfers), whose moments are a particle's own there, such a pack is
// refused whole and left to the per-particle path.
template <int N, int D, class S>
void check_pack(talus::ShapeKind kind) {
    constexpr int W = S::width;
    talus::Grid grid(D, {0.0, 0.0, 0.0}, {1.0, 0.8, 0.6}, 0.1, kind);
    const GridGeometry &g = grid.geo;
    ParticleSet set;
    set.dim = D;
    set.has_L = set.has_dx = set.has_C = set.has_divv = false;
    constexpr std::size_t n = 64;
    set.resize(n);
    std::mt19937_64 rng(5);
    std::uniform_real_distribution<double> unit(0.0, 1.0);
    // Positions away from the faces by more than the interior margin.
    for (std::size_t p = 0; p < n; ++p)
        for (int d = 0; d < D; ++d) {
            const double L = g.cells[static_cast<std::size_t>(d)] * g.h;
            const double m = (S::interior_margin + 0.01) * g.h;
            set.x[static_cast<std::size_t>(d)][p] = m + unit(rng) * (L - 2.0 * m);
        }
    // Gathered in a scrambled order (eval), and in a run (eval_run).
    std::vector<std::uint32_t> index(n);
    for (std::size_t p = 0; p < n; ++p)
        index[p] = static_cast<std::uint32_t>((p * 37) % n);
    auto same = [&](const talus::StencilPack<D, S, N> &pk, std::size_t j, std::size_t p) {
        using St = talus::Stencil<D, S>;
        ASSERT_TRUE(St::interior(g, set, p));
        St st;
        st.template eval<false, true>(g, set, p);
        for (int d = 0; d < D; ++d) {
            ASSERT_EQ(pk.base[d][j], st.base[d]) << "particle " << p << " axis " << d;
            ASSERT_EQ(pk.dinv[d], st.dinv[d]);
            for (int k = 0; k < W; ++k) {
                ASSERT_EQ(pk.w[d][k][j], st.w[d][k]) << "particle " << p << " axis " << d;
                ASSERT_EQ(pk.dw[d][k][j], st.dw[d][k]) << "particle " << p << " axis " << d;
                ASSERT_EQ(pk.off[d][k][j], st.off[d][k]) << "particle " << p << " axis " << d;
                ASSERT_EQ(pk.w_off[d][k][j], st.w_off[d][k]) << "particle " << p;
            }
        }
    };
    talus::StencilPack<D, S, N> pk;
    for (std::size_t first = 0; first + N <= n; first += N) {
        ASSERT_TRUE(pk.template eval<true>(g, set, &index[first]));
        for (std::size_t j = 0; j < N; ++j)
            same(pk, j, index[first + j]);
        ASSERT_TRUE(pk.template eval_run<true>(g, set, first));
        for (std::size_t j = 0; j < N; ++j)
            same(pk, j, first + j);
    }
    // One particle of the pack just inside the margin of a face, then just
    // inside the other face's: the pack is refused.
    for (const double at : {S::interior_margin - 1e-9, g.cells[0] - S::interior_margin + 1e-9}) {
        const double saved = set.x[0][N - 1];
        set.x[0][N - 1] = at * g.h;
        EXPECT_FALSE(pk.template eval_run<true>(g, set, 0)) << "near-face position " << at;
        set.x[0][N - 1] = saved;
    }
    // Without the offsets: packs whose particles sit next to the faces
    // (on them, inside the margin, at the margin itself, one axis or
    // several), mixed with interior ones, are taken, each lane its
    // particle's own stencil.
    const double far_x = g.cells[0] * 1.0, far_y = g.cells[1] * 1.0;
    const double near_at[] = {0.0,
                              1e-12,
                              0.3,
                              S::interior_margin - 1e-9,
                              S::interior_margin,
                              far_x - S::interior_margin + 1e-9,
                              far_x - S::interior_margin - 1e-9,
                              far_x - 0.2,
                              far_x};
    std::size_t placed = 0;
    for (std::size_t p = 0; p < n; p += 3, ++placed) {
        const double at = near_at[placed % std::size(near_at)];
        set.x[0][p] = std::min(at, far_x) * g.h;
        // Every fourth of them next to a face on the second axis too.
        if (placed % 4 == 0) set.x[1][p] = std::min(at, far_y) * g.h;
    }
    auto same_near = [&](const talus::StencilPack<D, S, N> &pack, std::size_t j, std::size_t p) {
        using St = talus::Stencil<D, S>;
        St st;
        if (St::interior(g, set, p))
            st.template eval<false, false>(g, set, p);
        else
            st.template eval<true, false>(g, set, p);
        for (int d = 0; d < D; ++d) {
            ASSERT_EQ(pack.base[d][j], st.base[d]) << "particle " << p << " axis " << d;
            for (int k = 0; k < W; ++k) {
                ASSERT_EQ(pack.w[d][k][j], st.w[d][k]) << "particle " << p << " axis " << d;
                ASSERT_EQ(pack.dw[d][k][j], st.dw[d][k]) << "particle " << p << " axis " << d;
            }
        }
    };
    for (std::size_t first = 0; first + N <= n; first += N) {
        ASSERT_TRUE(pk.template eval<false>(g, set, &index[first]));
        for (std::size_t j = 0; j < N; ++j)
            same_near(pk, j, index[first + j]);
        ASSERT_TRUE(pk.template eval_run<false>(g, set, first));
        for (std::size_t j = 0; j < N; ++j)
            same_near(pk, j, first + j);
    }
    // The placement above put near particles in the packs compared: of the
    // nine positions seven are near a face (the margin itself and 1e-9
    // inside the far one are interior), a third of the particles placed,
    // so a sixth of all or more.
    std::size_t near_particles = 0;
    for (std::size_t p = 0; p < n; ++p)
        near_particles += talus::Stencil<D, S>::interior(g, set, p) ? 0 : 1;
    EXPECT_GE(near_particles, n / 6) << "the near-face lanes were compared";
}

template <int D, class S>
void check_packs(talus::ShapeKind kind) {
    check_pack<2, D, S>(kind);
    check_pack<4, D, S>(kind);
    check_pack<8, D, S>(kind);
}

} // namespace

TEST(Stencil, PackLanesAreTheParticleStencilsBitForBit) {
    check_packs<2, talus::BSpline2Shape>(talus::ShapeKind::bspline2);
    check_packs<3, talus::BSpline2Shape>(talus::ShapeKind::bspline2);
    check_packs<2, talus::BSpline3Shape>(talus::ShapeKind::bspline3);
    check_packs<3, talus::BSpline3Shape>(talus::ShapeKind::bspline3);
}

// The transfer kernels' versions for each instruction set (isa.hpp) are one
// source compiled for different vector widths: they differ only in the
// rounding of fused multiply-adds and the order of a few sums, so their
// answers agree to round-off on a smooth (non-chaotic) run. Over 40 steps of
// an elastic sphere striking a rough floor (FLIP and APIC, which uses every
// lane of the kernels), the differences measured are 2e-16 m in position,
// 2.4e-15 of the largest velocity and 5e-16 of the largest stress; the
// bounds, 1e-13 of each field's scale, allow a few ulps per step
// accumulated over the steps and nothing like an error in a kernel. The
// same in 2D, a disk, where the G2P reads half records (stencil.hpp).
TEST(Stencil, EveryInstructionSetGivesTheSameRun) {
    // An elastic ball (a sphere, a disk in 2D) striking a rough floor.
    auto ball = [](bool three, const char *transfer) {
        return std::string("talus: 1\ndimension: ") + (three ? "3" : "2") + "\ngrid: {origin: " +
               (three ? "[0, 0, 0], size: [1.6, 1.6, 1.6]" : "[0, 0], size: [1.6, 1.6]") +
               ", cell: 0.05}\nmaterials:\n  m: {model: linear_elastic, density: 1000, "
               "youngs_modulus: 1.0e6, poisson_ratio: 0.3}\n"
               "groups:\n  a: {material: m, particles_per_cell: 2, velocity: " +
               (three ? "[0.5, 0, -0.3]" : "[0.5, -0.3]") +
               ",\n      shape: {sphere: {center: " + (three ? "[0.8, 0.8, 0.41]" : "[0.8, 0.41]") +
               ", radius: 0.4}}}\nboundaries: {" + (three ? "z-" : "y-") +
               ": {friction: 0.3}}\ngravity: " + (three ? "[0, 0, -9.81]" : "[0, -9.81]") +
               "\nsolver: {transfer: " + transfer + "}\ntime: {end: 1}\n";
    };
    const char *flip = "{type: flip, alpha: 0.95}";
    // The user's own TALUS_KERNEL_ISA, put back after each run.
    const char *user = std::getenv("TALUS_KERNEL_ISA");
    const std::string users = user ? user : "";
    auto run = [&](const std::string &yaml, const char *isa) {
        setenv("TALUS_KERNEL_ISA", isa, 1);
        std::unique_ptr<talus::test::Sim> s;
        try {
            s = talus::test::sim_from_text(yaml);
        } catch (...) {
            user ? setenv("TALUS_KERNEL_ISA", users.c_str(), 1) : unsetenv("TALUS_KERNEL_ISA");
            throw;
        }
        user ? setenv("TALUS_KERNEL_ISA", users.c_str(), 1) : unsetenv("TALUS_KERNEL_ISA");
        for (int k = 0; k < 40; ++k)
            s->sim->step(1.0);
        return s;
    };
    // Largest difference, and largest magnitude of the field in `a`.
    auto worst = [](const auto &a, const auto &b) {
        double diff = 0.0, scale = 0.0;
        for (std::size_t i = 0; i < a.size(); ++i) {
            diff = std::max(diff, std::abs(a[i] - b[i]));
            scale = std::max(scale, std::abs(a[i]));
        }
        return std::pair{diff, scale};
    };
    int compared = 0;
    const std::string yamls[] = {ball(true, flip), ball(true, "apic"), ball(false, flip),
                                 ball(false, "apic")};
    for (const std::string &yaml : yamls) {
        auto ref = run(yaml, "generic");
        for (const char *isa : {"avx2", "avx512"}) {
            std::unique_ptr<talus::test::Sim> other;
            try {
                other = run(yaml, isa);
            } catch (const talus::Error &) {
                continue; // this CPU or build has no such version
            }
            ++compared;
            const auto &a = ref->sim->sets()[0];
            const auto &b = other->sim->sets()[0];
            ASSERT_EQ(a.n, b.n);
            // Scales: the domain (1.6 m), the fastest velocity component,
            // the largest stress component (the impact's, ~1e4 Pa).
            double dx = 0.0, dv = 0.0, sv = 0.0;
            for (std::size_t d = 0; d < static_cast<std::size_t>(a.dim); ++d) {
                dx = std::max(dx, worst(a.x[d], b.x[d]).first);
                const auto [dvd, svd] = worst(a.v[d], b.v[d]);
                dv = std::max(dv, dvd);
                sv = std::max(sv, svd);
            }
            const auto [ds, ss] = worst(a.stress, b.stress);
            ASSERT_GT(ss, 1e3); // the sphere is loaded: the check has something to compare
            EXPECT_LE(dx, 1e-13 * 1.6) << isa << " position";
            EXPECT_LE(dv, 1e-13 * sv) << isa << " velocity";
            EXPECT_LE(ds, 1e-13 * ss) << isa << " stress";
        }
    }
    if (compared == 0) GTEST_SKIP() << "only the generic kernels on this machine";
}
