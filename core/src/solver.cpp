// The explicit MPM cycle. Equation numbers refer to seed 000 (the MPoint
// theory manual) unless stated; docs/theory.md has the full account.
#include <talus/crash_report.hpp>
#include <talus/solver.hpp>
#include <talus/stress_rotation.hpp>

#include <talus/sdk/voigt.hpp>

#include <Eigen/Core>
#include <Eigen/LU>
#include <fmt/format.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstring>
#include <limits>
#include <mutex>
#include <numeric>
#include <optional>
#include <tuple>

#ifdef _OPENMP
#include <omp.h>
#endif

namespace talus {

// ----------------------------------------------------------- ParticleSet --

namespace {
// Every per-particle array with its number of values per particle.
template <class PS, class F>
void for_each_array(PS &s, F &&f) {
    for (int d = 0; d < s.dim; ++d) {
        f(s.x[static_cast<std::size_t>(d)], 1);
        f(s.x0[static_cast<std::size_t>(d)], 1);
        f(s.v[static_cast<std::size_t>(d)], 1);
        if (s.has_dx) f(s.dx[static_cast<std::size_t>(d)], 1);
    }
    f(s.mass, 1);
    f(s.vol0, 1);
    f(s.lp, 1);
    f(s.F, 9);
    f(s.F_new, 9);
    f(s.J, 1);
    f(s.rho, 1);
    f(s.stress, 6);
    f(s.state, s.state_size);
    f(s.de, 6);
    f(s.c, 1);
    if (s.has_L) f(s.L, 9);
    if (s.has_C) f(s.C, 9);
    f(s.work, 1);
    if (s.has_divv) f(s.divv, 1);
}
} // namespace

void ParticleSet::resize(std::size_t count) {
    n = count;
    for_each_array(*this, [&](auto &a, std::size_t stride) { a.resize(count * stride); });
    id.resize(count);
    group.resize(count);
    load_mask.resize(count);
    fix_mask.resize(count);
}

void ParticleSet::move(std::size_t from, std::size_t to) {
    if (from == to) return;
    for_each_array(*this, [&](auto &a, std::size_t stride) {
        std::copy_n(a.begin() + static_cast<std::ptrdiff_t>(from * stride), stride,
                    a.begin() + static_cast<std::ptrdiff_t>(to * stride));
    });
    id[to] = id[from];
    group[to] = group[from];
    load_mask[to] = load_mask[from];
    fix_mask[to] = fix_mask[from];
}

// ------------------------------------------------------------------ Impl --

namespace {
// USL without cell averaging does its kinematics inside the velocity G2P:
// no stored gradient or position step.
bool fused_usl(const SolverSpec &sv) {
    return sv.scheme == Scheme::usl && !sv.cell_averaged_dilation;
}

// Kinematic consistency (docs/theory.md, its table): each particle moves
// with the grid velocity field whose gradient advances its F, or with that
// field's mean with the start velocities. USL and USAVG move the particles
// in the velocity G2P (by v~, or by (v + v~) / 2); USF and MUSL in the
// gradient pass of their own field.
bool trapezoid_positions(const SolverSpec &sv) {
    return sv.scheme == Scheme::usavg || (sv.second_order_position && sv.scheme != Scheme::usf);
}
bool velocity_pass_moves_particles(const SolverSpec &sv) {
    return sv.scheme == Scheme::usl || sv.scheme == Scheme::usavg;
}
} // namespace

struct Simulation::Impl {
    Simulation &sim;
    int dim = 2;
    int ghost = kGhostLayers;
    double h = 1.0, inv_h = 1.0;
    std::array<double, 3> origin{0, 0, 0};
    std::array<int, 3> cells{1, 1, 1}; // cells of the domain per direction
    std::array<int, 3> nodes{1, 1, 1}; // nodes including ghost layers
    std::size_t n_nodes = 0, n_cells = 0;

    // Grid fields as node records of 8 doubles (one cache line), so that a
    // particle's scatter touches one line per node, not one per field:
    //   acc: [0] mass, [1..3] momentum, [4..6] force (P2G accumulators)
    //   vel: [0..2] v at the start of the step, [4..6] v~ at its end
    static constexpr std::size_t kRec = 8, kM = 0, kP = 1, kF = 4, kV0 = 0, kV1 = 4;
    // acc [7]: bit k set when a particle of particle_velocities[k] reaches
    // the node (exact in a double: 32 bits)
    static constexpr std::size_t kFix = 7;
    std::vector<double> acc, vel;

    // Nodes on or beyond each face (x-, x+, y-, y+, z-, z+).
    std::array<std::vector<std::uint32_t>, 6> face_nodes;
    std::vector<std::vector<std::uint32_t>> prescribed_nodes; // per Scenario::nodal_velocities

    // Slab colouring for conflict-free parallel P2G: slabs of `slab_width`
    // cells along `slab_axis`; a particle's stencil reaches at most one cell
    // below and two above its own, so slabs of one colour (every other slab)
    // never write the same node when slab_width >= 4.
    int slab_axis = 0, slab_width = 4, n_slabs = 1;
    std::vector<std::vector<std::uint32_t>> order;    // per set: particle indices by slab
    std::vector<std::vector<std::size_t>> slab_begin; // per set: n_slabs + 1 offsets

    std::vector<double> cell_div, cell_vol; // cell-averaged dilation sums
    std::vector<std::size_t> slab_end_tmp;  // bin_particles scratch
    std::tuple<std::vector<double>, std::vector<std::int64_t>, std::vector<std::int32_t>,
               std::vector<std::uint32_t>>
        sort_buffers;

    // Per-thread scratch for the plugin's cut-step sub-stepping.
    struct Scratch {
        std::vector<double> s0, q0, de, Fa, Fb, rho;
    };
    std::vector<Scratch> scratch;

    double apic_dinv = 0.0; // D_p^-1 of APIC for B-splines (Jiang et al. 2015)

    // Wall time per phase, for talus_bench --profile.
    std::array<double, Simulation::kPhases> phase_seconds{};
    struct PhaseTimer {
        double &acc;
        std::chrono::steady_clock::time_point t0 = std::chrono::steady_clock::now();
        ~PhaseTimer() {
            acc += std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
        }
    };
    PhaseTimer time_phase(int k) { return PhaseTimer{phase_seconds[static_cast<std::size_t>(k)]}; }

    // Kernels for this dimension and shape function.
    void (*p2g)(Impl &, bool mass_momentum, bool forces, bool remap, double t) = nullptr;
    // kin_dt > 0: also do the kinematics over kin_dt (fused USL path).
    void (*g2p_motion)(Impl &, double dt, bool gradient, double kin_dt) = nullptr;
    // pos_dt > 0: also the position step over pos_dt from the velocity at
    // pos_offset of the same records.
    void (*g2p_gradient)(Impl &, const double *field, std::size_t offset, std::size_t pos_offset,
                         double pos_dt) = nullptr;

    explicit Impl(Simulation &s) : sim(s) {}

    std::size_t node_index(int i, int j, int k) const {
        return static_cast<std::size_t>(i) +
               static_cast<std::size_t>(nodes[0]) *
                   (static_cast<std::size_t>(j) +
                    static_cast<std::size_t>(nodes[1]) * static_cast<std::size_t>(k));
    }
    // Cell (in domain cells) containing a position; clamped into the domain.
    std::size_t cell_index(const ParticleSet &s, std::size_t p) const {
        std::size_t idx = 0, stride = 1;
        for (int d = 0; d < dim; ++d) {
            int c = static_cast<int>(fast_floor(
                (s.x[static_cast<std::size_t>(d)][p] - origin[static_cast<std::size_t>(d)]) *
                inv_h));
            c = std::clamp(c, 0, cells[static_cast<std::size_t>(d)] - 1);
            idx += static_cast<std::size_t>(c) * stride;
            stride *= static_cast<std::size_t>(cells[static_cast<std::size_t>(d)]);
        }
        return idx;
    }
    int slab_of(const ParticleSet &s, std::size_t p) const {
        const std::size_t a = static_cast<std::size_t>(slab_axis);
        int c = static_cast<int>(fast_floor((s.x[a][p] - origin[a]) * inv_h));
        c = std::clamp(c, 0, cells[a] - 1);
        return std::min(c / slab_width, n_slabs - 1);
    }

    // sum_a w_a (x_a - x)^2 along axis d at coordinate x, m^2: the diagonal
    // entry of APIC's D_p (x_a: the nodes' Greville points).
    double affine_moment(int d, double x) const {
        const std::size_t dd = static_cast<std::size_t>(d);
        const double xi = (x - origin[dd]) * inv_h;
        auto moment = [&](auto shape) {
            using S = decltype(shape);
            int base = 0;
            double w[S::width], dw[S::width], gv[S::width];
            S::eval_bounded(xi, 0.0, cells[dd], base, w, dw, gv);
            return second_moment<S::width>(w, gv, xi) * h * h;
        };
        return sim.sc_.solver.shape == ShapeKind::bspline3 ? moment(BSpline3Shape{})
                                                           : moment(BSpline2Shape{});
    }
    void setup_grid();
    void bin_particles();
    void sort_particles();
    void reset_grid();
    void grid_velocities(double dt, double t, bool update);
    // Applies the boundary conditions to the velocity field at `offset` in
    // the records of `field` (vel at kV0 or kV1, or acc at kF for MUSL).
    void apply_bc(double *field, std::size_t offset, double t_eval);
    void kinematics_and_update(double dt, double t);
    void call_material(ParticleSet &s, std::size_t begin, std::size_t count, double t, double dt,
                       Scratch &scr, std::string &error, std::optional<FailedCall> &failed,
                       int depth);
    // The last pass of a step: positions, the leaving check, each particle's
    // slab for the next step's binning, and max(c + |v|) for its time step.
    void finish_step();
    void remove_or_report_leaving();
    std::vector<std::vector<std::int32_t>> slab_index; // per set, per particle
    double max_speed = -1.0;                           // < 0: not known yet
    // Particles whose cell index is below their predecessor's in memory
    // (counted by finish_step): a measure of how far the order has decayed.
    double out_of_order = 0.0;
    bool slabs_changed = true;                       // any particle changed slab in the last step
    std::vector<std::vector<std::uint32_t>> cell_of; // per set, per particle
    // Set when G2P already did the kinematics (USL without cell-averaged
    // dilation): one pass over the particles less. An inverted point found
    // there is remembered here and reported by kinematics_and_update.
    bool kinematics_done = false;
    bool initial_state = false;     // the constructor's call on the initial state
    bool positions_applied = false; // G2P moved the particles (fused USL)
    int inverted_set = -1;
    std::size_t inverted_particle = 0;
    std::string inversion_message(const ParticleSet &s, std::size_t p, double t) const {
        return fmt::format(
            "step {} (t = {:.6g} s): particle {} of group '{}' inverted (J = {:.3g} <= 0): the "
            "deformation in one step is too large; reduce cfl or dt",
            sim.step_ + 1, t, s.id[p], sim.sc_.groups[static_cast<std::size_t>(s.group[p])].name,
            s.J[p]);
    }

