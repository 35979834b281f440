// Mohr-Coulomb: linear elastic - perfectly plastic, non-associated (dilation
// angle psi <= friction angle phi), with a tension cut-off and optional
// linear softening of phi, psi and c with the accumulated plastic deviatoric
// strain.
//
// The return mapping is exact in principal stress space (principal_return.hpp,
// after Clausen, Damkilde & Andersen 2006, 2007): onto the shear plane, the
// triaxial compression and extension edges, the apex, the cut-off plane and
// the lines and points where the cut-off meets the shear planes.
//
// Softening is implicit: the strength used in the return is the one at the
// end of the increment, kappa_n+1 = kappa_n + d_kappa(kappa_n+1), a scalar
// equation solved by safeguarded regula falsi between kappa_n and a bound
// where it changes sign (see Softening below). The consistent tangent
// includes the coupling through kappa.
//
// A start stress outside the yield surface (only possible from a user's
// initial stress or another model's stress at a stage's set_material, both
// with yield_mode 0: every stress this model returns is admissible) is
// first projected onto the surface by the same return, at the start state's
// strength and without counting the projection as plastic strain; the
// increment then starts from the projected stress. A zero increment thus
// returns the projected stress.
//
// The host rotates sigma_start objectively before the call (the model is not
// TALUS_MODEL_FINITE_STRAIN); the model works on the strain increment.
#include "elastic_screen.hpp"
#include "plane_lanes.hpp"
#include "principal_return.hpp"

#include <talus/sdk/material.hpp>
#include <talus/sdk/spectral.hpp>
#include <talus/sdk/voigt.hpp>
#include <talus/sdk/wave_speed.hpp>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <numbers>
#include <optional>
#include <string>

namespace {

using talus::sdk::Mat3;
using talus::sdk::Mat6;
using talus::sdk::Vec6;
using talus_mc::Elastic;
using talus_mc::M3;
using talus_mc::Return;
using talus_mc::Strength;
using talus_mc::V3;

constexpr double kDeg = std::numbers::pi / 180.0;

#if defined(__GNUC__) || defined(__clang__)
#define TALUS_MC_INLINE [[gnu::always_inline]] inline
#else
#define TALUS_MC_INLINE inline
#endif

std::string fmt_g(double v) {
    char buf[64];
    std::snprintf(buf, sizeof buf, "%g", v);
    return buf;
}

using Spectral = talus::sdk::SymmetricEigen;

struct MohrCoulomb {
    static constexpr talus::sdk::ModelInfo info{
        .id = "mohr_coulomb",
        .name = "Mohr-Coulomb (elastic - perfectly plastic, tension cut-off, softening)",
        .version = "1.0.0",
        .doc = "Isotropic linear elasticity with the Mohr-Coulomb yield surface (1 + sin phi) s1 - "
               "(1 - sin phi) s3 = 2 c cos phi (s1 >= s2 >= s3 principal stresses, tension "
               "positive), non-associated flow with the dilation angle psi in the plastic "
               "potential, and a tension cut-off s1 <= T. Exact return mapping in principal "
               "stress space onto the planes, the triaxial compression and extension edges and "
               "the apex (Clausen, Damkilde & Andersen, Comput. Struct. 85 (2007) 1795-1807), "
               "with its consistent tangent. Optional linear softening of phi, psi and c "
               "between two values of the accumulated plastic deviatoric strain "
               "sqrt(2/3 e_p:e_p), solved implicitly. An initial stress outside the surface "
               "is projected onto it at set-up, without plastic strain, and each point moved "
               "is reported as a warning. Wave speed: "
               "the elastic P-wave speed sqrt((K + 4G/3) / rho).",
        .finite_strain = false,
        .tangent = true,
    };

