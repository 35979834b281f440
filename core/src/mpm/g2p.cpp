#include "g2p.hpp"

#include "parallel.hpp"
#include "stencil.hpp"
#include "transfer.hpp"

#include <type_traits>

namespace talus {

namespace {

// Velocity (the FLIP/PIC blend or PIC with an affine matrix), the position
// step (first order, or second order: x + dt v~ - dt^2/2 a = x + dt (v +
// v~)/2, see docs/theory.md on eq. 37) and the velocity gradient from v~.
template <int D, class S, class T, bool StoreGradient, bool Kinematics>
void g2p_motion_pass(const G2pTargets &t, const double *vel, double dt, Motion motion,
                     par::FirstFailure<Inversion> *inverted) {
    constexpr bool Gradient = StoreGradient || Kinematics || T::gradient;
    const GridGeometry &g = t.geo;
    const double alpha = t.alpha;
    const bool second = motion == Motion::mean_velocity;
    const bool move = motion != Motion::none;
    const bool bspline = g.affine_dinv > 0.0;
    const Loads &loads = t.loads;
    using St = Stencil<D, S, T::moments>;
    for (std::size_t si = 0; si < t.sets.size(); ++si) {
        ParticleSet &s = t.sets[si];
        auto body = [&](auto near, std::size_t p) __attribute__((always_inline)) {
            St st;
            st.template eval<decltype(near)::value>(g, s, p);
            double vpic[D] = {}, vold[D] = {}, L[D][D] = {}, B[D][D] = {}, step[D];
            for (int q = 0; q < St::NN; ++q) {
                const double *rec = vel + node::kRecord * st.idx[q];
                for (int d = 0; d < D; ++d) {
                    const double a1 = rec[node::kEndVelocity + static_cast<std::size_t>(d)];
                    vpic[d] += st.w[q] * a1;
                    vold[d] += st.w[q] * rec[node::kVelocity + static_cast<std::size_t>(d)];
                    if constexpr (Gradient)
                        for (int c = 0; c < D; ++c)
                            L[d][c] += a1 * st.grad[q][c];
                    if constexpr (T::moments)
                        for (int c = 0; c < D; ++c)
                            B[d][c] += st.w[q] * a1 * st.off[q][c];
                }
            }
            double vnew[D];
            for (int d = 0; d < D; ++d) {
                const std::size_t dd = static_cast<std::size_t>(d);
                vnew[d] = vpic[d] + alpha * (s.v[dd][p] - vold[d]);
                step[d] = second ? 0.5 * dt * (vpic[d] + vold[d]) : dt * vpic[d];
            }
            if constexpr (Kinematics) {
                if (!kinematics_point<D>(s, p, &L[0][0], dt, D, false)) inverted->record({si, p});
            } else if constexpr (StoreGradient) {
                for (int r = 0; r < D; ++r)
                    for (int c = 0; c < D; ++c)
                        s.L[9 * p + static_cast<std::size_t>(3 * r + c)] = L[r][c];
            }
            if constexpr (T::affine)
                T::template affine_matrix<D>(B, L, st.dinv, bspline, &s.C[9 * p]);
            // Particle velocity fixities override the grid's answer.
            if (const std::uint32_t mask = s.fix_mask[p]) {
                loads.fix_velocity<D>(mask, vnew);
                loads.fixity_step<D>(mask, dt, step);
            }
            for (int d = 0; d < D; ++d) {
                const std::size_t dd = static_cast<std::size_t>(d);
                s.v[dd][p] = vnew[d];
                // With the kinematics fused in nothing later in the step
                // needs the start position: move the particle now.
                if constexpr (Kinematics)
                    s.x[dd][p] += step[d];
                else if (move)
                    s.dx[dd][p] = step[d];
            }
        };
        auto near_face = [&](std::size_t p) __attribute__((noinline)) {
            body(std::true_type{}, p);
        };
        par::for_each(s.n, [&](std::size_t p) {
            if (St::interior(g, s, p)) [[likely]]
                body(std::false_type{}, p);
            else
                near_face(p);
        });
    }
}

template <int D, class S, bool Positions>
void g2p_gradient_pass(const G2pTargets &t, const double *field, std::size_t offset,
                       std::size_t move_offset, double move_dt) {
    const GridGeometry &g = t.geo;
    using St = Stencil<D, S, false>;
    for (ParticleSet &s : t.sets) {
        auto body = [&](auto near, std::size_t p) __attribute__((always_inline)) {
            St st;
            st.template eval<decltype(near)::value>(g, s, p);
            double L[D][D] = {}, vk[D] = {};
            for (int q = 0; q < St::NN; ++q) {
                const double *node = field + node::kRecord * st.idx[q];
                const double *rec = node + offset;
                for (int d = 0; d < D; ++d) {
                    if constexpr (Positions)
                        vk[d] += st.w[q] * node[move_offset + static_cast<std::size_t>(d)];
                    for (int c = 0; c < D; ++c)
                        L[d][c] += rec[d] * st.grad[q][c];
                }
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
        // As in g2p_motion_pass: the uniform kernel inline, the clamped one
        // out of line (a stencil evaluation left to the compiler was not
        // inlined for the cubic B-spline: 8 % of a USAVG step in a call).
        auto near_face = [&](std::size_t p) __attribute__((noinline)) {
            body(std::true_type{}, p);
        };
        par::for_each(s.n, [&](std::size_t p) {
            if (St::interior(g, s, p)) [[likely]]
                body(std::false_type{}, p);
            else
                near_face(p);
        });
    }
}

} // namespace

void g2p_velocity(const G2pTargets &t, const double *vel, double dt, Motion motion,
                  bool store_gradient) {
    with_kernel(t.geo.dim, t.shape, [&]<int D, class S>() {
        with_transfer(t.transfer, [&]<class T>() {
            if (store_gradient)
                g2p_motion_pass<D, S, T, true, false>(t, vel, dt, motion, nullptr);
            else
                g2p_motion_pass<D, S, T, false, false>(t, vel, dt, motion, nullptr);
        });
    });
}

std::optional<Inversion> g2p_velocity_and_kinematics(const G2pTargets &t, const double *vel,
                                                     double dt, Motion motion) {
    par::FirstFailure<Inversion> inverted;
    with_kernel(t.geo.dim, t.shape, [&]<int D, class S>() {
        with_transfer(t.transfer, [&]<class T>() {
            g2p_motion_pass<D, S, T, false, true>(t, vel, dt, motion, &inverted);
        });
    });
    if (const Inversion *first = inverted.first()) return *first;
    return std::nullopt;
}

void g2p_gradient(const G2pTargets &t, const double *field, std::size_t offset,
                  std::size_t move_offset, double move_dt) {
    with_kernel(t.geo.dim, t.shape, [&]<int D, class S>() {
        if (move_dt > 0.0)
            g2p_gradient_pass<D, S, true>(t, field, offset, move_offset, move_dt);
        else
            g2p_gradient_pass<D, S, false>(t, field, offset, 0, 0.0);
    });
}

} // namespace talus