    // Functions of time evaluated once per step, not once per particle:
    // each load's value at t, each fixity's velocity at t and t + dt.
    std::vector<std::array<double, 3>> load_now, fix_start, fix_end;
    std::vector<double> group_area; // traction area (h / ppc)^(dim - 1) per group
    void evaluate_time_functions(double t, double dt) {
        const Scenario &sc = sim.sc_;
        load_now.resize(sc.loads.size());
        for (std::size_t k = 0; k < sc.loads.size(); ++k)
            for (int d = 0; d < dim; ++d)
                load_now[k][static_cast<std::size_t>(d)] =
                    sc.loads[k].value[static_cast<std::size_t>(d)](t);
        fix_start.resize(sc.particle_velocities.size());
        fix_end.resize(sc.particle_velocities.size());
        for (std::size_t k = 0; k < sc.particle_velocities.size(); ++k)
            for (int d = 0; d < dim; ++d)
                if (const auto &fn =
                        sc.particle_velocities[k].velocity.c[static_cast<std::size_t>(d)]) {
                    fix_start[k][static_cast<std::size_t>(d)] = (*fn)(t);
                    fix_end[k][static_cast<std::size_t>(d)] = (*fn)(t + dt);
                }
    }
};

namespace {

inline double stress_work(const double *sig, const double *de) {
    return sig[0] * de[0] + sig[1] * de[1] + sig[2] * de[2] + sig[3] * de[3] + sig[4] * de[4] +
           sig[5] * de[5];
}

// Per-point kinematics: F (eq. 39), J, density (eq. 41), the strain
// increment (eq. 42), div v, the objective rotation of the start stress,
// and the first half of the stress work. Returns false if the point
// inverted (J <= 0). L is a row-major 3x3 (Stride 3) or D x D (Stride D).
template <int Stride>
inline bool kinematics_point(ParticleSet &s, std::size_t p, const double *Lg, double dt, int dim,
                             bool defer_work) {
    double L[9] = {0, 0, 0, 0, 0, 0, 0, 0, 0};
    for (int r = 0; r < (Stride == 3 ? 3 : Stride); ++r)
        for (int c = 0; c < (Stride == 3 ? 3 : Stride); ++c)
            L[3 * r + c] = Lg[Stride * r + c];
    const double *F0 = &s.F[9 * p];
    double *F1 = &s.F_new[9 * p];
    double J;
    if (dim == 2) {
        // Plane strain: only the in-plane block of F changes.
        const double a00 = 1.0 + dt * L[0], a01 = dt * L[1], a10 = dt * L[3], a11 = 1.0 + dt * L[4];
        F1[0] = a00 * F0[0] + a01 * F0[3];
        F1[1] = a00 * F0[1] + a01 * F0[4];
        F1[3] = a10 * F0[0] + a11 * F0[3];
        F1[4] = a10 * F0[1] + a11 * F0[4];
        F1[2] = F1[5] = F1[6] = F1[7] = 0.0;
        F1[8] = F0[8];
        J = (F1[0] * F1[4] - F1[1] * F1[3]) * F1[8];
    } else {
        for (int i = 0; i < 3; ++i)
            for (int j = 0; j < 3; ++j)
                F1[3 * i + j] = F0[3 * i + j] + dt * (L[3 * i] * F0[j] + L[3 * i + 1] * F0[3 + j] +
                                                      L[3 * i + 2] * F0[6 + j]);
        J = F1[0] * (F1[4] * F1[8] - F1[5] * F1[7]) - F1[1] * (F1[3] * F1[8] - F1[5] * F1[6]) +
            F1[2] * (F1[3] * F1[7] - F1[4] * F1[6]);
    }
    // A failing J is kept too: the error message and the failure output
    // show the value that failed, not the last valid one.
    s.J[p] = J;
    if (!(J > 0.0)) return false;
    s.rho[p] = s.rho0 / J;
    double *de = &s.de[6 * p];
    de[0] = dt * L[0];
    de[1] = dt * L[4];
    de[2] = dt * L[8];
    de[3] = dt * (L[1] + L[3]);
    de[4] = dt * (L[5] + L[7]);
    de[5] = dt * (L[2] + L[6]);
    if (s.has_divv) s.divv[p] = L[0] + L[4] + L[8];
    if (!s.finite_strain) hughes_winget(L, dt, &s.stress[6 * p]);
    if (!defer_work) s.work[p] += 0.5 * J * s.vol0[p] * stress_work(&s.stress[6 * p], de);
    return true;
}

// ------------------------------------------------------------- stencils --

// Weights and gradients of one particle's stencil. The kernels see the
// domain's bounds (eval_bounded): the B-splines are clamped at the faces.
template <int D, class S, bool Offsets = true>
struct Stencil {
    static constexpr int W = S::width;
    static constexpr int NN = D == 2 ? W * W : W * W * W;
    std::size_t idx[NN];
    double w[NN];
    double grad[NN][D];
    double off[Offsets ? NN : 1][D]; // x_i - x_p, m (x_i: the node's Greville point)
    // 1 / D_p per axis, 1/m^2: D_p = sum_i w_ip (x_i - x_p)(x_i - x_p)^T is
    // diagonal for a tensor-product kernel with linear precision (the cross
    // terms factor into sum_a w_a (x_a - x_p) = 0), h^2/4 (quadratic) or
    // h^2/3 (cubic) away from the faces (Jiang et al. 2015).
    double dinv[D];

    // Almost every particle is away from the faces, where the uniform kernel
    // holds. The hot kernels test this once per particle and run their
    // per-particle body in two instantiations, the uniform one inline and
    // the clamped one (docs/theory.md, "Boundaries") out of line: one
    // branch inside the shared body costs 10 % in 3D through register
    // allocation alone.
    [[gnu::always_inline]] static bool interior(const Simulation::Impl &g, const ParticleSet &s,
                                                std::size_t p) {
        bool inner = true;
        for (int d = 0; d < D; ++d) {
            const std::size_t dd = static_cast<std::size_t>(d);
            inner = inner && S::interior((s.x[dd][p] - g.origin[dd]) * g.inv_h, g.cells[dd]);
        }
        return inner;
    }

    // Near == false requires interior(g, s, p).
    template <bool Near>
    [[gnu::always_inline]] void eval(const Simulation::Impl &g, const ParticleSet &s,
                                     std::size_t p) {
        int base[D];
        double w1[D][W], dw1[D][W], g1[D][W], xi[D];
        for (int d = 0; d < D; ++d) {
            const std::size_t dd = static_cast<std::size_t>(d);
            xi[d] = (s.x[dd][p] - g.origin[dd]) * g.inv_h;
            if constexpr (Near)
                S::eval_bounded(xi[d], s.lp[p], g.cells[dd], base[d], w1[d], dw1[d], g1[d]);
            else
                S::eval(xi[d], s.lp[p], base[d], w1[d], dw1[d]);
            base[d] += g.ghost;
            for (int k = 0; k < W; ++k)
                dw1[d][k] *= g.inv_h; // d/dx = d/dxi / h, once per axis
            if constexpr (Offsets) {
                if constexpr (Near) {
                    const double m2 = second_moment<W>(w1[d], g1[d], xi[d]) * g.h * g.h;
                    dinv[d] = m2 > 0.0 ? 1.0 / m2 : 0.0;
                } else {
                    dinv[d] = g.apic_dinv;
                }
            }
        }
        combine(g, base, w1, dw1, Near ? g1 : nullptr, xi);
    }

    void eval(const Simulation::Impl &g, const ParticleSet &s, std::size_t p) {
        if (interior(g, s, p))
            eval<false>(g, s, p);
        else
            eval<true>(g, s, p);
    }

    // Tensor products of the per-axis weights; node points g1 in cells (the
    // nodes themselves when null).
    [[gnu::always_inline]] void combine(const Simulation::Impl &g, const int *base,
                                        const double (*w1)[W], const double (*dw1)[W],
                                        const double (*g1)[W], const double *xi) {
        double o1[D][W];
        if constexpr (Offsets)
            for (int d = 0; d < D; ++d)
                for (int k = 0; k < W; ++k)
                    o1[d][k] = ((g1 ? g1[d][k] : base[d] - g.ghost + k) - xi[d]) * g.h;
        int q = 0;
        if constexpr (D == 2) {
            for (int b = 0; b < W; ++b)
                for (int a = 0; a < W; ++a, ++q) {
                    idx[q] = g.node_index(base[0] + a, base[1] + b, 0);
                    w[q] = w1[0][a] * w1[1][b];
                    grad[q][0] = dw1[0][a] * w1[1][b];
                    grad[q][1] = w1[0][a] * dw1[1][b];
                    if constexpr (Offsets) {
                        off[q][0] = o1[0][a];
                        off[q][1] = o1[1][b];
                    }
                }
        } else {
            for (int c = 0; c < W; ++c)
                for (int b = 0; b < W; ++b)
                    for (int a = 0; a < W; ++a, ++q) {
                        idx[q] = g.node_index(base[0] + a, base[1] + b, base[2] + c);
                        const double wbc = w1[1][b] * w1[2][c];
                        w[q] = w1[0][a] * wbc;
                        grad[q][0] = dw1[0][a] * wbc;
                        grad[q][1] = w1[0][a] * dw1[1][b] * w1[2][c];
                        grad[q][2] = w1[0][a] * w1[1][b] * dw1[2][c];
                        if constexpr (Offsets) {
                            off[q][0] = o1[0][a];
                            off[q][1] = o1[1][b];
                            off[q][2] = o1[2][c];
                        }
                    }
        }
    }
};

// Sum of the applied forces on particle p at this step (point loads and
// tractions; a traction acts on the particle's face area V0^((d-1)/d)).
template <int D>
void particle_load(const Simulation::Impl &g, const ParticleSet &s, std::size_t p, double *f) {
    for (int d = 0; d < D; ++d)
        f[d] = 0.0;
    std::uint32_t mask = s.load_mask[p];
    const auto &loads = g.sim.scenario().loads;
    while (mask) {
        const int k = __builtin_ctz(mask);
        mask &= mask - 1;
        const double scale = loads[static_cast<std::size_t>(k)].kind == Load::Kind::traction
                                 ? g.group_area[static_cast<std::size_t>(s.group[p])]
                                 : 1.0;
        for (int d = 0; d < D; ++d)
            f[d] += scale * g.load_now[static_cast<std::size_t>(k)][static_cast<std::size_t>(d)];
    }
}

// Phase 1 (P2G): nodal mass (eq. 28), momentum with the affine term (eq.
// 29), internal force with the current volume and Cauchy stress (eq. 20),
// external force (eq. 21). Remap re-projects the updated particle momentum
// only (MUSL) into the momentum slots.
template <int D, class S, bool Mass, bool Momentum, bool Affine, bool Forces>
void p2g_pass(Simulation::Impl &g, const double *grav) {
    using Impl = Simulation::Impl;
    auto &sets = g.sim.sets();
    double *acc = g.acc.data();
    for (int colour = 0; colour < 2; ++colour) {
#pragma omp parallel for schedule(dynamic, 1)
        for (int slab = colour; slab < g.n_slabs; slab += 2) {
            using St = Stencil<D, S, Affine>;
            for (std::size_t si = 0; si < sets.size(); ++si) {
                const ParticleSet &s = sets[si];
                const std::uint32_t *ord = g.order[si].data();
                const std::size_t b = g.slab_begin[si][static_cast<std::size_t>(slab)];
                const std::size_t e = g.slab_begin[si][static_cast<std::size_t>(slab) + 1];
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
                        if (s.load_mask[p]) particle_load<D>(g, s, p, fext);
                        for (int d = 0; d < D; ++d)
                            fext[d] += m * grav[d];
                    }
                    const std::uint32_t fixed = Mass ? s.fix_mask[p] : 0u;
                    for (int q = 0; q < St::NN; ++q) {
                        double *rec = acc + Impl::kRec * st.idx[q];
                        const double mw = m * st.w[q];
                        if constexpr (Mass) rec[Impl::kM] += mw;
                        // The nodes a fixed particle reaches carry its
                        // fixity (apply_bc): a constraint the grid sees.
                        if (fixed && st.w[q] > 0.0) [[unlikely]]
                            rec[Impl::kFix] = static_cast<double>(
                                static_cast<std::uint32_t>(rec[Impl::kFix]) | fixed);
                        for (int d = 0; d < D; ++d) {
                            if constexpr (Momentum) {
                                double vq = vp[d];
                                if constexpr (Affine)
                                    for (int c = 0; c < D; ++c)
                                        vq += Cp[d][c] * st.off[q][c];
                                rec[Impl::kP + static_cast<std::size_t>(d)] += mw * vq;
                            }
                            if constexpr (Forces) {
                                double fi = st.w[q] * fext[d];
                                for (int c = 0; c < D; ++c)
                                    fi -= Vsig[d][c] * st.grad[q][c];
                                rec[Impl::kF + static_cast<std::size_t>(d)] += fi;
                            }
                        }
                    }
                };
                auto near_face = [&](std::size_t p) __attribute__((noinline)) {
                    body(std::true_type{}, p);
                };
                for (std::size_t k = b; k < e; ++k) {
                    const std::size_t p = ord[k];
                    if (St::interior(g, s, p)) [[likely]]
                        body(std::false_type{}, p);
                    else
                        near_face(p);
                }
            }
        }
    }
}