    static constexpr std::array params{
        talus::sdk::real("youngs_modulus", "Pa", "Young's modulus E.")
            .required()
            .above(0.0)
            .typical(1.0e7),
        talus::sdk::real("poisson_ratio", "-", "Poisson's ratio nu.")
            .required()
            .above(-1.0)
            .below(0.5)
            .typical(0.3),
        talus::sdk::real("friction_angle", "deg", "Friction angle phi (peak when softening).")
            .required()
            .at_least(0.0)
            .below(90.0)
            .typical(30.0),
        talus::sdk::real("dilation_angle", "deg",
                         "Dilation angle psi of the plastic potential, at most phi; psi = phi is "
                         "associated flow.")
            .defaults_to(0.0)
            .at_least(0.0)
            .below(90.0)
            .typical(10.0),
        talus::sdk::real("cohesion", "Pa", "Cohesion c (peak when softening).")
            .defaults_to(0.0)
            .at_least(0.0)
            .typical(1.0e4),
        talus::sdk::real("tension_cutoff", "Pa",
                         "Tensile strength T: the largest principal stress stays <= T. A value "
                         "beyond the apex c cot phi can never be reached and has no effect.")
            .defaults_to(0.0)
            .at_least(0.0)
            .typical(5.0e3),
        talus::sdk::boolean("softening",
                            "Soften phi, psi and c linearly with the plastic deviatoric strain "
                            "between softening_start and softening_end.")
            .defaults_to(0.0)
            .typical(1.0),
        talus::sdk::real("residual_friction_angle", "deg",
                         "Friction angle reached at softening_end (with softening).")
            .defaults_to(0.0)
            .at_least(0.0)
            .below(90.0)
            .typical(25.0),
        talus::sdk::real("residual_dilation_angle", "deg",
                         "Dilation angle reached at softening_end (with softening), at most the "
                         "residual friction angle.")
            .defaults_to(0.0)
            .at_least(0.0)
            .below(90.0)
            .typical(0.0),
        talus::sdk::real("residual_cohesion", "Pa",
                         "Cohesion reached at softening_end (with softening).")
            .defaults_to(0.0)
            .at_least(0.0)
            .typical(2.0e3),
        talus::sdk::real("softening_start", "-",
                         "Plastic deviatoric strain at which softening starts (with softening).")
            .defaults_to(0.0)
            .at_least(0.0)
            .typical(0.0),
        talus::sdk::real("softening_end", "-",
                         "Plastic deviatoric strain at which the residual values are reached "
                         "(with softening); greater than softening_start.")
            .defaults_to(0.0)
            .at_least(0.0)
            .typical(1.0e-3),
    };

    static constexpr std::array state{
        talus::sdk::state_variable("plastic_deviatoric_strain", "-",
                                   "Accumulated equivalent plastic deviatoric strain, the sum of "
                                   "sqrt(2/3 de_p:de_p) over the increments; drives softening.")
            .output()
            .user_initialisable(),
        talus::sdk::state_variable("plastic_volumetric_strain", "-",
                                   "Accumulated plastic volumetric strain tr(e_p), positive in "
                                   "dilation.")
            .output(),
        talus::sdk::state_variable(
            "yield_mode", "-",
            "Where the stress is: 0 inside the yield surface, otherwise "
            "the part of the surface the last return put it on: 1 shear "
            "plane, 2 triaxial compression edge, 3 triaxial extension edge, 4 apex, 5 "
            "tension plane, 6 tension edge, 7 tension apex, 8 shear-tension "
            "line, 9 shear-tension corner (compression), 10 shear-tension "
            "corner (extension).")
            .output(),
    };

