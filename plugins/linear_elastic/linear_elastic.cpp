// Linear elastic (hypoelastic) material: isotropic Hooke's law applied to the
// strain increment, sigma_end = sigma_start + D : d_eps.
//
// The host rotates sigma_start objectively before the call (see
// material_abi.h), so this is the usual rate form used by explicit MPM codes
// for small strains with large rotations. It is not hyperelastic: for large
// strains use neo_hookean.
//
// The model is its constructor, update() and wave_speed(), the whole of
// what the SDK needs (a new model starts from `talus plugin new`, the same
// shape). quick_update, at the end, is the SDK's opt-in speed path
// (docs/plugins.md, "Speed paths"): the same arithmetic over a chunk.
#include <talus/sdk/hooke.hpp>
#include <talus/sdk/material.hpp>
#include <talus/sdk/wave_speed.hpp>

#include <cmath>

namespace {

using talus::sdk::Mat6;
using talus::sdk::Vec6;

struct LinearElastic {
    static constexpr talus::sdk::ModelInfo info{
        .id = "linear_elastic",
        .name = "Linear elastic (isotropic Hooke, incremental)",
        .version = "1.0.0",
        .doc = "Isotropic linear elasticity applied to the strain increment: "
               "sigma_end = sigma_start + lambda tr(d_eps) I + 2 G d_eps, with "
               "G = E / (2 (1 + nu)) and lambda = E nu / ((1 + nu)(1 - 2 nu)). "
               "Hypoelastic: the host applies the objective stress rotation. "
               "Wave speed: the P-wave speed sqrt((K + 4G/3) / rho).",
        .finite_strain = false,
        .tangent = true,
    };

    // Bounds: E > 0 and -1 < nu < 1/2 are exactly the conditions for the
    // elasticity tensor to be positive definite (K > 0 and G > 0).
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
    };
    static constexpr std::array<talus::sdk::State, 0> state{};

    explicit LinearElastic(const talus::sdk::ParamValues &p) {
        const double E = p["youngs_modulus"];
        const double nu = p["poisson_ratio"];
        shear_ = E / (2.0 * (1.0 + nu));
        lambda_ = E * nu / ((1.0 + nu) * (1.0 - 2.0 * nu));
        // K + 4G/3 = lambda + 2G: the P-wave (constrained) modulus.
        p_wave_modulus_ = lambda_ + 2.0 * shear_;
        D_.setZero();
        for (int i = 0; i < 3; ++i) {
            for (int j = 0; j < 3; ++j)
                D_(i, j) = lambda_;
            D_(i, i) = p_wave_modulus_;
            // Engineering shear strain in, tensor shear stress out: G, not 2G.
            D_(i + 3, i + 3) = shear_;
        }
    }

    void update(const talus::sdk::PointIn &in, talus::sdk::PointOut &out) const {
        talus::sdk::isotropic_hooke(lambda_, shear_, in.stress.data(), in.strain_increment.data(),
                                    out.stress.data(), 1);
        if (out.tangent) *out.tangent = D_;
    }

    // The whole update over a chunk of the batch (the SDK's quick pass),
    // so every update call takes this path: update() and wave_speed() are
    // the per-point forms the SDK's contract asks for, with the same
    // arithmetic (isotropic_hooke, sqrt(M / rho)). Without it the SDK set up each
    // point for update() and computed its wave speed alone, where the
    // division and the square root wait on each other, which costs most on
    // a core where they are slow
    // (bench/results/2026-11-26-xeon-2.1ghz-plugin-path.md).
    void quick_update(const talus::sdk::Points &p) const {
        talus::sdk::isotropic_hooke(lambda_, shear_, p.stress_start, p.strain_increment,
                                    p.stress_end, p.n);
        for (std::size_t k = 0; k < p.n; ++k) {
            if (p.tangent) Eigen::Map<Mat6>(p.tangent + 36 * k) = D_; // symmetric
            p.done[k] = 1;
        }
        if (p.wave_speed) talus::sdk::wave_speeds(p_wave_modulus_, p.density, p.wave_speed, p.n);
    }

    double wave_speed(const talus::sdk::PointIn &in, const talus::sdk::PointOut &) const {
        return std::sqrt(p_wave_modulus_ / in.density);
    }

  private:
    double shear_ = 0.0;
    double lambda_ = 0.0;
    double p_wave_modulus_ = 0.0;
    Mat6 D_;
};

} // namespace

TALUS_MATERIAL_LIBRARY("talus_linear_elastic", "1.0.0", LinearElastic)