template <int D, class S>
void p2g_kernel(Simulation::Impl &g, bool mass_momentum, bool forces, bool remap, double t) {
    const auto &sc = g.sim.scenario();
    const double ramp = sc.gravity_ramp > 0.0 ? std::min(1.0, t / sc.gravity_ramp) : 1.0;
    double grav[3];
    for (int d = 0; d < 3; ++d)
        grav[d] = sc.gravity[static_cast<std::size_t>(d)] * ramp;
    const bool affine = sc.solver.transfer != Transfer::flip;
    // MUSL remap: the updated particle momentum alone, no affine term.
    if (remap) return p2g_pass<D, S, false, true, false, false>(g, grav);
    // USF / USAVG second pass: forces alone, from the updated stress.
    if (!mass_momentum) return p2g_pass<D, S, false, false, false, true>(g, grav);
    if (affine) {
        if (forces)
            p2g_pass<D, S, true, true, true, true>(g, grav);
        else
            p2g_pass<D, S, true, true, true, false>(g, grav);
    } else {
        if (forces)
            p2g_pass<D, S, true, true, false, true>(g, grav);
        else
            p2g_pass<D, S, true, true, false, false>(g, grav);
    }
}

// A velocity fixity prescribes the displacement of its components over the
// step (trapezoidal in the prescribed velocity), whatever the grid says.
template <int D>
inline void fixity_step(const Simulation::Impl &g, std::uint32_t mask, double dt, double *step) {
    const auto &fixes = g.sim.scenario().particle_velocities;
    while (mask) {
        const std::size_t k = static_cast<std::size_t>(__builtin_ctz(mask));
        mask &= mask - 1;
        for (int d = 0; d < D; ++d) {
            const std::size_t dd = static_cast<std::size_t>(d);
            if (fixes[k].velocity.c[dd])
                step[d] = 0.5 * dt * (g.fix_start[k][dd] + g.fix_end[k][dd]);
        }
    }
}

// Phase 3 (G2P) motion: particle velocity by the FLIP/PIC blend (eq. 36) or
// PIC with an affine matrix (APIC / TPIC), the position increment (first
// order, or second order: x + dt v~ - dt^2/2 a = x + dt (v + v~)/2, see
// docs/theory.md on eq. 37), and optionally the velocity gradient from v~
// (eq. 38).
template <int D, class S, bool Gradient, bool Apic, bool Kinematics>
void g2p_motion_pass(Simulation::Impl &g, double dt, double kin_dt) {
    using Impl = Simulation::Impl;
    auto &sets = g.sim.sets();
    const auto &sc = g.sim.scenario();
    const Transfer tr = sc.solver.transfer;
    const double alpha = tr == Transfer::flip ? sc.solver.alpha : 0.0;
    const bool second = trapezoid_positions(sc.solver);
    const bool move = velocity_pass_moves_particles(sc.solver);
    const double *vel = g.vel.data();
    const bool bspline = g.apic_dinv > 0.0;
    using St = Stencil<D, S, Apic>;
    for (auto &s : sets) {
        const std::ptrdiff_t n = static_cast<std::ptrdiff_t>(s.n);
        auto body = [&](auto near, std::size_t p) __attribute__((always_inline)) {
            St st;
            st.template eval<decltype(near)::value>(g, s, p);
            double vpic[D] = {}, vold[D] = {}, L[D][D] = {}, B[D][D] = {}, step[D];
            for (int q = 0; q < St::NN; ++q) {
                const double *rec = vel + Impl::kRec * st.idx[q];
                for (int d = 0; d < D; ++d) {
                    const double a1 = rec[Impl::kV1 + static_cast<std::size_t>(d)];
                    vpic[d] += st.w[q] * a1;
                    vold[d] += st.w[q] * rec[Impl::kV0 + static_cast<std::size_t>(d)];
                    if constexpr (Gradient)
                        for (int c = 0; c < D; ++c)
                            L[d][c] += a1 * st.grad[q][c];
                    if constexpr (Apic)
                        for (int c = 0; c < D; ++c)
                            B[d][c] += st.w[q] * a1 * st.off[q][c];
                }
            }
            for (int d = 0; d < D; ++d) {
                const std::size_t dd = static_cast<std::size_t>(d);
                s.v[dd][p] = vpic[d] + alpha * (s.v[dd][p] - vold[d]);
                step[d] = second ? 0.5 * dt * (vpic[d] + vold[d]) : dt * vpic[d];
            }
            if constexpr (Kinematics) {
                if (!kinematics_point<D>(s, p, &L[0][0], kin_dt, D, false)) {
#pragma omp critical(talus_inverted)
                    if (g.inverted_set < 0) {
                        g.inverted_set = static_cast<int>(&s - g.sim.sets().data());
                        g.inverted_particle = p;
                    }
                }
            } else if constexpr (Gradient) {
                for (int r = 0; r < D; ++r)
                    for (int c = 0; c < D; ++c)
                        s.L[9 * p + static_cast<std::size_t>(3 * r + c)] = L[r][c];
            }
            if constexpr (Apic) {
                // C_p = B_p D_p^-1 (Jiang et al. 2015); for tent-based kernels
                // D_p is not constant and grad w plays the role of w D^-1 dx.
                for (int r = 0; r < D; ++r)
                    for (int c = 0; c < D; ++c)
                        s.C[9 * p + static_cast<std::size_t>(3 * r + c)] =
                            bspline ? B[r][c] * st.dinv[c] : L[r][c];
            } else if (tr == Transfer::tpic) {
                // Taylor transfer: the velocity gradient itself (eq. 29).
                for (int r = 0; r < D; ++r)
                    for (int c = 0; c < D; ++c)
                        s.C[9 * p + static_cast<std::size_t>(3 * r + c)] = L[r][c];
            }
            // Particle velocity fixities override the grid's answer.
            if (std::uint32_t mask = s.fix_mask[p]) {
                const auto &fixes = sc.particle_velocities;
                for (std::uint32_t m = mask; m;) {
                    const std::size_t k = static_cast<std::size_t>(__builtin_ctz(m));
                    m &= m - 1;
                    for (int d = 0; d < D; ++d)
                        if (fixes[k].velocity.c[static_cast<std::size_t>(d)])
                            s.v[static_cast<std::size_t>(d)][p] =
                                g.fix_end[k][static_cast<std::size_t>(d)];
                }
                fixity_step<D>(g, mask, dt, step);
            }
            // With the kinematics fused in (USL) nothing later in the step
            // needs the start position: move the particle now.
            for (int d = 0; d < D; ++d) {
                if constexpr (Kinematics)
                    s.x[static_cast<std::size_t>(d)][p] += step[d];
                else if (move)
                    s.dx[static_cast<std::size_t>(d)][p] = step[d];
            }
        };
        auto near_face = [&](std::size_t p) __attribute__((noinline)) {
            body(std::true_type{}, p);
        };
#pragma omp parallel for schedule(static)
        for (std::ptrdiff_t pp = 0; pp < n; ++pp) {
            const std::size_t p = static_cast<std::size_t>(pp);
            if (St::interior(g, s, p)) [[likely]]
                body(std::false_type{}, p);
            else
                near_face(p);
        }
    }
}

template <int D, class S>
void g2p_motion_kernel(Simulation::Impl &g, double dt, bool gradient, double kin_dt) {
    const Transfer tr = g.sim.scenario().solver.transfer;
    // APIC and TPIC need the gradient of v~ for C whatever the scheme.
    const bool grad = gradient || tr != Transfer::flip;
    if (kin_dt > 0.0) {
        g.kinematics_done = true;
        g.positions_applied = true;
        g.inverted_set = -1;
        if (tr == Transfer::apic) return g2p_motion_pass<D, S, true, true, true>(g, dt, kin_dt);
        return g2p_motion_pass<D, S, true, false, true>(g, dt, kin_dt);
    }
    if (tr == Transfer::apic) return g2p_motion_pass<D, S, true, true, false>(g, dt, 0.0);
    if (grad) return g2p_motion_pass<D, S, true, false, false>(g, dt, 0.0);
    g2p_motion_pass<D, S, false, false, false>(g, dt, 0.0);
}

