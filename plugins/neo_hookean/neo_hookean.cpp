// Compressible Neo-Hookean hyperelasticity on the deformation gradient, the
// energy of Bonet & Wood (Nonlinear Continuum Mechanics for Finite Element
// Analysis, 2nd ed. 2008, sec. 6.4.3, eqs. 6.27-6.29):
//
//   psi(F) = mu/2 (tr b - 3) - mu ln J + lambda/2 (ln J)^2,   b = F F^T,
//   sigma  = (mu (b - I) + lambda ln J I) / J.
//
// The stress is a function of F_end alone (no history), so the model is
// objective by construction: the host passes F and does not rotate the
// stress (TALUS_MODEL_FINITE_STRAIN). It reduces to Hooke's law with the same
// E and nu for small strains, and resists both J -> 0 and J -> infinity.
//
// Host conventions (talus/material_abi.h): the tangent is d sigma_end / d
// strain_increment with F_end = exp(d_eps) F_start, the increment a pure
// stretch (docs/plugins.md). It is computed exactly below, including the
// derivative of the matrix exponential at a finite increment.
#include <talus/sdk/material.hpp>
#include <talus/sdk/voigt.hpp>

#include <Eigen/Eigenvalues>

#include <algorithm>
#include <cmath>

namespace {

using talus::sdk::Mat3;
using talus::sdk::Mat6;
using talus::sdk::Vec6;

// Cauchy stress of the energy for a given F (tensor form).
Mat3 cauchy(const Mat3 &F, double mu, double lambda, double &J) {
    J = F.determinant();
    const Mat3 b = F * F.transpose();
    return (mu * (b - Mat3::Identity()) + lambda * std::log(J) * Mat3::Identity()) / J;
}

struct NeoHookean {
    static constexpr talus::sdk::ModelInfo info{
        .id = "neo_hookean",
        .name = "Neo-Hookean (compressible, Bonet & Wood)",
        .version = "1.0.0",
        .doc = "Compressible Neo-Hookean hyperelasticity: psi = mu/2 (tr b - 3) - mu ln J + "
               "lambda/2 (ln J)^2, sigma = (mu (b - I) + lambda ln J I) / J, b = F F^T "
               "(Bonet & Wood 2008, eq. 6.28), with mu = E / (2 (1 + nu)) and lambda = E nu / "
               "((1 + nu)(1 - 2 nu)): Hooke's law at small strain. Stress from F alone, "
               "objective by construction. Wave speed: the largest longitudinal speed of the "
               "current state, sqrt(((lambda + 2 |mu - lambda ln J|) / J + s) / rho), s the "
               "largest Gershgorin bound of sigma's eigenvalues (at least 0).",
        .finite_strain = true,
        .tangent = true,
    };

    // The small-strain limit is Hooke's law with these E and nu, so the
    // bounds are the same positive-definiteness conditions.
    static constexpr std::array params{
        talus::sdk::real("youngs_modulus", "Pa", "Young's modulus E (small-strain limit).")
            .required()
            .above(0.0)
            .typical(1.0e6),
        talus::sdk::real("poisson_ratio", "-", "Poisson's ratio nu (small-strain limit).")
            .required()
            .above(-1.0)
            .below(0.5)
            .typical(0.3),
    };
    static constexpr std::array<talus::sdk::State, 0> state{};

    explicit NeoHookean(const talus::sdk::ParamValues &p) {
        const double E = p["youngs_modulus"];
        const double nu = p["poisson_ratio"];
        mu_ = E / (2.0 * (1.0 + nu));
        lambda_ = E * nu / ((1.0 + nu) * (1.0 - 2.0 * nu));
    }

    void update(const talus::sdk::PointIn &in, talus::sdk::PointOut &out) const {
        const Mat3 F = in.F_end;
        double J = 0.0;
        const Mat3 sig = cauchy(F, mu_, lambda_, J);
        if (out.tangent) *out.tangent = tangent(in.strain_increment, F, sig, J);
        out.stress = talus::sdk::matrix_to_stress(sig);
    }