    explicit MohrCoulomb(const talus::sdk::ParamValues &p) {
        const double E = p["youngs_modulus"];
        const double nu = p["poisson_ratio"];
        el_.shear = E / (2.0 * (1.0 + nu));
        el_.lambda = E * nu / ((1.0 + nu) * (1.0 - 2.0 * nu));
        De_.setZero();
        for (int i = 0; i < 3; ++i) {
            for (int j = 0; j < 3; ++j)
                De_(i, j) = el_.lambda;
            De_(i, i) = el_.lambda + 2.0 * el_.shear;
            De_(i + 3, i + 3) = el_.shear; // engineering shear strain in
        }
        phi_ = p["friction_angle"];
        psi_ = p["dilation_angle"];
        c_ = p["cohesion"];
        tension_ = p["tension_cutoff"];
        softening_ = p["softening"] != 0.0;
        phi_r_ = p["residual_friction_angle"];
        psi_r_ = p["residual_dilation_angle"];
        c_r_ = p["residual_cohesion"];
        k0_ = p["softening_start"];
        k1_ = p["softening_end"];
        if (psi_ > phi_)
            throw talus::sdk::Failure("dilation_angle (" + fmt_g(psi_) +
                                      " deg) exceeds friction_angle (" + fmt_g(phi_) +
                                      " deg): the plastic work would be negative; use psi <= phi");
        if (softening_) {
            if (!(k1_ > k0_))
                throw talus::sdk::Failure("softening_end (" + fmt_g(k1_) +
                                          ") must be greater than softening_start (" + fmt_g(k0_) +
                                          ") when softening is on");
            if (psi_r_ > phi_r_)
                throw talus::sdk::Failure("residual_dilation_angle (" + fmt_g(psi_r_) +
                                          " deg) exceeds residual_friction_angle (" +
                                          fmt_g(phi_r_) + " deg)");
            // The law softens: a residual above the peak would harden the
            // material with plastic strain, most often two values swapped.
            if (phi_r_ > phi_)
                throw talus::sdk::Failure("residual_friction_angle (" + fmt_g(phi_r_) +
                                          " deg) exceeds friction_angle (" + fmt_g(phi_) +
                                          " deg, the peak): softening lowers the strength to "
                                          "its residual; are the two swapped?");
            if (c_r_ > c_)
                throw talus::sdk::Failure("residual_cohesion (" + fmt_g(c_r_) +
                                          " Pa) exceeds cohesion (" + fmt_g(c_) +
                                          " Pa, the peak): softening lowers the strength to its "
                                          "residual; are the two swapped?");
        } else if (phi_r_ != 0.0 || psi_r_ != 0.0 || c_r_ != 0.0 || k0_ != 0.0 || k1_ != 0.0) {
            throw talus::sdk::Failure(
                "residual_friction_angle, residual_dilation_angle, residual_cohesion, "
                "softening_start and softening_end take effect only with softening: true; set "
                "it or remove them");
        }
        fixed_strength_ = strength_at(0.0);
        fixed_lode_bound_ = lode_bound(fixed_strength_);
        fixed_inv_lode_bound_ = 1.0 / fixed_lode_bound_;
        fixed_systems_.emplace(fixed_strength_, el_);
        screen_.lambda = el_.lambda;
        for (int i = 0; i < 6; ++i) {
            screen_.moduli[i] = i < 3 ? 2.0 * el_.shear : el_.shear;
            screen_.normal[i] = i < 3 ? 1.0 : 0.0;
        }
    }

    // The points of a chunk whose trial stress is clearly inside the
    // surface (clearly_elastic), finished in one loop without the SDK's
    // per-point set-up: most points of a batch
    // (bench/results/2026-11-25-mohr-coulomb-quick-pass-pairs-epyc-zen4.md).
    // The others, without softening or a tangent asked for, are finished by
    // the plane pass here too; else they go to update_group() and update().
    void quick_update(const talus::sdk::Points &p) const {
        std::size_t k = 0;
#if defined(TALUS_MC_HAS_QUAD_SCREEN)
        // Four points a vector where the processor has AVX2 and the
        // strength is the same for every point; the rest point by point.
        if (!softening_ && talus_mc::quad_screen_available())
            k = talus_mc::quad::screen_quads(screen_, fixed_strength_, fixed_lode_bound_,
                                             fixed_inv_lode_bound_, p.n, p.stress_start,
                                             p.strain_increment, p.stress_end, p.state_end,
                                             state.size(), p.done);
        if (p.tangent)
            for (std::size_t j = 0; j < k; ++j)
                if (p.done[j]) Eigen::Map<Mat6>(p.tangent + 36 * j) = De_; // symmetric
#endif
        for (; k < p.n; ++k) {
            Vec6 trial;
            if (!elastic_trial(Eigen::Map<const Vec6>(p.stress_start + 6 * k),
                               Eigen::Map<const Vec6>(p.strain_increment + 6 * k),
                               p.state_start[state.size() * k], trial))
                continue;
            Eigen::Map<Vec6>(p.stress_end + 6 * k) = trial;
            p.state_end[state.size() * k + 2] = talus_mc::kElastic;
            if (p.tangent) Eigen::Map<Mat6>(p.tangent + 36 * k) = De_; // symmetric
            p.done[k] = 1;
        }
        if (!softening_ && !p.tangent) plane_pass(p);
        // Every point's, as wave_speed() gives it (update() overwrites the
        // ones it takes), two points at a time.
        if (p.wave_speed) talus::sdk::wave_speeds(p_wave_modulus(), p.density, p.wave_speed, p.n);
    }

    // update() for up to eight points, their decompositions together
    // (eight a vector with AVX-512: symmetric_eigen_group).
    void update_group(const talus::sdk::PointIn *const *in, talus::sdk::PointOut *const *out,
                      std::size_t n) const {
        std::array<Vec6, talus::sdk::kGroupSize> trial;
        std::array<Mat3, talus::sdk::kGroupSize> m;
        std::array<Spectral, talus::sdk::kGroupSize> sp;
        for (std::size_t k = 0; k < n; ++k) {
            trial[k] = in[k]->stress + hooke(in[k]->strain_increment);
            m[k] = talus::sdk::stress_to_matrix(trial[k]);
        }
        talus::sdk::symmetric_eigen_group(m.data(), sp.data(), n);
        for (std::size_t k = 0; k < n; ++k)
            finish(*in[k], *out[k], trial[k], sp[k]);
    }