// Velocity gradient (eq. 38) from one velocity field of the node records,
// for the schemes that take it from another field than v~ (USF, MUSL,
// USAVG). With pos_dt > 0 the particle also moves over pos_dt with the
// velocity at pos_offset of the same records (USF, MUSL: the field of the
// gradient, or for second-order MUSL its mean with the start velocities).
template <int D, class S, bool Positions>
void g2p_gradient_pass(Simulation::Impl &g, const double *field, std::size_t offset,
                       std::size_t pos_offset, double pos_dt) {
    using Impl = Simulation::Impl;
    for (auto &s : g.sim.sets()) {
        const std::ptrdiff_t n = static_cast<std::ptrdiff_t>(s.n);
#pragma omp parallel for schedule(static)
        for (std::ptrdiff_t pp = 0; pp < n; ++pp) {
            const std::size_t p = static_cast<std::size_t>(pp);
            Stencil<D, S, false> st;
            st.eval(g, s, p);
            double L[D][D] = {}, vk[D] = {};
            for (int q = 0; q < Stencil<D, S, false>::NN; ++q) {
                const double *node = field + Impl::kRec * st.idx[q];
                const double *rec = node + offset;
                for (int d = 0; d < D; ++d) {
                    if constexpr (Positions)
                        vk[d] += st.w[q] * node[pos_offset + static_cast<std::size_t>(d)];
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
                    step[d] = pos_dt * vk[d];
                if (const std::uint32_t mask = s.fix_mask[p]) fixity_step<D>(g, mask, pos_dt, step);
                for (int d = 0; d < D; ++d)
                    s.dx[static_cast<std::size_t>(d)][p] = step[d];
            }
        }
    }
}

template <int D, class S>
void g2p_gradient_kernel(Simulation::Impl &g, const double *field, std::size_t offset,
                         std::size_t pos_offset, double pos_dt) {
    if (pos_dt > 0.0) return g2p_gradient_pass<D, S, true>(g, field, offset, pos_offset, pos_dt);
    g2p_gradient_pass<D, S, false>(g, field, offset, 0, 0.0);
}

template <int D, class S>
void bind(Simulation::Impl &g) {
    g.p2g = &p2g_kernel<D, S>;
    g.g2p_motion = &g2p_motion_kernel<D, S>;
    g.g2p_gradient = &g2p_gradient_kernel<D, S>;
}

template <int D>
void bind_shape(Simulation::Impl &g, ShapeKind k) {
    switch (k) {
    case ShapeKind::linear: bind<D, LinearShape>(g); break;
    case ShapeKind::gimp: bind<D, GimpShape>(g); break;
    case ShapeKind::bspline2: bind<D, BSpline2Shape>(g); break;
    case ShapeKind::bspline3: bind<D, BSpline3Shape>(g); break;
    }
}

} // namespace

// ------------------------------------------------------------ grid setup --

void Simulation::Impl::setup_grid() {
    const Scenario &sc = sim.sc_;
    dim = sc.dim;
    h = sc.cell;
    inv_h = 1.0 / h;
    origin = sc.origin;
    n_nodes = 1;
    n_cells = 1;
    for (int d = 0; d < 3; ++d) {
        const std::size_t dd = static_cast<std::size_t>(d);
        if (d < dim) {
            cells[dd] = static_cast<int>(std::lround(sc.size[dd] / h));
            nodes[dd] = cells[dd] + 1 + 2 * ghost;
        } else {
            cells[dd] = 1;
            nodes[dd] = 1;
        }
        n_nodes *= static_cast<std::size_t>(nodes[dd]);
        n_cells *= static_cast<std::size_t>(cells[dd]);
    }
    acc.assign(kRec * n_nodes, 0.0);
    vel.assign(kRec * n_nodes, 0.0);
    // The nodes whose functions are non-zero at a face, and those beyond,
    // carry that face's condition: for the clamped B-splines the layer just
    // outside the face (the node on the face has a function vanishing there
    // and stays free), for the tent-based kernels the face node and beyond.
    const int layer = face_layer(sc.solver.shape);
    for (std::size_t i = 0; i < n_nodes; ++i) {
        const int ijk[3] = {static_cast<int>(i % static_cast<std::size_t>(nodes[0])),
                            static_cast<int>((i / static_cast<std::size_t>(nodes[0])) %
                                             static_cast<std::size_t>(nodes[1])),
                            static_cast<int>(i / (static_cast<std::size_t>(nodes[0]) *
                                                  static_cast<std::size_t>(nodes[1])))};
        for (int d = 0; d < dim; ++d) {
            if (ijk[d] <= ghost - layer)
                face_nodes[static_cast<std::size_t>(2 * d)].push_back(
                    static_cast<std::uint32_t>(i));
            if (ijk[d] >= ghost + cells[static_cast<std::size_t>(d)] + layer)
                face_nodes[static_cast<std::size_t>(2 * d + 1)].push_back(
                    static_cast<std::uint32_t>(i));
        }
        (void)ijk;
    }
    prescribed_nodes.resize(sc.nodal_velocities.size());
    for (std::size_t k = 0; k < sc.nodal_velocities.size(); ++k)
        for (std::size_t i = 0; i < n_nodes; ++i) {
            double x[3];
            const int ijk[3] = {static_cast<int>(i % static_cast<std::size_t>(nodes[0])),
                                static_cast<int>((i / static_cast<std::size_t>(nodes[0])) %
                                                 static_cast<std::size_t>(nodes[1])),
                                static_cast<int>(i / (static_cast<std::size_t>(nodes[0]) *
                                                      static_cast<std::size_t>(nodes[1])))};
            // A node stands for its Greville point (clamped B-splines).
            for (int d = 0; d < dim; ++d)
                x[d] = origin[static_cast<std::size_t>(d)] +
                       node_greville(sc.solver.shape, ijk[d] - ghost,
                                     cells[static_cast<std::size_t>(d)]) *
                           h;
            if (sc.nodal_velocities[k].box.contains(x, dim))
                prescribed_nodes[k].push_back(static_cast<std::uint32_t>(i));
        }
    for (std::size_t k = 0; k < sc.nodal_velocities.size(); ++k)
        if (prescribed_nodes[k].empty())
            throw Error(sc.nodal_velocities[k].origin.error(fmt::format(
                "the box holds no grid node (nodes are {:g} m apart{}); enlarge the box", h,
                face_layer(sc.solver.shape) > 0 ? ", at their Greville points near a face" : "")));

    // Slabs across the longest direction; on a tie the slowest-varying
    // index of the cell order, so that a slab's particles are contiguous in
    // memory once sorted by cell.
    slab_axis = dim - 1;
    for (int d = dim - 2; d >= 0; --d)
        if (cells[static_cast<std::size_t>(d)] > cells[static_cast<std::size_t>(slab_axis)])
            slab_axis = d;
    n_slabs = std::max(1, cells[static_cast<std::size_t>(slab_axis)] / slab_width);

    if (sc.solver.cell_averaged_dilation) {
        cell_div.assign(n_cells, 0.0);
        cell_vol.assign(n_cells, 0.0);
    }
    // Sum over the stencil of w (x_i - x_p)(x_i - x_p)^T is h^2/4 I for the
    // quadratic and h^2/3 I for the cubic B-spline (Jiang et al. 2015).
    if (sc.solver.shape == ShapeKind::bspline2)
        apic_dinv = 4.0 / (h * h);
    else if (sc.solver.shape == ShapeKind::bspline3)
        apic_dinv = 3.0 / (h * h);

    if (dim == 2)
        bind_shape<2>(*this, sc.solver.shape);
    else
        bind_shape<3>(*this, sc.solver.shape);
#ifdef _OPENMP
    scratch.resize(static_cast<std::size_t>(omp_get_max_threads()));
#else
    scratch.resize(1);
#endif
}

// Groups the particles of every set by slab (a counting sort of indices).
void Simulation::Impl::bin_particles() {
    auto &sets = sim.sets_;
    // Unchanged slabs give the same order: nothing to redo.
    bool same = !slabs_changed && order.size() == sets.size();
    for (std::size_t si = 0; same && si < sets.size(); ++si)
        same = order[si].size() == sets[si].n && slab_index[si].size() == sets[si].n;
    if (same) return;
    order.resize(sets.size());
    slab_begin.resize(sets.size());
    slab_index.resize(sets.size());
    for (std::size_t si = 0; si < sets.size(); ++si) {
        const ParticleSet &s = sets[si];
        auto &begin = slab_begin[si];
        begin.assign(static_cast<std::size_t>(n_slabs) + 1, 0);
        // Slabs come from the last pass of the previous step, or are
        // computed here after a sort or at the start.
        auto &slab = slab_index[si];
        if (slab.size() != s.n) {
            slab.resize(s.n);
            for (std::size_t p = 0; p < s.n; ++p)
                slab[p] = slab_of(s, p);
        }
        for (std::size_t p = 0; p < s.n; ++p)
            ++begin[static_cast<std::size_t>(slab[p]) + 1];
        std::partial_sum(begin.begin(), begin.end(), begin.begin());
        order[si].resize(s.n);
        // Fill by decrementing the end offsets, walking backwards so that
        // each slab keeps memory order.
        std::vector<std::size_t> &end = slab_end_tmp;
        end.assign(begin.begin() + 1, begin.end());
        for (std::size_t p = s.n; p-- > 0;)
            order[si][--end[static_cast<std::size_t>(slab[p])]] = static_cast<std::uint32_t>(p);
    }
}

// Reorders each set's particles by cell so that neighbours in memory are
// neighbours on the grid (cache locality of P2G and G2P).
void Simulation::Impl::sort_particles() {
    for (ParticleSet &s : sim.sets_) {
        std::vector<std::size_t> key(s.n), perm(s.n);
        for (std::size_t p = 0; p < s.n; ++p)
            key[p] = cell_index(s, p);
        std::iota(perm.begin(), perm.end(), 0);
        std::stable_sort(perm.begin(), perm.end(),
                         [&](std::size_t a, std::size_t b) { return key[a] < key[b]; });
        bool sorted = true;
        for (std::size_t p = 0; p < s.n && sorted; ++p)
            sorted = perm[p] == p;
        if (sorted) continue;
        // Permute every array through one reusable buffer: no second copy
        // of the particles (which would fault in fresh pages every sort).
        auto permute = [&](auto &a, std::size_t stride) {
            using T = typename std::decay_t<decltype(a)>::value_type;
            auto &buf = std::get<std::vector<T>>(sort_buffers);
            buf.resize(s.n * stride);
            for (std::size_t p = 0; p < s.n; ++p)
                std::copy_n(a.begin() + static_cast<std::ptrdiff_t>(perm[p] * stride), stride,
                            buf.begin() + static_cast<std::ptrdiff_t>(p * stride));
            std::copy(buf.begin(), buf.end(), a.begin());
        };
        for_each_array(s, permute);
        permute(s.id, 1);
        permute(s.group, 1);
        permute(s.load_mask, 1);
        permute(s.fix_mask, 1);
    }
    for (auto &sl : slab_index)
        sl.clear(); // recomputed by bin_particles
    slabs_changed = true;
}

void Simulation::Impl::reset_grid() {
    // Parallel: on a large grid this is tens of megabytes every step.
    const std::ptrdiff_t chunks = 64;
    const std::size_t len = acc.size();
#pragma omp parallel for schedule(static)
    for (std::ptrdiff_t c = 0; c < chunks; ++c) {
        const std::size_t b = len * static_cast<std::size_t>(c) / chunks;
        const std::size_t e = len * static_cast<std::size_t>(c + 1) / chunks;
        std::fill(acc.begin() + static_cast<std::ptrdiff_t>(b),
                  acc.begin() + static_cast<std::ptrdiff_t>(e), 0.0);
    }
}

