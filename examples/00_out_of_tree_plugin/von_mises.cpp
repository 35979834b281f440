// J2 (von Mises) plasticity with linear isotropic hardening, small strain,
// radial return mapping and its consistent tangent: Simo & Hughes,
// "Computational Inelasticity" (Springer, 1998), Box 3.1 (return) and
// Box 3.2 (algorithmic tangent). An example of a plugin written outside the
// Talus tree, with a state variable and a tangent.
#include <talus/sdk/material.hpp>

#include <cmath>

namespace {

using talus::sdk::Mat6;
using talus::sdk::Vec6;

struct VonMises {
    static constexpr talus::sdk::ModelInfo info{
        .id = "von_mises",
        .name = "Von Mises plasticity, linear isotropic hardening",
        .version = "1.0.0",
        .doc = "Isotropic linear elasticity with a von Mises yield surface "
               "sqrt(3 J2) = yield_stress + hardening_modulus * eps_p, associated flow, "
               "radial return and consistent tangent (Simo & Hughes 1998, Boxes 3.1-3.2).",
        .finite_strain = false,
        .tangent = true,
    };
    static constexpr std::array params{
        talus::sdk::real("youngs_modulus", "Pa", "Young's modulus E.")
            .required()
            .above(0.0)
            .typical(2.0e11),
        talus::sdk::real("poisson_ratio", "-", "Poisson's ratio nu.")
            .required()
            .above(-1.0)
            .below(0.5)
            .typical(0.3),
        talus::sdk::real("yield_stress", "Pa", "Initial uniaxial yield stress.")
            .required()
            .above(0.0)
            .typical(2.5e8),
        talus::sdk::real("hardening_modulus", "Pa", "Linear isotropic hardening modulus H.")
            .defaults_to(0.0)
            .at_least(0.0)
            .typical(1.0e9),
    };
    static constexpr std::array state{
        talus::sdk::state_variable("equivalent_plastic_strain", "-",
                                   "Accumulated equivalent plastic strain eps_p.")
            .output()
            .user_initialisable()};

    explicit VonMises(const talus::sdk::ParamValues &p)
        : G(p["youngs_modulus"] / (2.0 * (1.0 + p["poisson_ratio"]))),
          K(p["youngs_modulus"] / (3.0 * (1.0 - 2.0 * p["poisson_ratio"]))), sy(p["yield_stress"]),
          H(p["hardening_modulus"]) {}

    void update(const talus::sdk::PointIn &in, talus::sdk::PointOut &out) const {
        // Elastic trial state.
        const Vec6 &de = in.strain_increment;
        const double dvol = de[0] + de[1] + de[2];
        Vec6 s = in.stress;
        for (int i = 0; i < 3; ++i) {
            s[i] += K * dvol + 2.0 * G * (de[i] - dvol / 3.0);
            s[i + 3] += G * de[i + 3]; // engineering shear strain
        }
        const double p = (s[0] + s[1] + s[2]) / 3.0;
        Vec6 dev = s;
        for (int i = 0; i < 3; ++i)
            dev[i] -= p;
        // Frobenius norm of the deviator: shear components count twice.
        const double norm =
            std::sqrt(dev.head<3>().squaredNorm() + 2.0 * dev.tail<3>().squaredNorm());
        const double eps_p = out.state[0];
        const double f = norm - std::sqrt(2.0 / 3.0) * (sy + H * eps_p);

        if (f <= 0.0) {
            out.stress = s;
            if (out.tangent) *out.tangent = elastic_tangent();
            return;
        }
        const double dgamma = f / (2.0 * G + 2.0 * H / 3.0);
        const Vec6 n = dev / norm;
        // n is deviatoric, so the pressure is untouched.
        out.stress = s - 2.0 * G * dgamma * n;
        out.state[0] = eps_p + std::sqrt(2.0 / 3.0) * dgamma;
        if (out.tangent) {
            const double theta = 1.0 - 2.0 * G * dgamma / norm;
            const double theta_bar = 1.0 / (1.0 + H / (3.0 * G)) - (1.0 - theta);
            *out.tangent = volumetric() * K + 2.0 * G * theta * deviatoric_projector() -
                           2.0 * G * theta_bar * n * n.transpose();
        }
    }

    double wave_speed(const talus::sdk::PointIn &in, const talus::sdk::PointOut &) const {
        return std::sqrt((K + 4.0 * G / 3.0) / in.density);
    }

  private:
    double G, K, sy, H;

    // 1 (x) 1 in Voigt form.
    static Mat6 volumetric() {
        Mat6 m = Mat6::Zero();
        m.topLeftCorner<3, 3>().setOnes();
        return m;
    }
    // Maps an engineering-shear strain to the tensor deviator: delta - 1/3
    // on the normal block, 1/2 on the shear diagonal.
    static Mat6 deviatoric_projector() {
        Mat6 m = Mat6::Zero();
        m.topLeftCorner<3, 3>().setConstant(-1.0 / 3.0);
        for (int i = 0; i < 3; ++i) {
            m(i, i) += 1.0;
            m(i + 3, i + 3) = 0.5;
        }
        return m;
    }
    Mat6 elastic_tangent() const { return K * volumetric() + 2.0 * G * deviatoric_projector(); }
};

} // namespace

TALUS_MATERIAL_LIBRARY("talus_example_von_mises", "1.0.0", VonMises)