    void update(const talus::sdk::PointIn &in, talus::sdk::PointOut &out) const {
        Vec6 trial;
        if (elastic_trial(in.stress, in.strain_increment, in.state[0], trial)) {
            out.stress = trial;
            out.state[2] = talus_mc::kElastic;
            if (out.tangent) *out.tangent = De_;
            return;
        }
        finish(in, out, trial, talus::sdk::symmetric_eigen(talus::sdk::stress_to_matrix(trial)));
    }

    // The set-up call (ABI 1.1): the user's initial stress is returned to
    // the surface by update's projection (a zero increment returns the
    // projected stress, see the head of this file), and a stress that moved
    // is reported through the host's log, naming the particle and how far
    // it moved, rather than passing silently.
    void init_state(const talus::sdk::PointIn &in, talus::sdk::PointOut &out) const {
        update(in, out);
        const double moved = (out.stress - in.stress).cwiseAbs().maxCoeff();
        if (moved > 0.0) {
            char msg[200];
            std::snprintf(msg, sizeof msg,
                          "point %lld: the initial stress lies outside the yield surface; "
                          "returned to it (largest component change %.4g Pa)",
                          static_cast<long long>(in.point_id), moved);
            talus::sdk::log_warning(msg);
        }
    }

    double wave_speed(const talus::sdk::PointIn &in, const talus::sdk::PointOut &) const {
        return std::sqrt(p_wave_modulus() / in.density);
    }

  private:
    // yield_mode's values as stored.
    static constexpr double kElasticCode = talus_mc::kElastic;

    // The plane pass: the points the screen left, decomposed eight at a
    // time, finished here without the SDK's per-point set-up. Those whose
    // trial stress is admissible or returns onto the shear or the cut-off
    // plane (most of them,
    // bench/results/2026-11-28-mohr-coulomb-plane-pass-ice-lake.md) four a
    // vector (plane_lanes.hpp), the others by finish() with the same
    // decomposition. The vector form runs finish()'s operations through
    // the same functions, so a point gets the same bits on either path.
    // Without softening and a tangent only (else update_group()).
    void plane_pass(const talus::sdk::Points &p) const {
        std::array<std::uint32_t, talus::sdk::kEigenGroup> idx;
        std::size_t g = 0;
        for (std::size_t k = 0; k < p.n; ++k) {
            // Without a branch: where the screen's verdicts mix, one was
            // mispredicted at every change.
            idx[g] = static_cast<std::uint32_t>(k);
            g += p.done[k] == 0;
            if (g == idx.size()) {
                plane_group(p, idx.data(), g);
                g = 0;
            }
        }
        if (g > 0) plane_group(p, idx.data(), g);
    }