// Boundary conditions on a nodal velocity field (seed 004 step 2.4). Contact
// (slip, friction) is unilateral: a node moving away from the wall is left
// alone; one moving into it loses its normal velocity and, with Coulomb
// friction, its tangential speed is reduced by mu times the normal speed
// removed (a velocity projection of the impulse).
void Simulation::Impl::apply_bc(double *field, std::size_t offset, double t_eval) {
    const Scenario &sc = sim.sc_;
    auto V = [&](std::uint32_t i) { return field + kRec * i + offset; };
    for (int f = 0; f < 2 * dim; ++f) {
        const FaceCondition &fc = sc.faces[static_cast<std::size_t>(f)];
        if (fc.type == FaceType::free) continue;
        const std::size_t axis = static_cast<std::size_t>(f / 2);
        const double sign = (f % 2 == 0) ? -1.0 : 1.0; // outward normal
        for (std::uint32_t i : face_nodes[static_cast<std::size_t>(f)]) {
            double *v = V(i);
            if (fc.type == FaceType::fixed) {
                for (int d = 0; d < dim; ++d)
                    v[d] = 0.0;
            } else if (fc.type == FaceType::roller) {
                v[axis] = 0.0;
            } else {
                const double vn = sign * v[axis];
                if (vn <= 0.0) continue; // separating: no contact
                v[axis] = 0.0;
                if (fc.friction == 0.0) continue;
                double vt2 = 0.0;
                for (int d = 0; d < dim; ++d)
                    if (static_cast<std::size_t>(d) != axis) vt2 += v[d] * v[d];
                const double vt = std::sqrt(vt2);
                const double scale = vt > 0.0 ? std::max(0.0, 1.0 - fc.friction * vn / vt) : 0.0;
                for (int d = 0; d < dim; ++d)
                    if (static_cast<std::size_t>(d) != axis) v[d] *= scale;
            }
        }
    }
    for (std::size_t k = 0; k < sc.nodal_velocities.size(); ++k)
        for (int d = 0; d < dim; ++d)
            if (const auto &fn = sc.nodal_velocities[k].velocity.c[static_cast<std::size_t>(d)]) {
                const double v = (*fn)(t_eval);
                for (std::uint32_t i : prescribed_nodes[k])
                    V(i)[d] = v;
            }
    // Particle fixities act on the grid too: every node a fixed particle
    // reaches moves as prescribed, so the body attached to those particles
    // is held through the grid (a fixity on the particles alone would keep
    // them in place while the grid, and the rest of the body, moved on).
    // The constrained zone is the fixed particles plus one kernel support.
    const auto &fixes = sc.particle_velocities;
    if (fixes.empty()) return;
    double value[kMaxLoads][3];
    for (std::size_t k = 0; k < fixes.size(); ++k)
        for (int d = 0; d < dim; ++d)
            if (const auto &fn = fixes[k].velocity.c[static_cast<std::size_t>(d)])
                value[k][d] = (*fn)(t_eval);
    const std::ptrdiff_t N = static_cast<std::ptrdiff_t>(n_nodes);
#pragma omp parallel for schedule(static)
    for (std::ptrdiff_t ii = 0; ii < N; ++ii) {
        const std::uint32_t i = static_cast<std::uint32_t>(ii);
        std::uint32_t mask = static_cast<std::uint32_t>(acc[kRec * i + kFix]);
        while (mask) {
            const std::size_t k = static_cast<std::size_t>(__builtin_ctz(mask));
            mask &= mask - 1;
            for (int d = 0; d < dim; ++d)
                if (fixes[k].velocity.c[static_cast<std::size_t>(d)]) V(i)[d] = value[k][d];
        }
    }
}

// Phase 2: v = p / m (eq. 30) with the boundary conditions at t; with
// `update`, v~ = v + dt f / m (eqs. 31-32) with the conditions at t + dt.
void Simulation::Impl::grid_velocities(double dt, double t, bool update) {
    const std::ptrdiff_t N = static_cast<std::ptrdiff_t>(n_nodes);
    double *a = acc.data(), *v = vel.data();
    const int D = dim;
    // v = p / m everywhere and, when updating, v~ = v + dt f / m in the same
    // pass; the constrained nodes are then redone in order (conditions on v,
    // v~ from the constrained v, conditions on v~), which matters for
    // friction, where v~'s approach speed depends on the constrained v.
#pragma omp parallel for schedule(static)
    for (std::ptrdiff_t ii = 0; ii < N; ++ii) {
        const std::size_t i = static_cast<std::size_t>(ii);
        const double m = a[kRec * i + kM];
        const double inv = m > 0.0 ? 1.0 / m : 0.0;
        for (int d = 0; d < D; ++d) {
            const std::size_t dd = static_cast<std::size_t>(d);
            const double v0 = a[kRec * i + kP + dd] * inv;
            v[kRec * i + kV0 + dd] = v0;
            if (update) v[kRec * i + kV1 + dd] = v0 + dt * a[kRec * i + kF + dd] * inv;
        }
    }
    apply_bc(v, kV0, t);
    if (!update) return;
    auto redo = [&](std::uint32_t i) {
        const double m = a[kRec * i + kM];
        const double inv = m > 0.0 ? 1.0 / m : 0.0;
        for (int d = 0; d < D; ++d) {
            const std::size_t dd = static_cast<std::size_t>(d);
            v[kRec * i + kV1 + dd] = v[kRec * i + kV0 + dd] + dt * a[kRec * i + kF + dd] * inv;
        }
    };
    for (int f = 0; f < 2 * D; ++f)
        if (sim.sc_.faces[static_cast<std::size_t>(f)].type != FaceType::free)
            for (std::uint32_t i : face_nodes[static_cast<std::size_t>(f)])
                redo(i);
    for (const auto &nodes_k : prescribed_nodes)
        for (std::uint32_t i : nodes_k)
            redo(i);
    apply_bc(v, kV1, t + dt);
}

// ---------------------------------------------------- material update --

namespace {} // namespace

// One plugin call for points [begin, begin + count) of set s, in place;
// a cut-step request is honoured by splitting the increment (strain, and F
// linearly between start and end) into ceil(1/factor) sub-increments.
void Simulation::Impl::call_material(ParticleSet &s, std::size_t begin, std::size_t count, double t,
                                     double dt, Scratch &scr, std::string &error,
                                     std::optional<FailedCall> &failed, int depth) {
    const std::size_t ns = s.state_size;
    scr.s0.assign(s.stress.begin() + static_cast<std::ptrdiff_t>(6 * begin),
                  s.stress.begin() + static_cast<std::ptrdiff_t>(6 * (begin + count)));
    scr.q0.assign(s.state.begin() + static_cast<std::ptrdiff_t>(ns * begin),
                  s.state.begin() + static_cast<std::ptrdiff_t>(ns * (begin + count)));
    talus_batch b{};
    b.flags = TALUS_BATCH_WANT_WAVE_SPEED;
    b.n_points = count;
    b.time = t;
    b.dt = dt;
    b.strain_increment = &s.de[6 * begin];
    b.F_start = &s.F[9 * begin];
    b.F_end = &s.F_new[9 * begin];
    b.density = &s.rho[begin];
    b.stress_start = &s.stress[6 * begin];
    b.stress_end = &s.stress[6 * begin];
    b.state_start = ns ? &s.state[ns * begin] : nullptr;
    b.state_end = ns ? &s.state[ns * begin] : nullptr;
    b.wave_speed = &s.c[begin];
    const Scenario &sc = sim.sc_;
    const auto &mat = sc.materials[s.material];
    // Whom to blame if the plugin crashes (crash_report.hpp).
    const crash::Task task{mat.name.c_str(),
                           sc.groups[static_cast<std::size_t>(s.group[begin])].name.c_str(),
                           initial_state ? 0 : sim.step_ + 1, s.id[begin], s.id[begin + count - 1]};
    const crash::TaskScope blame(&task);
    const MaterialInstance::Result r = s.instance->update(b);
    if (r.ok()) return;
    if (r.status == TALUS_STATUS_CUT_STEP && depth < 8) {
        // Restore the inputs and sub-step this batch.
        std::copy(scr.s0.begin(), scr.s0.end(),
                  s.stress.begin() + static_cast<std::ptrdiff_t>(6 * begin));
        std::copy(scr.q0.begin(), scr.q0.end(),
                  s.state.begin() + static_cast<std::ptrdiff_t>(ns * begin));
        const int k = std::max(2, static_cast<int>(std::ceil(1.0 / r.cut_factor)));
        std::vector<double> de(s.de.begin() + static_cast<std::ptrdiff_t>(6 * begin),
                               s.de.begin() + static_cast<std::ptrdiff_t>(6 * (begin + count)));
        std::vector<double> Fa(s.F.begin() + static_cast<std::ptrdiff_t>(9 * begin),
                               s.F.begin() + static_cast<std::ptrdiff_t>(9 * (begin + count)));
        std::vector<double> Fb(s.F_new.begin() + static_cast<std::ptrdiff_t>(9 * begin),
                               s.F_new.begin() + static_cast<std::ptrdiff_t>(9 * (begin + count)));
        std::vector<double> rho(s.rho.begin() + static_cast<std::ptrdiff_t>(begin),
                                s.rho.begin() + static_cast<std::ptrdiff_t>(begin + count));
        for (int j = 1; j <= k; ++j) {
            const double a0 = static_cast<double>(j - 1) / k, a1 = static_cast<double>(j) / k;
            for (std::size_t p = 0; p < count; ++p) {
                for (int c = 0; c < 6; ++c)
                    s.de[6 * (begin + p) + static_cast<std::size_t>(c)] =
                        de[6 * p + static_cast<std::size_t>(c)] / k;
                Eigen::Map<Eigen::Matrix<double, 3, 3, Eigen::RowMajor>> F0(&s.F[9 * (begin + p)]),
                    F1(&s.F_new[9 * (begin + p)]);
                const Eigen::Map<const Eigen::Matrix<double, 3, 3, Eigen::RowMajor>> A(&Fa[9 * p]),
                    B(&Fb[9 * p]);
                F0 = A + a0 * (B - A);
                F1 = A + a1 * (B - A);
                s.rho[begin + p] = s.rho0 / F1.determinant();
            }
            call_material(s, begin, count, t + a0 * dt, dt / k, scr, error, failed, depth + 1);
            if (!error.empty()) return;
        }
        // Leave F, F_new, de and rho as they were for the caller.
        std::copy(de.begin(), de.end(), s.de.begin() + static_cast<std::ptrdiff_t>(6 * begin));
        std::copy(Fa.begin(), Fa.end(), s.F.begin() + static_cast<std::ptrdiff_t>(9 * begin));
        std::copy(Fb.begin(), Fb.end(), s.F_new.begin() + static_cast<std::ptrdiff_t>(9 * begin));
        std::copy(rho.begin(), rho.end(), s.rho.begin() + static_cast<std::ptrdiff_t>(begin));
#pragma omp atomic
        ++sim.cut_steps_;
        return;
    }
    const std::size_t p = begin + static_cast<std::size_t>(std::max<std::int64_t>(0, r.point));
    if (r.point >= 0 && static_cast<std::size_t>(r.point) < count) {
        // The failing point's inputs: stress and state from the copies made
        // before the call (the plugin may have written over them), the rest
        // unchanged inputs.
        FailedCall fc;
        fc.material = s.material;
        fc.particle = s.id[p];
        fc.step = initial_state ? 0 : sim.step_ + 1;
        fc.time = t;
        fc.dt = dt;
        fc.density = s.rho[p];
        const std::size_t k = p - begin;
        for (std::size_t c = 0; c < 6; ++c) {
            fc.strain_increment[c] = s.de[6 * p + c];
            fc.stress[c] = scr.s0[6 * k + c];
        }
        for (std::size_t c = 0; c < 9; ++c) {
            fc.F_start[c] = s.F[9 * p + c];
            fc.F_end[c] = s.F_new[9 * p + c];
        }
        fc.state.assign(scr.q0.begin() + static_cast<std::ptrdiff_t>(ns * k),
                        scr.q0.begin() + static_cast<std::ptrdiff_t>(ns * (k + 1)));
        fc.cut_step = r.status == TALUS_STATUS_CUT_STEP;
        fc.message = r.message;
        failed = std::move(fc);
    }
    const std::string where =
        r.point >= 0
            ? fmt::format("particle {} of group '{}' at ({:.6g}, {:.6g}{})", s.id[p],
                          sc.groups[static_cast<std::size_t>(s.group[p])].name, s.x[0][p],
                          s.x[1][p], dim == 3 ? fmt::format(", {:.6g}", s.x[2][p]) : std::string())
            : fmt::format("a batch of {} particles", count);
    error = fmt::format(
        "step {} (t = {:.6g} s): material '{}' (model '{}', {}) failed at {}: {}{}", sim.step_ + 1,
        t, mat.name, mat.spec.model->id(), mat.spec.model->library().path().string(), where,
        r.message,
        r.status == TALUS_STATUS_CUT_STEP ? " (still asking for a smaller step after 8 cuts)" : "");
}

