// Linear elastic (hypoelastic) material: isotropic Hooke's law applied to the
// strain increment, sigma_end = sigma_start + D : d_eps.
//
// The host rotates sigma_start objectively before the call (see
// material_abi.h), so this is the usual rate form used by explicit MPM codes
// for small strains with large rotations. It is not hyperelastic: for large
// strains use neo_hookean.
//
// This file is also the template for a new model: copy the folder, rename.
#include <talus/sdk/material.hpp>

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
        const Vec6 &de = in.strain_increment;
        const double lam_tr = lambda_ * (de[0] + de[1] + de[2]);
        out.stress = in.stress;
        for (int i = 0; i < 3; ++i) {
            out.stress[i] += lam_tr + 2.0 * shear_ * de[i];
            out.stress[i + 3] += shear_ * de[i + 3];
        }
        if (out.tangent) *out.tangent = D_;
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