    void plane_group(const talus::sdk::Points &p, const std::uint32_t *idx, std::size_t g) const {
        std::array<Vec6, talus::sdk::kEigenGroup> trial;
        std::array<Mat3, talus::sdk::kEigenGroup> m;
        for (std::size_t j = 0; j < g; ++j) {
            const std::size_t k = idx[j];
            trial[j] = Eigen::Map<const Vec6>(p.stress_start + 6 * k) +
                       hooke(Eigen::Map<const Vec6>(p.strain_increment + 6 * k));
            m[j] = talus::sdk::stress_to_matrix(trial[j]);
        }
        talus_mc::PlaneLanes lanes;
        // The decompositions straight into the lanes (idle ones repeat the
        // last point's), not point by point through a SymmetricEigen.
        talus::sdk::symmetric_eigen_lanes(m.data(), g, lanes.trial);
        for (std::size_t lane = 0; lane < lanes.kLanes; ++lane) {
            // Idle lanes repeat the last point.
            const std::size_t j = std::min(lane, g - 1);
            const double *q0 = p.state_start + state.size() * idx[j];
            lanes.kappa[lane] = q0[0];
            lanes.vol[lane] = q0[1];
            lanes.last[lane] = q0[2];
        }
#if defined(TALUS_MC_HAS_PLANE_QUAD)
        if (talus_mc::quad::available()) {
            talus_mc::quad::plane_lanes(*fixed_systems_, fixed_strength_, el_, lanes, 0);
            if (g > 4) talus_mc::quad::plane_lanes(*fixed_systems_, fixed_strength_, el_, lanes, 4);
        } else
#endif
            talus_mc::plane_lanes_each(*fixed_systems_, fixed_strength_, el_, lanes, g);
        for (std::size_t j = 0; j < g; ++j) {
            const std::size_t k = idx[j];
            const double verdict = lanes.verdict[j];
            // finish() where neither plane takes the point, or a start
            // stress the model did not put on the surface may need its
            // projection before the return.
            if (verdict == 0.0 ||
                (verdict == 2.0 && lanes.last[j] == kElasticCode &&
                 !clearly_elastic(Eigen::Map<const Vec6>(p.stress_start + 6 * k), fixed_strength_,
                                  fixed_lode_bound_, fixed_inv_lode_bound_))) {
                Spectral sp;
                lanes.trial.get(j, sp);
                finish_at(p, k, trial[j], sp);
                continue;
            }
            double *se = p.stress_end + 6 * k;
            double *q1 = p.state_end + state.size() * k;
            if (verdict == 1.0) {
                Eigen::Map<Vec6> out(se);
                out = trial[j];
                q1[0] = lanes.kappa[j];
                q1[1] = lanes.vol[j];
            } else {
                for (int e = 0; e < 6; ++e)
                    se[e] = lanes.stress[e][j];
                q1[0] = lanes.kappa_end[j];
                q1[1] = lanes.vol_end[j];
            }
            q1[2] = lanes.mode_end[j];
            p.done[k] = 1;
        }
    }

    // finish() on point k of a chunk, in place of update(): its start
    // stress and state copied first (the end arrays may be the start
    // ones), the end state already a copy of the start one (Points).
    // finish() reads neither F nor the context a Points lacks.
    void finish_at(const talus::sdk::Points &p, std::size_t k, const Vec6 &trial,
                   const Spectral &sp) const {
        const std::size_t ns = state.size();
        std::array<double, state.size()> q0;
        std::copy(p.state_start + ns * k, p.state_start + ns * (k + 1), q0.begin());
        talus::sdk::PointIn in(p.strain_increment + 6 * k, nullptr, nullptr,
                               p.stress_start + 6 * k);
        in.time = p.time;
        in.dt = p.dt;
        in.density = p.density[k];
        in.state = std::span<const double>(q0.data(), ns);
        talus::sdk::PointOut out;
        out.state = std::span<double>(p.state_end + ns * k, ns);
        finish(in, out, trial, sp);
        double *se = p.stress_end + 6 * k;
        for (int e = 0; e < 6; ++e)
            se[e] = out.stress[e];
        p.done[k] = 1;
    }

    // K + 4G/3 = lambda + 2G: the P-wave (constrained) modulus.
    double p_wave_modulus() const { return el_.lambda + 2.0 * el_.shear; }

