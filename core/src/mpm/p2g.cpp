#include "p2g.hpp"

#include "parallel.hpp"
#include "stencil.hpp"

#include <type_traits>

namespace talus {

namespace {

template <int D, class S, bool Mass, bool Momentum, bool Affine, bool Forces>
void p2g_pass(const P2gSources &src, double *acc) {
    const GridGeometry &g = src.geo;
    const auto &sets = src.sets;
    const double *grav = src.loads.gravity();
    using St = Stencil<D, S, Affine>;
    par::for_each_slab_by_colour(src.order.n_slabs(), [&](int slab) {
        for (std::size_t si = 0; si < sets.size(); ++si) {
            const ParticleSet &s = sets[si];
            auto body = [&](auto near, std::size_t p) __attribute__((always_inline)) {
                St st;
                st.template eval<decltype(near)::value>(g, s, p);
                const double m = s.mass[p];
                double vp[D], Cp[D][D] = {}, Vsig[D][D] = {}, fext[D] = {};
                for (int d = 0; d < D; ++d)
                    vp[d] = s.v[static_cast<std::size_t>(d)][p];
                if constexpr (Affine)
                    for (int r = 0; r < D; ++r)
                        for (int c = 0; c < D; ++c)
                            Cp[r][c] = s.C[9 * p + static_cast<std::size_t>(3 * r + c)];
                if constexpr (Forces) {
                    const double V = s.J[p] * s.vol0[p];
                    const double *sg = &s.stress[6 * p];
                    // In-plane part of V sigma for D = 2.
                    Vsig[0][0] = V * sg[0];
                    Vsig[1][1] = V * sg[1];
                    Vsig[0][1] = Vsig[1][0] = V * sg[3];
                    if constexpr (D == 3) {
                        Vsig[2][2] = V * sg[2];
                        Vsig[1][2] = Vsig[2][1] = V * sg[4];
                        Vsig[0][2] = Vsig[2][0] = V * sg[5];
                    }
                    if (s.load_mask[p])
                        src.loads.particle_force<D>(s.load_mask[p], s.group[p], fext);
                    for (int d = 0; d < D; ++d)
                        fext[d] += m * grav[d];
                }
                const std::uint32_t fixed = Mass ? s.fix_mask[p] : 0u;
                for (int q = 0; q < St::NN; ++q) {
                    double *rec = acc + node::kRecord * st.idx[q];
                    const double mw = m * st.w[q];
                    if constexpr (Mass) rec[node::kMass] += mw;
                    // The nodes a fixed particle reaches carry its fixity
                    // (Boundary::apply): a constraint the grid sees.
                    if (fixed && st.w[q] > 0.0) [[unlikely]]
                        rec[node::kFixity] = static_cast<double>(
                            static_cast<std::uint32_t>(rec[node::kFixity]) | fixed);
                    for (int d = 0; d < D; ++d) {
                        if constexpr (Momentum) {
                            double vq = vp[d];
                            if constexpr (Affine)
                                for (int c = 0; c < D; ++c)
                                    vq += Cp[d][c] * st.off[q][c];
                            rec[node::kMomentum + static_cast<std::size_t>(d)] += mw * vq;
                        }
                        if constexpr (Forces) {
                            double fi = st.w[q] * fext[d];
                            for (int c = 0; c < D; ++c)
                                fi -= Vsig[d][c] * st.grad[q][c];
                            rec[node::kForce + static_cast<std::size_t>(d)] += fi;
                        }
                    }
                }
            };
            auto near_face = [&](std::size_t p) __attribute__((noinline)) {
                body(std::true_type{}, p);
            };
            const Ordering::Range r = src.order.slab(si, slab);
            for (const std::uint32_t *k = r.begin; k != r.end; ++k) {
                const std::size_t p = *k;
                if (St::interior(g, s, p)) [[likely]]
                    body(std::false_type{}, p);
                else
                    near_face(p);
            }
        }
    });
}

template <bool Mass, bool Momentum, bool Affine, bool Forces>
void run(const P2gSources &src, double *acc) {
    with_kernel(src.geo.dim, src.shape, [&]<int D, class S>() {
        p2g_pass<D, S, Mass, Momentum, Affine, Forces>(src, acc);
    });
}

} // namespace

void p2g_momentum(const P2gSources &src, double *acc) {
    if (src.affine)
        run<true, true, true, false>(src, acc);
    else
        run<true, true, false, false>(src, acc);
}

void p2g_forces(const P2gSources &src, double *acc) { run<false, false, false, true>(src, acc); }

void p2g_momentum_and_forces(const P2gSources &src, double *acc) {
    if (src.affine)
        run<true, true, true, true>(src, acc);
    else
        run<true, true, false, true>(src, acc);
}

void p2g_remap(const P2gSources &src, double *acc) { run<false, true, false, false>(src, acc); }

} // namespace talus