    // Longitudinal waves in the current state: the spatial elasticity tensor
    // of this energy is c = lambda/J I(x)I + 2 (mu - lambda ln J)/J II (Bonet &
    // Wood eq. 6.30), and the Cauchy stress adds n.sigma.n to the acoustic
    // tensor, bounded here by the largest Gershgorin row sum (no eigen solve
    // per particle and step; the bound only shortens dt where the stress is a
    // sizeable part of the modulus). Absolute value: beyond J = e^(mu /
    // lambda) the shear term changes sign but the speed must stay an upper
    // bound for the time step.
    double wave_speed(const talus::sdk::PointIn &in, const talus::sdk::PointOut &out) const {
        const double J = in.F_end.determinant();
        const Vec6 &s = out.stress;
        const double s1 = std::max({s[0] + std::abs(s[3]) + std::abs(s[5]),
                                    s[1] + std::abs(s[3]) + std::abs(s[4]),
                                    s[2] + std::abs(s[4]) + std::abs(s[5]), 0.0});
        const double M = (lambda_ + 2.0 * std::abs(mu_ - lambda_ * std::log(J))) / J + s1;
        return std::sqrt(M / in.density);
    }

  private:
    // d sigma / d d_eps at F_end = E F_start, E = exp(d_eps). A change dE of
    // E moves F_end by G F_end with G = dE E^-1, so db = G b + b G^T, dJ/J =
    // tr G and d sigma = (mu db + lambda tr G I) / J - sigma tr G. dE comes
    // from the Daleckii-Krein formula for a symmetric argument: with d_eps =
    // sum_k l_k n_k n_k^T, dE = sum_kl f[l_k, l_l] (n_k^T H n_l) n_k n_l^T,
    // f[a, b] = (e^a - e^b) / (a - b) (e^a when a = b) (Higham, Functions of
    // Matrices, 2008, thm. 3.11).
    Mat6 tangent(const Vec6 &de, const Mat3 &F, const Mat3 &sig, double J) const {
        const Eigen::SelfAdjointEigenSolver<Mat3> es(talus::sdk::strain_to_matrix(de));
        const Mat3 &N = es.eigenvectors();
        const Eigen::Vector3d l = es.eigenvalues();
        Mat3 dd; // divided differences of exp
        for (int k = 0; k < 3; ++k)
            for (int m = 0; m < 3; ++m) {
                const double a = l[k], b = l[m];
                // expm1 keeps the quotient accurate for nearly equal values.
                dd(k, m) = std::abs(a - b) > 1e-8 ? std::exp(b) * std::expm1(a - b) / (a - b)
                                                  : std::exp(0.5 * (a + b));
            }
        const Mat3 Einv = N * (-l.array()).exp().matrix().asDiagonal() * N.transpose();
        const Mat3 b = F * F.transpose();
        Mat6 D;
        for (int j = 0; j < 6; ++j) {
            // Unit engineering-shear increment j as a tensor.
            Vec6 e = Vec6::Zero();
            e[j] = 1.0;
            const Mat3 H = N.transpose() * talus::sdk::strain_to_matrix(e) * N;
            const Mat3 dE = N * dd.cwiseProduct(H) * N.transpose();
            const Mat3 G = dE * Einv;
            const double trG = G.trace();
            const Mat3 db = G * b + b * G.transpose();
            const Mat3 ds = (mu_ * db + lambda_ * trG * Mat3::Identity()) / J - sig * trG;
            D.col(j) = talus::sdk::matrix_to_stress(ds);
        }
        return D;
    }

    double mu_ = 0.0;
    double lambda_ = 0.0;
};

} // namespace

TALUS_MATERIAL_LIBRARY("talus_neo_hookean", "1.0.0", NeoHookean)