    // The update from the decomposition of the trial stress on.
    void finish(const talus::sdk::PointIn &in, talus::sdk::PointOut &out, Vec6 trial,
                Spectral sp) const {
        const double kappa_n = in.state[0];
        const Strength st_n = strength(kappa_n);
        const double bound = softening_ ? lode_bound(st_n) : fixed_lode_bound_;
        const double inv_bound = softening_ ? 1.0 / bound : fixed_inv_lode_bound_;
        // The candidates' systems: solved once without softening, else
        // each as its candidate is tried.
        auto return_of = [&](const V3 &t, int h) {
            return softening_ ? talus_mc::return_map(t, st_n, el_, h)
                              : talus_mc::return_map(t, st_n, *fixed_systems_, h);
        };
        // The last return's kind is tried first: a point that keeps
        // yielding mostly stays on the same part of the surface, and any
        // valid candidate gives the same stress (the candidates partition
        // the trial space).
        const double last = in.state[2];
        const int hint = last >= 1.0 && last < static_cast<int>(talus_mc::kModeCount)
                             ? talus_mc::candidate_of(static_cast<talus_mc::Mode>(last))
                             : talus_mc::kNone;
        Return r = return_of(sp.values, hint);
        if (r.mode == talus_mc::kElastic) {
            out.stress = trial;
            // A stress left on the surface without plastic flow (a zero or
            // neutral increment) keeps its place on it.
            if (!on_surface(sp.values, st_n)) out.state[2] = talus_mc::kElastic;
            if (out.tangent) *out.tangent = De_;
            return;
        }
        // Plastic. A start stress that this model did not leave on the
        // surface itself (yield_mode 0: a user's initial stress, or the
        // stress a group brings to this material at a stage's
        // set_material) may lie outside it: it is then projected first,
        // without plastic strain. A stress the last return put on the
        // surface (yield_mode > 0, at the strength of the kappa stored with
        // it, rotated by the host without changing its principal values)
        // is admissible, and so is one clearly inside. (A start stress on
        // the surface that rounding puts just outside projects onto
        // itself.)
        if (last == 0.0 && !clearly_elastic(in.stress, st_n, bound, inv_bound)) {
            const Spectral s0 =
                talus::sdk::symmetric_eigen(talus::sdk::stress_to_matrix(in.stress));
            if (!talus_mc::admissible(s0.values, st_n,
                                      talus_mc::stress_tolerance(s0.values, st_n))) {
                const Return r0 = return_of(s0.values, talus_mc::kNone);
                trial = s0.compose_stress(r0.stress) + hooke(in.strain_increment);
                sp = talus::sdk::symmetric_eigen(talus::sdk::stress_to_matrix(trial));
                r = return_of(sp.values, hint);
            }
        }
        // Without softening the return above is final and kappa only
        // accumulates; with it, kappa is solved for (plastic_return).
        double kappa = kappa_n;
        M3 P_total;
        const M3 *P = &r.P;
        if (softening_) {
            r = plastic_return(sp.values, kappa_n, r, kappa, P_total);
            P = &P_total;
        }
        const V3 x = el_.solve(sp.values - r.stress); // principal plastic strain increment
        if (!softening_) kappa = kappa_n + talus_mc::deviatoric_measure(x);
        out.stress = sp.compose_stress(r.stress);
        out.state[0] = kappa;
        out.state[1] = in.state[1] + ((x[0] + x[1]) + x[2]);
        out.state[2] = r.mode;
        if (out.tangent) *out.tangent = spectral_tangent(sp, r.stress, *P);
    }

    // The trial stress of an increment from s0 at kappa_n, and whether it
    // is clearly inside the surface (the elastic step's whole result).
    // Inlined into the quick pass's loop: without softening it then reads
    // the fixed strength in place (a call and a copy of the strength per
    // point were a quarter of the pass).
    TALUS_MC_INLINE bool elastic_trial(const Vec6 &s0, const Vec6 &de, double kappa_n,
                                       Vec6 &trial) const {
        trial = s0 + hooke(de);
        if (!softening_)
            return clearly_elastic(trial, fixed_strength_, fixed_lode_bound_,
                                   fixed_inv_lode_bound_);
        const Strength st_n = strength_at(kappa_n);
        const double bound = lode_bound(st_n);
        return clearly_elastic(trial, st_n, bound, 1.0 / bound);
    }

    // Linear softening weight in [0, 1] and its derivative.
    double weight(double kappa, double &dw) const {
        dw = 0.0;
        if (!softening_ || kappa <= k0_) return 0.0;
        if (kappa >= k1_) return 1.0;
        dw = 1.0 / (k1_ - k0_);
        return (kappa - k0_) * dw;
    }

    Strength strength(double kappa) const {
        if (!softening_) return fixed_strength_;
        return strength_at(kappa);
    }

    Strength strength_at(double kappa) const {
        double dw = 0.0;
        const double w = weight(kappa, dw);
        const double phi = (phi_ + (phi_r_ - phi_) * w) * kDeg;
        const double psi = (psi_ + (psi_r_ - psi_) * w) * kDeg;
        Strength s;
        s.sin_phi = std::sin(phi);
        s.cos_phi = std::cos(phi);
        s.sin_psi = std::sin(psi);
        s.cohesion = c_ + (c_r_ - c_) * w;
        // The cut-off matters only up to the apex c cot phi; at the apex
        // itself (c = 0, T = 0, the default) it supplies the tensile flow.
        s.tension_active = !(s.sin_phi > 0.0 && tension_ * s.sin_phi > s.cohesion * s.cos_phi);
        s.tension = tension_;
        return s;
    }

    // The isotropic elastic stress increment of a strain increment
    // (engineering shear): lambda tr(d_eps) 1 + 2 G d_eps. In whole-vector
    // operations: a Vec6 assembled element by element on the stack and read
    // back in pairs waits for the stores (store forwarding), which cost a
    // fifth of this model's update (so did an update of its first three
    // elements in place).
    Vec6 hooke(const Vec6 &de) const {
        return de.cwiseProduct(Eigen::Map<const Vec6>(screen_.moduli)) +
               (el_.lambda * (de[0] + de[1] + de[2])) * Eigen::Map<const Vec6>(screen_.normal);
    }