// Phase 3, kinematics: F (eq. 39), J, volume and density (eqs. 40-41), the
// strain increment (eq. 42) with the optional cell-averaged dilation (eqs.
// 47-53), the objective rotation of the start stress, then the material.
void Simulation::Impl::kinematics_and_update(double dt, double t) {
    auto tm = time_phase(5);
    auto &sets = sim.sets_;
    const bool cad = sim.sc_.solver.cell_averaged_dilation;
    std::string error;
    std::mutex error_mutex;
    for (auto &s : sets) {
        if (kinematics_done) break; // done inside G2P (see g2p_motion_pass)
        const std::ptrdiff_t n = static_cast<std::ptrdiff_t>(s.n);
#pragma omp parallel for schedule(static)
        for (std::ptrdiff_t pp = 0; pp < n; ++pp) {
            const std::size_t p = static_cast<std::size_t>(pp);
            if (!kinematics_point<3>(s, p, &s.L[9 * p], dt, dim, cad)) {
                std::lock_guard<std::mutex> lock(error_mutex);
                if (error.empty()) error = inversion_message(s, p, t);
            }
        }
    }
    if (kinematics_done && inverted_set >= 0)
        error =
            inversion_message(sets[static_cast<std::size_t>(inverted_set)], inverted_particle, t);
    kinematics_done = false;
    if (!error.empty()) throw Error(error);

    if (cad) {
        // Volume-weighted mean of div v over the points in each cell (eq. 53;
        // the cell is the one containing the point), then eq. 52 on the
        // normal strain increments of the dim in-plane directions.
        std::fill(cell_div.begin(), cell_div.end(), 0.0);
        std::fill(cell_vol.begin(), cell_vol.end(), 0.0);
        for (auto &s : sets)
            for (std::size_t p = 0; p < s.n; ++p) {
                const std::size_t c = cell_index(s, p);
                const double V = s.J[p] * s.vol0[p];
                cell_div[c] += s.divv[p] * V;
                cell_vol[c] += V;
            }
        for (auto &s : sets) {
            const std::ptrdiff_t n = static_cast<std::ptrdiff_t>(s.n);
#pragma omp parallel for schedule(static)
            for (std::ptrdiff_t pp = 0; pp < n; ++pp) {
                const std::size_t p = static_cast<std::size_t>(pp);
                const std::size_t c = cell_index(s, p);
                const double corr = dt * (cell_div[c] / cell_vol[c] - s.divv[p]) / dim;
                for (int d = 0; d < dim; ++d)
                    s.de[6 * p + static_cast<std::size_t>(d)] += corr;
            }
        }
    }

    // Stress work, trapezoidal: half with the (rotated) start stress (above,
    // or here once the dilation is averaged), half with the end stress.
    for (auto &s : sets) {
        if (cad) {
            const std::ptrdiff_t n = static_cast<std::ptrdiff_t>(s.n);
#pragma omp parallel for schedule(static)
            for (std::ptrdiff_t pp = 0; pp < n; ++pp) {
                const std::size_t p = static_cast<std::size_t>(pp);
                s.work[p] += 0.5 * s.J[p] * s.vol0[p] * stress_work(&s.stress[6 * p], &s.de[6 * p]);
            }
        }
        const std::size_t B = static_cast<std::size_t>(sim.opt_.batch_size);
        const std::ptrdiff_t nb = static_cast<std::ptrdiff_t>((s.n + B - 1) / B);
#ifdef _OPENMP
        // One scratch per thread; the thread count may have changed since
        // set-up (omp_set_num_threads between steps).
        if (scratch.size() < static_cast<std::size_t>(omp_get_max_threads()))
            scratch.resize(static_cast<std::size_t>(omp_get_max_threads()));
#endif
#pragma omp parallel for schedule(dynamic, 4)
        for (std::ptrdiff_t bb = 0; bb < nb; ++bb) {
            std::string local;
            std::optional<FailedCall> local_failed;
#ifdef _OPENMP
            Scratch &scr = scratch[static_cast<std::size_t>(omp_get_thread_num())];
#else
            Scratch &scr = scratch[0];
#endif
            const std::size_t begin = static_cast<std::size_t>(bb) * B;
            const std::size_t count = std::min(B, s.n - begin);
            call_material(s, begin, count, t, dt, scr, local, local_failed, 0);
            for (std::size_t p = begin; p < begin + count; ++p)
                s.work[p] += 0.5 * s.J[p] * s.vol0[p] * stress_work(&s.stress[6 * p], &s.de[6 * p]);
            if (!local.empty()) {
                std::lock_guard<std::mutex> lock(error_mutex);
                if (error.empty()) {
                    error = local;
                    sim.failed_call_ = std::move(local_failed);
                }
            }
        }
        if (!error.empty()) throw Error(error);
        s.F.swap(s.F_new);
    }
}

void Simulation::Impl::finish_step() {
    const Scenario &sc = sim.sc_;
    double speed = 0.0, disorder = 0.0;
    long outside = 0, moved = 0, held = 0;
    double depth = 0.0;
    slab_index.resize(sim.sets_.size());
    for (std::size_t si = 0; si < sim.sets_.size(); ++si) {
        ParticleSet &s = sim.sets_[si];
        auto &slab = slab_index[si];
        if (slab.size() != s.n) {
            slab.assign(s.n, -1);
            ++moved;
        }
        cell_of.resize(sim.sets_.size());
        auto &cell = cell_of[si];
        cell.resize(s.n);
        const std::ptrdiff_t n = static_cast<std::ptrdiff_t>(s.n);
        const int D = dim;
        // A closed face is impenetrable: the grid's normal velocity at it is
        // zero (clamped basis), so the motion computed from the grid cannot
        // carry a particle through it by more than the round-off of the
        // position sum (or a step above the stability limit); what does is
        // put back onto the face (and counted), so that "outside" means
        // through a free face only.
        double lo[3], hi[3];
        bool hold_lo[3] = {false, false, false}, hold_hi[3] = {false, false, false};
        for (int d = 0; d < D; ++d) {
            const std::size_t dd = static_cast<std::size_t>(d);
            lo[d] = origin[dd];
            hi[d] = origin[dd] + sc.size[dd];
            hold_lo[d] = sc.faces[2 * dd].type != FaceType::free;
            hold_hi[d] = sc.faces[2 * dd + 1].type != FaceType::free;
        }
#pragma omp parallel for schedule(static) reduction(max : speed, depth) reduction(+ : outside, moved, held)
        for (std::ptrdiff_t pp = 0; pp < n; ++pp) {
            const std::size_t p = static_cast<std::size_t>(pp);
            bool in = true;
            double v2 = 0.0;
            for (int d = 0; d < D; ++d) {
                const std::size_t dd = static_cast<std::size_t>(d);
                double x = positions_applied ? s.x[dd][p] : s.x[dd][p] + s.dx[dd][p];
                if (hold_lo[d] && x < lo[d]) {
                    depth = std::max(depth, lo[d] - x);
                    x = lo[d];
                    ++held;
                } else if (hold_hi[d] && x > hi[d]) {
                    depth = std::max(depth, x - hi[d]);
                    x = hi[d];
                    ++held;
                }
                s.x[dd][p] = x;
                in = in && x >= lo[d] && x <= hi[d];
                v2 += s.v[dd][p] * s.v[dd][p];
            }
            outside += in ? 0 : 1;
            speed = std::max(speed, s.c[p] + std::sqrt(v2));
            // The cell, and from it the slab, with one floor per axis.
            std::size_t ci = 0, stride = 1;
            int sl = 0;
            for (int d = 0; d < D; ++d) {
                const std::size_t dd = static_cast<std::size_t>(d);
                const int c =
                    std::clamp(static_cast<int>(fast_floor((s.x[dd][p] - origin[dd]) * inv_h)), 0,
                               cells[dd] - 1);
                ci += static_cast<std::size_t>(c) * stride;
                stride *= static_cast<std::size_t>(cells[dd]);
                if (d == slab_axis) sl = std::min(c / slab_width, n_slabs - 1);
            }
            moved += sl != slab[p] ? 1 : 0;
            slab[p] = sl;
            cell[p] = static_cast<std::uint32_t>(ci);
        }
        long descents = 0;
#pragma omp parallel for schedule(static) reduction(+ : descents)
        for (std::ptrdiff_t pp = 1; pp < n; ++pp)
            descents +=
                cell[static_cast<std::size_t>(pp)] < cell[static_cast<std::size_t>(pp) - 1] ? 1 : 0;
        disorder += static_cast<double>(descents);
    }
    max_speed = speed;
    out_of_order = disorder;
    sim.held_at_faces_ += held;
    sim.held_depth_ = std::max(sim.held_depth_, depth);
    positions_applied = false;
    slabs_changed = moved > 0;
    if (outside > 0) remove_or_report_leaving();
}

// Particles outside the domain (seed-independent policy): stop with a report
// naming them, or remove and count them.
void Simulation::Impl::remove_or_report_leaving() {
    const Scenario &sc = sim.sc_;
    std::vector<std::string> report;
    std::size_t outside = 0;
    for (auto &s : sim.sets_) {
        std::size_t keep = 0;
        for (std::size_t p = 0; p < s.n; ++p) {
            bool in = true;
            for (int d = 0; d < dim; ++d) {
                const std::size_t dd = static_cast<std::size_t>(d);
                const double x = s.x[dd][p];
                in = in && x >= origin[dd] && x <= origin[dd] + sc.size[dd] && std::isfinite(x);
            }
            if (in) {
                s.move(p, keep++);
                continue;
            }
            ++outside;
            if (report.size() < 10)
                report.push_back(fmt::format(
                    "particle {} of group '{}' at ({:.6g}, {:.6g}{})", s.id[p],
                    sc.groups[static_cast<std::size_t>(s.group[p])].name, s.x[0][p], s.x[1][p],
                    dim == 3 ? fmt::format(", {:.6g}", s.x[2][p]) : std::string()));
            if (sc.solver.leave == LeavePolicy::stop) s.move(p, keep++); // keep for the report
        }
        if (sc.solver.leave == LeavePolicy::remove) s.resize(keep);
    }
    for (auto &sl : slab_index)
        sl.clear(); // indices moved: recompute
    slabs_changed = true;
    if (outside == 0) return;
    if (sc.solver.leave == LeavePolicy::remove) {
        sim.removed_ += static_cast<long>(outside);
        return;
    }
    std::string list;
    for (const auto &r : report)
        list += "\n  " + r;
    throw Error(fmt::format("step {} (t = {:.6g} s): {} particle(s) left the grid (policy "
                            "solver.leaving_grid: stop; use 'remove' to delete them instead):{}{}",
                            sim.step_, sim.time_, outside, list,
                            outside > report.size()
                                ? fmt::format("\n  ... and {} more", outside - report.size())
                                : std::string()));
}

