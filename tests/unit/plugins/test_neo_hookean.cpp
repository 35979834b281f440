// The shipped Neo-Hookean plugin through the loader, as the solver and the
// driver call it: stresses against the closed-form homogeneous deformations
// of tests/data/neo_hookean_homogeneous.csv, the tangent against central
// differences far from the reference state, objectivity, and the wave speed.
#include "solver_helpers.hpp"
#include "test_paths.hpp"

#include <talus/material/plugin_loader.hpp>

#include <Eigen/Dense>
#include <gtest/gtest.h>

#include <cmath>
#include <fstream>
#include <sstream>
#include <string>
#include <vector>

namespace {

using Mat3 = Eigen::Matrix<double, 3, 3, Eigen::RowMajor>;
using Vec6 = Eigen::Matrix<double, 6, 1>;

struct Point {
    Vec6 de = Vec6::Zero();
    Mat3 F0 = Mat3::Identity(), F1 = Mat3::Identity();
    double rho = 1000.0;
    Vec6 s0 = Vec6::Zero();
};

struct Result {
    Vec6 stress;
    Eigen::Matrix<double, 6, 6, Eigen::RowMajor> D;
    double c = 0.0;
};

const talus::Model &model(talus::PluginRegistry &reg) {
    return reg.load((talus::test::plugin_dir() / "talus_neo_hookean.so").string()).models()[0];
}

Result call(const talus::MaterialInstance &m, const Point &p) {
    Result r;
    talus_batch b{};
    b.flags = TALUS_BATCH_WANT_WAVE_SPEED | TALUS_BATCH_WANT_TANGENT;
    b.n_points = 1;
    b.dt = 1.0;
    b.strain_increment = p.de.data();
    b.F_start = p.F0.data();
    b.F_end = p.F1.data();
    b.density = &p.rho;
    b.stress_start = p.s0.data();
    b.stress_end = r.stress.data();
    b.wave_speed = &r.c;
    b.tangent = r.D.data();
    const auto res = m.update(b);
    EXPECT_TRUE(res.ok()) << res.message;
    return r;
}

Mat3 sym_exp(const Vec6 &e) {
    Mat3 m;
    m << e[0], e[3] / 2, e[5] / 2, e[3] / 2, e[1], e[4] / 2, e[5] / 2, e[4] / 2, e[2];
    const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> es(m);
    return es.eigenvectors() * es.eigenvalues().array().exp().matrix().asDiagonal() *
           es.eigenvectors().transpose();
}

} // namespace

// Every Bonet-Wood row of the reference file (uniaxial strain, uniaxial
// stress in 3D and plane strain, simple shear, hydrostatic, two peer vectors).
// The file prints F and sigma to 10 significant digits. The printed stress
// carries up to 5e-10 of itself in rounding: 1e-9 of the row's largest
// stress covers it. The printed F carries up to 5e-10 per entry (the solved
// lateral stretches of the uniaxial-stress rows, e.g. 1.067338369), which
// moves sigma by about (lambda + 2 mu) / J * 5e-10 per entry, under 5e-9 E
// for these states (the reference's near-zero lateral stresses, ~1e-10 Pa,
// come from the unrounded F). A wrong term (a missing ln J, b in place of
// b - I, a lost 1/J) is off by 1e-3 of the stress or more.
TEST(NeoHookean, MatchesTheClosedFormHomogeneousDeformations) {
    talus::PluginRegistry reg;
    const talus::Model &m = model(reg);
    std::ifstream in(talus::test::data_dir() / "neo_hookean_homogeneous.csv");
    ASSERT_TRUE(in) << "missing reference file";
    std::string line;
    int rows = 0;
    while (std::getline(in, line)) {
        if (line.empty() || line[0] == '#' || line.rfind("case,", 0) == 0) continue;
        std::stringstream ss(line);
        std::string name, energy, cell;
        std::getline(ss, name, ',');
        std::getline(ss, energy, ',');
        if (energy != "bonet_wood") continue;
        std::vector<double> v;
        while (std::getline(ss, cell, ','))
            v.push_back(std::stod(cell));
        ASSERT_EQ(v.size(), 18u) << line;
        const double params[] = {v[0], v[1]};
        const auto inst = m.create(params);
        Point p;
        for (int k = 0; k < 9; ++k)
            p.F1.data()[k] = v[2 + static_cast<std::size_t>(k)];
        const Result r = call(*inst, p);
        double scale = 0.0;
        for (int k = 0; k < 6; ++k)
            scale = std::max(scale, std::abs(v[12 + static_cast<std::size_t>(k)]));
        for (int k = 0; k < 6; ++k)
            EXPECT_NEAR(r.stress[k], v[12 + static_cast<std::size_t>(k)],
                        1e-9 * scale + 5e-9 * v[0])
                << name << " row " << rows << " component " << k;
        ++rows;
    }
    EXPECT_EQ(rows, 68);
}