    // max over the Lode angle of cos(theta) - sin(phi) sin(theta) / sqrt(3),
    // for clearly_elastic: a square root per strength, not per call.
    static double lode_bound(const Strength &st) {
        return std::sqrt(1.0 + st.sin_phi * st.sin_phi / 3.0);
    }
    // Whether the trial stress is inside the surface by more than the
    // return's tolerance (elastic_screen.hpp, whose four-lane form the quick
    // pass runs: the same operations). `bound`: lode_bound(st), `inv_bound`
    // its inverse.
    static bool clearly_elastic(const Vec6 &t, const Strength &st, double bound, double inv_bound) {
        bool in = false;
        talus_mc::clearly_elastic(t.data(), st, bound, inv_bound, in);
        return in;
    }
    // Within the validity tolerance of the shear plane or the cut-off.
    static bool on_surface(const V3 &s, const Strength &st) { return talus_mc::on_surface(s, st); }

    // The return at the strength of kappa, with its plastic deviatoric
    // strain increment.
    Return return_at(const V3 &trial, double kappa, double &dkappa) const {
        const Return r = talus_mc::return_map(trial, strength(kappa), el_);
        dkappa = talus_mc::deviatoric_measure(el_.solve(trial - r.stress));
        return r;
    }

    // Implicit softening: kappa = kappa_n + d_kappa(kappa), d_kappa the
    // plastic deviatoric strain of the return at the strength of kappa.
    // g(kappa) = kappa_n + d_kappa(kappa) - kappa is >= 0 at kappa_n, and <= 0
    // at hi = max(k1, kappa_n + d_kappa(k1)) because the strength, and so
    // d_kappa, is constant beyond k1. Regula falsi with the Illinois
    // modification (Dowell & Jarratt 1971) on that bracket converges
    // superlinearly on the piecewise-smooth g; when softening is so steep
    // that g has several roots (snap-back at the point), the root found lies
    // in the bracket.
    // `at_start`: the return at the strength of kappa_n, already known.
    Return plastic_return(const V3 &trial, double kappa_n, const Return &at_start, double &kappa,
                          M3 &P_total) const {
        Return r = at_start;
        double dk = talus_mc::deviatoric_measure(el_.solve(trial - r.stress));
        kappa = kappa_n + dk;
        if (softening_ && kappa_n < k1_ && dk > 0.0) {
            double lo = kappa_n, g_lo = dk; // g(lo) > 0
            double dk_hi = 0.0;
            r = return_at(trial, k1_, dk_hi);
            double hi = std::max(k1_, kappa_n + dk_hi);
            double g_hi = kappa_n + dk_hi - hi; // <= 0
            kappa = hi;
            // Strain-like; 1e-14 of the softening range is far below any
            // physical resolution and above the rounding of g.
            const double tol = 1e-14 * std::max(hi, k1_ - k0_);
            int side = 0;
            for (int it = 0; it < 200 && g_hi < -tol; ++it) {
                double k = (lo * g_hi - hi * g_lo) / (g_hi - g_lo);
                if (!(k > lo && k < hi)) k = 0.5 * (lo + hi);
                r = return_at(trial, k, dk);
                kappa = k;
                const double g = kappa_n + dk - k;
                if (std::abs(g) <= tol) break;
                if (g > 0.0) {
                    lo = k;
                    g_lo = g;
                    if (side == -1) g_hi *= 0.5;
                    side = -1;
                } else {
                    hi = k;
                    g_hi = g;
                    if (side == 1) g_lo *= 0.5;
                    side = 1;
                }
                if (hi - lo <= tol) break;
            }
            if (kappa == hi && g_hi >= -tol) r = return_at(trial, hi, dk);
            kappa = kappa_n + dk;
        }
        P_total = r.P;
        add_softening_coupling(trial, kappa, r, P_total);
        return r;
    }