// ------------------------------------------------------------ Simulation --

Simulation::Simulation(Scenario &scenario, SolverOptions options)
    : sc_(scenario), opt_(options), impl_(std::make_unique<Impl>(*this)) {
#ifdef _OPENMP
    if (opt_.threads > 0) omp_set_num_threads(opt_.threads);
#endif
    if (sc_.loads.size() > kMaxLoads || sc_.particle_velocities.size() > kMaxLoads)
        throw Error(fmt::format("{}: at most {} loads and {} particle_velocities entries", sc_.file,
                                kMaxLoads, kMaxLoads));
    impl_->setup_grid();
    Impl &g = *impl_;
    const int D = sc_.dim;
    for (const GroupSpec &gs : sc_.groups)
        g.group_area.push_back(std::pow(sc_.cell / gs.particles_per_cell, D - 1));

    // One particle set per material used by some group.
    std::vector<int> set_of(sc_.materials.size(), -1);
    std::int64_t next_id = 0;
    for (std::size_t gi = 0; gi < sc_.groups.size(); ++gi) {
        const GroupSpec &gs = sc_.groups[gi];
        if (set_of[gs.material] < 0) {
            set_of[gs.material] = static_cast<int>(sets_.size());
            ParticleSet s;
            const NamedMaterial &m = sc_.materials[gs.material];
            s.material = gs.material;
            s.instance = m.instance.get();
            s.finite_strain = m.spec.model->finite_strain();
            s.state_size = m.spec.model->state_size();
            s.rho0 = m.spec.density;
            s.dim = sc_.dim;
            s.has_C = sc_.solver.transfer != Transfer::flip;
            s.has_divv = sc_.solver.cell_averaged_dilation;
            s.has_L = !fused_usl(sc_.solver);
            s.has_dx = s.has_L;
            sets_.push_back(std::move(s));
        }
        ParticleSet &s = sets_[static_cast<std::size_t>(set_of[gs.material])];
        const NamedMaterial &m = sc_.materials[gs.material];
        // Particles on a regular sub-lattice of each cell (ppc per direction),
        // kept where the shape contains them.
        const Box bb = gs.shape.bounds(D);
        const int ppc = gs.particles_per_cell;
        const double sub = sc_.cell / ppc;
        std::array<int, 3> lo{0, 0, 0}, hi{0, 0, 0};
        for (int d = 0; d < D; ++d) {
            const std::size_t dd = static_cast<std::size_t>(d);
            lo[dd] = static_cast<int>(std::floor((bb.min[dd] - g.origin[dd]) / sub)) - 1;
            hi[dd] = static_cast<int>(std::ceil((bb.max[dd] - g.origin[dd]) / sub)) + 1;
        }
        const double V0 = std::pow(sub, D);
        const double centre[3] = {0.5 * (bb.min[0] + bb.max[0]), 0.5 * (bb.min[1] + bb.max[1]),
                                  0.5 * (bb.min[2] + bb.max[2])};
        double surface = -std::numeric_limits<double>::infinity();
        if (gs.stress.kind == InitialStress::Kind::geostatic) {
            surface = gs.stress.surface.value_or(bb.max[static_cast<std::size_t>(D - 1)]);
            if (!(sc_.gravity[static_cast<std::size_t>(D - 1)] < 0.0))
                throw Error(gs.stress_origin.error(
                    fmt::format("a geostatic initial stress needs gravity pointing down the last "
                                "axis ({}), got {:g} m/s^2 (set gravity:)",
                                D == 2 ? "y" : "z", sc_.gravity[static_cast<std::size_t>(D - 1)])));
        }
        const std::vector<double> q_init = m.spec.initial_state;
        std::size_t made = 0;
        for (int k = (D == 3 ? lo[2] : 0); k < (D == 3 ? hi[2] : 1); ++k)
            for (int j = lo[1]; j < hi[1]; ++j)
                for (int i = lo[0]; i < hi[0]; ++i) {
                    double x[3] = {g.origin[0] + (i + 0.5) * sub, g.origin[1] + (j + 0.5) * sub,
                                   D == 3 ? g.origin[2] + (k + 0.5) * sub : 0.0};
                    if (!gs.shape.contains(x, D)) continue;
                    for (int d = 0; d < D; ++d) {
                        const std::size_t dd = static_cast<std::size_t>(d);
                        if (x[d] < g.origin[dd] || x[d] > g.origin[dd] + sc_.size[dd])
                            throw Error(gs.shape_origin.error(fmt::format(
                                "group '{}' has particles outside the grid (at {} = {:.6g} m; "
                                "the grid spans [{:.6g}, {:.6g}] m); enlarge grid.size or move "
                                "the shape",
                                gs.name, "xyz"[d], x[d], g.origin[dd],
                                g.origin[dd] + sc_.size[dd])));
                    }
                    const std::size_t p = s.n;
                    s.resize(p + 1);
                    s.id[p] = next_id++;
                    s.group[p] = static_cast<std::int32_t>(gi);
                    // v = v0 + w x (x - centre): a rigid motion.
                    const Vec3 &w = gs.angular_velocity;
                    const double r[3] = {x[0] - centre[0], x[1] - centre[1],
                                         D == 3 ? x[2] - centre[2] : 0.0};
                    const double wxr[3] = {w[1] * r[2] - w[2] * r[1], w[2] * r[0] - w[0] * r[2],
                                           w[0] * r[1] - w[1] * r[0]};
                    for (int d = 0; d < D; ++d) {
                        const std::size_t dd = static_cast<std::size_t>(d);
                        s.x[dd][p] = s.x0[dd][p] = x[d];
                        s.v[dd][p] = gs.velocity[dd] + wxr[d];
                        if (s.has_dx) s.dx[dd][p] = 0.0;
                    }
                    s.vol0[p] = V0;
                    s.mass[p] = s.rho0 * V0;
                    s.lp[p] = 0.5 / ppc;
                    for (int a = 0; a < 9; ++a)
                        s.F[9 * p + static_cast<std::size_t>(a)] =
                            s.F_new[9 * p + static_cast<std::size_t>(a)] = (a % 4 == 0) ? 1.0 : 0.0;
                    s.J[p] = 1.0;
                    s.rho[p] = s.rho0;
                    double *sig = &s.stress[6 * p];
                    std::fill_n(sig, 6, 0.0);
                    if (gs.stress.kind == InitialStress::Kind::uniform)
                        std::copy_n(gs.stress.uniform.begin(), 6, sig);
                    if (gs.stress.kind == InitialStress::Kind::geostatic) {
                        // sigma_v = rho g (surface - depth coordinate), tension
                        // positive; the horizontal stresses are K0 sigma_v.
                        const double sv = s.rho0 * sc_.gravity[static_cast<std::size_t>(D - 1)] *
                                          std::max(0.0, surface - x[D - 1]);
                        for (int d = 0; d < 3; ++d)
                            sig[d] = d == D - 1 ? sv : gs.stress.k0 * sv;
                    }
                    std::copy(q_init.begin(), q_init.end(),
                              s.state.begin() + static_cast<std::ptrdiff_t>(p * s.state_size));
                    std::fill_n(&s.de[6 * p], 6, 0.0);
                    if (s.has_L) std::fill_n(&s.L[9 * p], 9, 0.0);
                    if (s.has_C) {
                        // The affine transfers start from the rigid motion's
                        // exact velocity gradient, skew(w).
                        double *C = &s.C[9 * p];
                        std::fill_n(C, 9, 0.0);
                        C[1] = -w[2];
                        C[2] = w[1];
                        C[3] = w[2];
                        C[5] = -w[0];
                        C[6] = -w[1];
                        C[7] = w[0];
                    }
                    s.work[p] = 0.0;
                    if (s.has_divv) s.divv[p] = 0.0;
                    std::uint32_t lm = 0, fm = 0;
                    for (std::size_t l = 0; l < sc_.loads.size(); ++l) {
                        const Load &ld = sc_.loads[l];
                        if ((!ld.group || *ld.group == gi) && (!ld.box || ld.box->contains(x, D)))
                            lm |= 1u << l;
                    }
                    for (std::size_t f = 0; f < sc_.particle_velocities.size(); ++f) {
                        const ParticleVelocity &pv = sc_.particle_velocities[f];
                        if ((!pv.group || *pv.group == gi) && (!pv.box || pv.box->contains(x, D)))
                            fm |= 1u << f;
                    }
                    s.load_mask[p] = lm;
                    s.fix_mask[p] = fm;
                    ++made;
                }
        if (made == 0)
            throw Error(gs.shape_origin.error(
                fmt::format("group '{}' contains no particle: its shape holds no point of the "
                            "{}-per-cell lattice (make it larger or raise particles_per_cell)",
                            gs.name, ppc)));
    }
    // A load or a fixity that acts on nothing is a mistake in its box or
    // group, not a no-op.
    auto selected = [&](std::size_t k, bool load) {
        for (const ParticleSet &s : sets_)
            for (std::size_t p = 0; p < s.n; ++p)
                if (((load ? s.load_mask[p] : s.fix_mask[p]) >> k) & 1u) return true;
        return false;
    };
    for (std::size_t k = 0; k < sc_.loads.size(); ++k)
        if (!selected(k, true))
            throw Error(sc_.loads[k].origin.error(
                "selects no particle (its box and group have no particle in common at t = 0)"));
    for (std::size_t k = 0; k < sc_.particle_velocities.size(); ++k)
        if (!selected(k, false))
            throw Error(sc_.particle_velocities[k].origin.error(
                "selects no particle (its box and group have no particle in common at t = 0)"));

    // The plugins see the initial state once (zero increment) and report
    // their wave speeds; a material that rejects its initial state stops here.
    impl_->initial_state = true;
    for (auto &s : sets_) {
        const std::size_t B = static_cast<std::size_t>(opt_.batch_size);
        std::string error;
        std::optional<FailedCall> failed; // the constructor throws: nobody to tell
        for (std::size_t begin = 0; begin < s.n && error.empty(); begin += B)
            impl_->call_material(s, begin, std::min(B, s.n - begin), 0.0, 0.0, impl_->scratch[0],
                                 error, failed, 0);
        if (!error.empty()) throw Error("initial state: " + error);
    }
    impl_->initial_state = false;
    impl_->sort_particles();
}

Simulation::~Simulation() = default;