// The consistent tangent at a large, sheared and stretched state with a
// finite increment (the conformance check probes only small strains). The
// host convention: F_end = exp(de) F_start. Central differences with h =
// 1e-6 have truncation ~h^2 |d3 sigma| (1e-12 of the modulus) and round-off
// ~1e-16 |sigma| / h (1e-10 of it): 1e-6 of max|D| separates a correct
// tangent from one that drops the exponential's derivative (5e-3 of
// max|D| here, computed independently with scipy's expm).
TEST(NeoHookean, TangentIsTheDerivativeAtLargeStrain) {
    talus::PluginRegistry reg;
    const double params[] = {1e6, 0.3};
    const auto inst = model(reg).create(params);
    Point p;
    p.F0 << 1.4, 0.3, 0.0, -0.1, 0.8, 0.2, 0.05, 0.0, 1.1;
    p.de << 0.04, -0.02, 0.01, 0.05, -0.03, 0.02;
    p.F1 = sym_exp(p.de) * p.F0;
    const Result base = call(*inst, p);
    const double h = 1e-6;
    double worst = 0.0;
    for (int j = 0; j < 6; ++j) {
        Point a = p, b = p;
        a.de[j] += h;
        b.de[j] -= h;
        a.F1 = sym_exp(a.de) * p.F0;
        b.F1 = sym_exp(b.de) * p.F0;
        const Vec6 col = (call(*inst, a).stress - call(*inst, b).stress) / (2 * h);
        for (int i = 0; i < 6; ++i)
            worst = std::max(worst, std::abs(col[i] - base.D(i, j)));
    }
    EXPECT_LT(worst, 1e-6 * base.D.cwiseAbs().maxCoeff());
}

// Objectivity: sigma(Q F) = Q sigma(F) Q^T for a rotation Q, so a rigid
// rotation of a strained state rotates its stress and keeps its invariants.
// Round-off only (1e-12 of the stress).
TEST(NeoHookean, RotatingTheDeformationRotatesTheStress) {
    talus::PluginRegistry reg;
    const double params[] = {1e6, 0.3};
    const auto inst = model(reg).create(params);
    Point p;
    p.F1 << 1.3, 0.2, 0.0, 0.1, 0.9, 0.0, 0.0, 0.0, 1.05;
    const Vec6 s = call(*inst, p).stress;
    const Mat3 Q = Eigen::AngleAxisd(1.1, Eigen::Vector3d(1, 2, 3).normalized()).toRotationMatrix();
    Point q = p;
    q.F1 = Q * p.F1;
    const Vec6 sq = call(*inst, q).stress;
    Mat3 S, SQ;
    S << s[0], s[3], s[5], s[3], s[1], s[4], s[5], s[4], s[2];
    SQ << sq[0], sq[3], sq[5], sq[3], sq[1], sq[4], sq[5], sq[4], sq[2];
    const Mat3 expect = Q * S * Q.transpose();
    EXPECT_LT((SQ - expect).cwiseAbs().maxCoeff(), 1e-12 * S.cwiseAbs().maxCoeff());
}

// In the reference state the model is Hooke's law: the tangent is the
// isotropic elasticity matrix and the wave speed the P-wave speed sqrt((lambda
// + 2 mu) / rho) (closed form; round-off only).
TEST(NeoHookean, IsHookesLawAtTheReferenceState) {
    talus::PluginRegistry reg;
    const double E = 2e7, nu = 0.25, params[] = {E, nu};
    const auto inst = model(reg).create(params);
    const double mu = E / (2 * (1 + nu)), lam = E * nu / ((1 + nu) * (1 - 2 * nu));
    const Result r = call(*inst, Point{});
    for (int i = 0; i < 6; ++i)
        for (int j = 0; j < 6; ++j) {
            const double D = i < 3 && j < 3 ? lam + (i == j ? 2 * mu : 0.0) : (i == j ? mu : 0.0);
            EXPECT_NEAR(r.D(i, j), D, 1e-9 * E) << i << "," << j;
        }
    EXPECT_NEAR(r.c, std::sqrt((lam + 2 * mu) / 1000.0), 1e-12 * r.c);
}