    // d sigma / d trial including kappa's dependence on the trial stress:
    // sigma(trial, kappa), kappa = kappa_n + d_kappa(trial, kappa), so
    // d kappa / d trial = (d_kappa,trial) / (1 - d_kappa,kappa). The partial
    // derivatives in kappa are central differences with the candidate fixed
    // (the return is smooth in the strength there), the ones in the trial
    // stress exact.
    void add_softening_coupling(const V3 &trial, double kappa, const Return &r, M3 &P) const {
        double dw = 0.0;
        weight(kappa, dw);
        if (dw == 0.0 || r.candidate == talus_mc::kNone) return;
        const V3 x = el_.solve(trial - r.stress);
        const double dk = talus_mc::deviatoric_measure(x);
        if (!(dk > 0.0)) return;
        const double h = 1e-6 * (k1_ - k0_);
        const double ka = std::max(k0_, kappa - h), kb = std::min(k1_, kappa + h);
        Return ra, rb;
        if (r.candidate == talus_mc::kApex) {
            ra.stress = talus_mc::apex(strength(ka));
            rb.stress = talus_mc::apex(strength(kb));
        } else {
            const talus_mc::Candidate &c =
                talus_mc::kCandidates[static_cast<std::size_t>(r.candidate)];
            V3 dl;
            const talus_mc::Planes pa(strength(ka)), pb(strength(kb));
            if (!talus_mc::solve_candidate(c, talus_mc::make_system(c, pa, el_), trial, pa, dl,
                                           ra) ||
                !talus_mc::solve_candidate(c, talus_mc::make_system(c, pb, el_), trial, pb, dl, rb))
                return;
        }
        const V3 ds_dk = (rb.stress - ra.stress) / (kb - ka);
        const V3 g = (2.0 / 3.0) * (x - V3::Constant(x.sum() / 3.0)) / dk; // d dk / d x
        const double dk_dk = -g.dot(el_.solve(ds_dk));
        // d dk / d trial = g^T D^-1 (I - P); D^-1 is symmetric.
        const Eigen::RowVector3d dk_dtrial = el_.solve(g).transpose() * (M3::Identity() - r.P);
        P += ds_dk * dk_dtrial / (1.0 - dk_dk);
    }

    // The consistent tangent d sigma / d d_eps (engineering shear) of the
    // isotropic return sigma = sum s_k n_k n_k^T of the trial stress
    // (de Souza Neto, Peric & Owen, Computational Methods for Plasticity,
    // 2008, app. A.5): the principal part P D_p on the eigenvalues, and
    // for each pair k != l the spin term 2G (s_k - s_l) / (t_k - t_l) on the
    // shear components of the eigenbasis (t the trial principal stresses),
    // by its limit G ((P_kk - P_kl) - (P_lk - P_ll)) when t_k = t_l.
    Mat6 spectral_tangent(const Spectral &sp, const V3 &s, const M3 &P) const {
        const M3 PD = P * el_.matrix();
        const V3 &t = sp.values;
        const double scale = std::max(t.cwiseAbs().maxCoeff(), 1e-300);
        M3 ratio = M3::Zero();
        for (int k = 0; k < 3; ++k)
            for (int l = 0; l < 3; ++l) {
                if (k == l) continue;
                const double dt = t[k] - t[l];
                ratio(k, l) = std::abs(dt) > 1e-8 * scale
                                  ? 2.0 * el_.shear * (s[k] - s[l]) / dt
                                  : el_.shear * ((P(k, k) - P(k, l)) - (P(l, k) - P(l, l)));
            }
        const M3 &N = sp.vectors;
        Mat6 D;
        for (int j = 0; j < 6; ++j) {
            Vec6 e = Vec6::Zero();
            e[j] = 1.0;
            const M3 Q = N.transpose() * talus::sdk::strain_to_matrix(e) * N;
            const V3 dp = PD * Q.diagonal();
            M3 dS = ratio.cwiseProduct(Q);
            dS.diagonal() = dp;
            D.col(j) = talus::sdk::matrix_to_stress(N * dS * N.transpose());
        }
        return D;
    }

    Elastic el_;
    Mat6 De_;
    // lambda, the moduli 2G / G and the normal components' mask: hooke()'s
    // and the quick pass's screen's (the same constants for both forms).
    talus_mc::ScreenElastic screen_;
    double phi_ = 0.0, psi_ = 0.0, c_ = 0.0, tension_ = 0.0;
    bool softening_ = false;
    double phi_r_ = 0.0, psi_r_ = 0.0, c_r_ = 0.0, k0_ = 0.0, k1_ = 0.0;
    // The strength without softening, computed once: its sines and cosines
    // would otherwise be a fifth of a plastic point's cost.
    Strength fixed_strength_;
    double fixed_lode_bound_ = 1.0, fixed_inv_lode_bound_ = 1.0;
    std::optional<talus_mc::Systems> fixed_systems_; // of fixed_strength_
};

} // namespace

TALUS_MATERIAL_LIBRARY("talus_mohr_coulomb", "1.0.0", MohrCoulomb)