ResourceEstimate estimate_resources(const Scenario &sc) {
    ResourceEstimate e;
    const int D = sc.dim;
    e.nodes = 1.0;
    double cells = 1.0;
    for (int d = 0; d < D; ++d) {
        const double n = std::round(sc.size[static_cast<std::size_t>(d)] / sc.cell);
        e.nodes *= n + 1 + 2 * kGhostLayers;
        cells *= n;
    }
    // Per node: the two 8-double records (acc, vel); per cell: the bins and
    // the cell-averaged dilation sums.
    e.bytes = e.nodes * 2 * 8 * 8 + cells * (4 + (sc.solver.cell_averaged_dilation ? 16 : 0));
    for (const GroupSpec &g : sc.groups) {
        const double n = g.shape.measure(D) / std::pow(sc.cell / g.particles_per_cell, D);
        e.particles += n;
        // The per-particle arrays of a set of this material, every optional
        // one counted (for_each_array, the list resize() uses), then id,
        // group, the two masks and the sort's index and cell arrays.
        ParticleSet probe;
        probe.dim = D;
        probe.state_size = sc.materials[g.material].spec.model->state_size();
        std::size_t doubles = 0;
        for_each_array(probe, [&](auto &, std::size_t stride) { doubles += stride; });
        e.bytes += n * (static_cast<double>(doubles) * 8 + 8 + 4 + 8 + 16);
    }
    return e;
}

std::size_t Simulation::particle_count() const {
    std::size_t n = 0;
    for (const auto &s : sets_)
        n += s.n;
    return n;
}

double Simulation::critical_dt() const {
    double worst = 0.0;
    for (const auto &s : sets_) {
        const std::ptrdiff_t n = static_cast<std::ptrdiff_t>(s.n);
        double local = 0.0;
#pragma omp parallel for reduction(max : local) schedule(static)
        for (std::ptrdiff_t pp = 0; pp < n; ++pp) {
            const std::size_t p = static_cast<std::size_t>(pp);
            double v2 = 0.0;
            for (int d = 0; d < sc_.dim; ++d)
                v2 += s.v[static_cast<std::size_t>(d)][p] * s.v[static_cast<std::size_t>(d)][p];
            local = std::max(local, s.c[p] + std::sqrt(v2));
        }
        worst = std::max(worst, local);
    }
    return worst > 0.0 ? sc_.solver.cfl * sc_.cell / worst
                       : std::numeric_limits<double>::infinity();
}

void Simulation::check_fixed_dt(double dt_crit) const {
    if (sc_.solver.dt && *sc_.solver.dt > dt_crit / sc_.solver.cfl)
        throw Error(sc_.solver.dt_origin.error(fmt::format(
            "{}: the fixed dt {:.4g} s is above the stability limit h / max(c + |v|) = {:.4g} s, "
            "where the explicit step is unstable; lower solver.dt below cfl times that "
            "({:.4g} s), or remove it to let cfl choose each step",
            step_ == 0 ? std::string("at t = 0")
                       : fmt::format("step {} (t = {:.6g} s)", step_ + 1, time_),
            *sc_.solver.dt, dt_crit / sc_.solver.cfl, dt_crit)));
}

void Simulation::step(double max_dt) {
    Impl &g = *impl_;
    double dt_crit = 0.0;
    {
        auto tm = g.time_phase(0);
        // max(c + |v|) comes from the last pass of the previous step.
        dt_crit = g.max_speed >= 0.0 ? (g.max_speed > 0.0 ? sc_.solver.cfl * sc_.cell / g.max_speed
                                                          : std::numeric_limits<double>::infinity())
                                     : critical_dt();
    }
    double dt = dt_crit;
    if (sc_.solver.dt) {
        dt = *sc_.solver.dt;
        // Above h / max(c + |v|) (a Courant number of 1) the explicit step
        // is unstable and the result is noise: refuse. Between the cfl
        // margin and that it is the user's call: warn once.
        check_fixed_dt(dt_crit);
        if (dt > dt_crit && !warned_dt_) {
            warned_dt_ = true;
            warnings_.push_back(
                fmt::format("step {} (t = {:.6g} s): the fixed dt {:.4g} s exceeds cfl h / "
                            "max(c + |v|) = {:.4g} s (below the stability limit, without the cfl "
                            "margin)",
                            step_ + 1, time_, dt, dt_crit));
        }
    }
    dt = std::min(dt, max_dt);
    if (!(dt > 0.0))
        throw Error(fmt::format("step {}: time step {} is not positive", step_ + 1, dt));
    const double t = time_;
    g.evaluate_time_functions(t, dt);

    {
        auto tm = g.time_phase(1);
        if (opt_.sort_disorder > 0.0 &&
            g.out_of_order > opt_.sort_disorder * static_cast<double>(particle_count()))
            g.sort_particles();
        g.bin_particles();
        g.reset_grid();
    }
    const Scheme scheme = sc_.solver.scheme;

    // Kinematic consistency: the particles move with the grid velocity
    // field whose gradient advances F (docs/theory.md), or with its mean
    // with the start velocities for a second-order position update.
    const bool trapezoid = trapezoid_positions(sc_.solver);
    double *a = g.acc.data();
    const double *v = g.vel.data();
    if (scheme == Scheme::usl || scheme == Scheme::musl) {
        {
            auto tm = g.time_phase(2);
            g.p2g(g, true, true, false, t);
        }
        {
            auto tm = g.time_phase(3);
            g.grid_velocities(dt, t, true);
        }
        {
            auto tm = g.time_phase(4);
            // USL without cell averaging does the kinematics inside G2P.
            const bool fuse = fused_usl(sc_.solver);
            g.g2p_motion(g, dt, scheme == Scheme::usl, fuse ? dt : 0.0);
        }
        if (scheme == Scheme::musl) {
            // Modified USL: the updated particle momentum is mapped again and
            // the velocity gradient taken from that field (Sulsky et al. 1995).
            // The particles move with it too, not with v~: moved by v~, they
            // drift away from what F records under a held load (a cantilever
            // creeps). The momentum slots hold the second-order mean.
            for (std::size_t i = 0; i < g.n_nodes; ++i)
                for (int d = 0; d < sc_.dim; ++d)
                    a[Impl::kRec * i + Impl::kP + static_cast<std::size_t>(d)] = 0.0;
            g.p2g(g, false, false, true, t);
            for (std::size_t i = 0; i < g.n_nodes; ++i) {
                const double m = a[Impl::kRec * i + Impl::kM];
                for (int d = 0; d < sc_.dim; ++d)
                    a[Impl::kRec * i + Impl::kF + static_cast<std::size_t>(d)] =
                        m > 0.0 ? a[Impl::kRec * i + Impl::kP + static_cast<std::size_t>(d)] / m
                                : 0.0;
            }
            g.apply_bc(a, Impl::kF, t + dt);
            if (trapezoid)
                for (std::size_t i = 0; i < g.n_nodes; ++i)
                    for (int d = 0; d < sc_.dim; ++d) {
                        const std::size_t k = Impl::kRec * i + static_cast<std::size_t>(d);
                        a[k + Impl::kP] = 0.5 * (v[k + Impl::kV0] + a[k + Impl::kF]);
                    }
            g.g2p_gradient(g, a, Impl::kF, trapezoid ? Impl::kP : Impl::kF, dt);
        }
        g.kinematics_and_update(dt, t);
    } else if (scheme == Scheme::usf) {
        // Update stress first: the velocity gradient from the mapped start
        // velocities, and the particles move with them; then forces from
        // the updated stress, grid update and the velocity G2P.
        g.p2g(g, true, false, false, t);
        g.grid_velocities(dt, t, false);
        g.g2p_gradient(g, v, Impl::kV0, Impl::kV0, dt);
        g.kinematics_and_update(dt, t);
        g.p2g(g, false, true, false, t);
        g.grid_velocities(dt, t, true);
        g.g2p_motion(g, dt, false, 0.0);
    } else { // USAVG: half the increment at each end of the step (Nairn 2003)
        g.p2g(g, true, false, false, t);
        g.grid_velocities(dt, t, false);
        g.g2p_gradient(g, v, Impl::kV0, 0, 0.0);
        g.kinematics_and_update(0.5 * dt, t);
        g.p2g(g, false, true, false, t);
        g.grid_velocities(dt, t, true);
        // F took half its step from v and takes half from v~: the particles
        // move with the mean of the two.
        g.g2p_motion(g, dt, true, 0.0);
        g.kinematics_and_update(0.5 * dt, t + 0.5 * dt);
    }
    auto tm = g.time_phase(6);
    time_ = t + dt;
    last_dt_ = dt;
    ++step_;
    g.finish_step();
}

std::array<double, Simulation::kPhases> Simulation::phase_seconds() const {
    return impl_->phase_seconds;
}

const char *Simulation::phase_name(int k) {
    static const char *names[kPhases] = {"time step",
                                         "sort and bin",
                                         "P2G",
                                         "grid update",
                                         "G2P",
                                         "kinematics and material",
                                         "positions and leaving check"};
    return names[k];
}

int Simulation::max_threads() {
#ifdef _OPENMP
    return omp_get_max_threads();
#else
    return 1;
#endif
}

double Simulation::grid_mass() const {
    double m = 0.0;
    for (std::size_t i = 0; i < impl_->n_nodes; ++i)
        m += impl_->acc[Impl::kRec * i + Impl::kM];
    return m;
}

Diagnostics Simulation::diagnostics() const {
    Diagnostics dg;
    dg.step = step_;
    dg.time = time_;
    dg.dt = last_dt_;
    dg.removed = removed_;
    dg.cut_steps = cut_steps_;
    dg.held_at_faces = held_at_faces_;
    dg.held_depth = held_depth_;
    const int D = sc_.dim;
    // The affine velocity field carries angular momentum too: for the
    // B-splines, sum_i x_i x p_i gains m eps:(C D_p) with D_p = h^2/4
    // (quadratic) or h^2/3 (cubic) away from the faces (Jiang et al. 2015).
    const bool affine = sc_.solver.transfer != Transfer::flip && impl_->apic_dinv > 0.0;
    for (const auto &s : sets_) {
        dg.particles += s.n;
        for (std::size_t p = 0; p < s.n; ++p) {
            const double m = s.mass[p];
            double v[3] = {0, 0, 0}, x[3] = {0, 0, 0};
            for (int d = 0; d < D; ++d) {
                v[d] = s.v[static_cast<std::size_t>(d)][p];
                x[d] = s.x[static_cast<std::size_t>(d)][p];
            }
            dg.mass += m;
            for (int d = 0; d < 3; ++d)
                dg.momentum[static_cast<std::size_t>(d)] += m * v[d];
            dg.kinetic_energy += 0.5 * m * (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]);
            dg.stress_work += s.work[p];
            static const double no_affine[9] = {};
            const double *C = s.has_C ? &s.C[9 * p] : no_affine;
            double Dp[3] = {0, 0, 0}; // D_p per axis (diagonal), m^2
            if (affine)
                for (int d = 0; d < D; ++d)
                    Dp[d] = impl_->affine_moment(d, x[d]);
            // sum_i x_i x m w_ip C (x_i - x_p) = x_p x m v_p + m eps_kab C_bc D_ac.
            dg.angular_momentum[2] +=
                m * (x[0] * v[1] - x[1] * v[0]) + m * (Dp[0] * C[3] - Dp[1] * C[1]);
            if (D == 3) {
                dg.angular_momentum[0] +=
                    m * (x[1] * v[2] - x[2] * v[1]) + m * (Dp[1] * C[7] - Dp[2] * C[5]);
                dg.angular_momentum[1] +=
                    m * (x[2] * v[0] - x[0] * v[2]) + m * (Dp[2] * C[2] - Dp[0] * C[6]);
            }
        }
    }
    return dg;
}

} // namespace talus
