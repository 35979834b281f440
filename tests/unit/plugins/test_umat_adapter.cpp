// The UMAT adapter (plugins/umat_adapter) running Fortran UMATs compiled by
// gfortran as a user would (tests/umat): an isotropic elastic UMAT against
// linear_elastic, in the driver and in a scenario; a J2 UMAT with state
// variables against the closed form of monotonic simple shear; its tangent
// (DDSDDE through the adapter's reordering) against finite differences in
// the conformance checks.
#include "one_point_batch.hpp"
#include "solver_helpers.hpp"
#include "test_paths.hpp"

#include <talus/driver/point_driver.hpp>
#include <talus/input/yaml_input.hpp>
#include <talus/plugin_check/conformance.hpp>

#include <Eigen/Geometry>
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <numbers>
#include <string>

namespace {

std::string umat(const std::string &name) {
    return std::string(TALUS_TEST_UMAT_DIR) + "/" + name + ".so";
}

const std::string kElasticUmat = "  model: umat\n  density: 2000\n  library: '" +
                                 umat("elastic_umat") + "'\n  props: [2.0e7, 0.3]\n";
const std::string kLinearElastic =
    "  model: linear_elastic\n  density: 2000\n  youngs_modulus: 2.0e7\n  poisson_ratio: 0.3\n";

// A path through every kind of driver stage a strain-increment model sees:
// oedometric loading, simple shear (all shear components), a rigid rotation
// of the loaded point (the adapter rotates its STRAN by DROT), a general
// strain-controlled stage.
std::string elastic_case(const std::string &material) {
    return "talus: 1\nmaterial:\n" + material +
           "initial_stress: [-1.0e4, -2.0e4, -3.0e4, 1.0e3, 0, 0]\n"
           "stages:\n"
           "  - {name: load, preset: oedometer, axial_strain: 0.002, increments: 20}\n"
           "  - {name: shear, preset: simple_shear, shear_strain: 0.003, constant: volume, "
           "increments: 20}\n"
           "  - {name: turn, rotation: {axis: [1, 2, 3], angle: 50}, increments: 25}\n"
           "  - name: more\n    increments: 10\n    control:\n"
           "      xx: {strain_change: 0.001}\n      yy: {strain_change: -0.0005}\n"
           "      zz: {stress_change: 2.0e3}\n      xy: {strain_change: 0.0007}\n"
           "      yz: {strain_change: -0.0004}\n      xz: {stress: 0}\n";
}

// The J2 UMAT's constants (PROPS 1-4) and its closed form in monotonic
// simple shear (strain gamma_xz only): tau = G gamma until tau_y = sigma_y /
// sqrt(3), then gamma_p = (G gamma - sigma_y / sqrt(3)) / (G + H / 3), tau =
// G (gamma - gamma_p), the equivalent plastic strain gamma_p / sqrt(3).
struct J2Shear {
    static constexpr double E = 2.0e7, nu = 0.25, sy = 4.0e4, H = 2.0e6;
    static constexpr double G = E / (2.0 * (1.0 + nu));
    static double plastic(double gamma) {
        return std::max(0.0, (G * gamma - sy / std::sqrt(3.0)) / (G + H / 3.0));
    }
    static double tau(double gamma) { return G * (gamma - plastic(gamma)); }
};

std::vector<talus::PointRow> run_case(const std::string &yaml, talus::PluginRegistry &reg) {
    const auto root = talus::yaml::load_string(yaml, "case.yaml");
    const talus::PointCase pc = talus::read_point_case(root, reg);
    return talus::run_point_case(pc);
}

} // namespace

// Isotropic elasticity through the adapter is linear_elastic: the same
// stress at every increment of every stage to 1e-10 of the largest stress
// (the two sum the same products in another order: round-off, ~1e-15).
TEST(UmatAdapter, ElasticUmatMatchesLinearElasticInTheDriver) {
    talus::PluginRegistry reg({}, false);
    const auto a = run_case(elastic_case(kElasticUmat), reg);
    const auto b = run_case(elastic_case(kLinearElastic), reg);
    ASSERT_EQ(a.size(), b.size());
    ASSERT_GT(a.size(), 70u);
    double scale = 0.0;
    for (const auto &r : b)
        scale = std::max(scale, r.stress.cwiseAbs().maxCoeff());
    for (std::size_t i = 0; i < a.size(); ++i) {
        ASSERT_EQ(a[i].time, b[i].time);
        for (int c = 0; c < 6; ++c) {
            ASSERT_NEAR(a[i].stress[c], b[i].stress[c], 1e-10 * scale)
                << "row " << i << " component " << c;
            // The driver solves the same path for both: strains of 1e-3
            // agree to round-off (~1e-18); 1e-14 leaves room for the
            // mixed-control stage's Newton iterations.
            ASSERT_NEAR(a[i].strain[c], b[i].strain[c], 1e-14) << "row " << i;
        }
        // The adapter's STRAN: the strain the driver accumulates (Hencky,
        // tensor shears here, engineering in the state) -- up to the rigid
        // rotation stage, after which STRAN is rotated with the material
        // (Abaqus' convention) while the driver's columns are not. The same
        // increments summed in the same order: round-off only.
        if (a[i].stage <= 2) {
            for (int c = 0; c < 6; ++c)
                ASSERT_NEAR(a[i].state[static_cast<std::size_t>(c)],
                            (c < 3 ? 1.0 : 2.0) * a[i].strain[c], 1e-14)
                    << "row " << i;
        }
    }
    // Through the rotation stage STRAN turns with the material, as Abaqus
    // rotates it with DROT: after 50 deg about [1, 2, 3] it is R eps R^T.
    std::size_t before = 0, after = 0;
    for (std::size_t i = 0; i < a.size(); ++i) {
        if (a[i].stage == 2) before = i;
        if (a[i].stage == 3) after = i;
    }
    auto tensor = [](const std::vector<double> &q) { // engineering -> tensor
        Eigen::Matrix3d e;
        e << q[0], 0.5 * q[3], 0.5 * q[5], 0.5 * q[3], q[1], 0.5 * q[4], 0.5 * q[5], 0.5 * q[4],
            q[2];
        return e;
    };
    const Eigen::Matrix3d R =
        Eigen::AngleAxisd(50.0 * std::numbers::pi / 180.0, Eigen::Vector3d(1, 2, 3).normalized())
            .toRotationMatrix();
    const Eigen::Matrix3d expected = R * tensor(a[before].state) * R.transpose();
    // Strains of 1e-3 turned through 25 increments: round-off ~1e-18.
    EXPECT_LT((tensor(a[after].state) - expected).cwiseAbs().maxCoeff(), 1e-15);
    EXPECT_GT((tensor(a[before].state) - expected).cwiseAbs().maxCoeff(), 1e-5); // it did turn
}

// J2 plasticity with linear hardening against the closed form of simple
// shear (J2Shear). Radial return is exact for linear hardening on a radial
// path: round-off only.
TEST(UmatAdapter, VonMisesUmatMatchesTheClosedFormOfSimpleShear) {
    const double sy = J2Shear::sy;
    const std::string yaml =
        "talus: 1\nmaterial:\n  model: umat\n  density: 2000\n  library: '" +
        umat("von_mises_umat") +
        "'\n  props: [2.0e7, 0.25, 4.0e4, 2.0e6]\n  nstatv: 7\n"
        "  state_names: eqp, ep_11, ep_22, ep_33, ep_12, ep_13, ep_23\n"
        "stages:\n  - {name: shear, preset: simple_shear, shear_strain: 0.01, constant: volume, "
        "increments: 50}\n";
    talus::PluginRegistry reg({}, false);
    const auto rows = run_case(yaml, reg);
    ASSERT_EQ(rows.size(), 51u);
    bool yielded = false;
    for (const auto &r : rows) {
        const double gamma = 2.0 * r.strain[5]; // xz, tensor -> engineering
        const double gp = J2Shear::plastic(gamma), tau = J2Shear::tau(gamma);
        yielded |= gp > 0.0;
        // Round-off of the return: a few ulps of the yield stress.
        ASSERT_NEAR(r.stress[5], tau, 1e-9 * sy) << "gamma " << gamma;
        for (int c = 0; c < 5; ++c)
            ASSERT_NEAR(r.stress[c], 0.0, 1e-9 * sy) << "gamma " << gamma;
        // Plastic strains of order 1e-2, sums of 50 increments: round-off
        // ~1e-17, so 1e-12 is far inside it yet catches any wrong factor.
        ASSERT_NEAR(r.state[0], gp / std::sqrt(3.0), 1e-12) << "gamma " << gamma; // eqp
        ASSERT_NEAR(r.state[5], gp, 1e-12) << "gamma " << gamma; // ep_13 (Abaqus order)
    }
    EXPECT_TRUE(yielded);
}

// The conformance suite on the adapter with the J2 UMAT on its plastic
// branch: the tangent check compares the converted DDSDDE with central
// differences (so the reordering of components and shear conventions is
// checked), plus batch, in-place, NaN and thread checks. Both models (the
// serialised and the reentrant one) pass.
TEST(UmatAdapter, PassesTheConformanceChecksWithThePlasticUmat) {
    talus::CheckOptions opt;
    opt.isolate = false;
    opt.strain_scale = 1e-3; // beyond yield (sigma_y / E = 2e-3) within the paths
    opt.params = {
        {"library", umat("von_mises_umat")}, {"props", "2.0e7,0.25,4.0e4,2.0e6"}, {"nstatv", "7"}};
    const auto rep = talus::check_plugin(talus::test::plugin_dir() / "talus_umat_adapter.so", opt);
    std::string text;
    for (const auto &o : rep.outcomes)
        text += o.model + " " + o.name + ": " + (o.passed ? "PASS " : "FAIL ") + o.detail + "\n";
    EXPECT_TRUE(rep.passed()) << text;
}

// The adapter's own refusals, each at the material's place in the file.
TEST(UmatAdapter, BadSettingsAreNamed) {
    talus::PluginRegistry reg({}, false);
    auto error_of = [&](const std::string &material) {
        try {
            run_case("talus: 1\nmaterial:\n  model: umat\n  density: 2000\n" + material +
                         "stages:\n  - {preset: isotropic, pressure: 1.0e4, increments: 1}\n",
                     reg);
        } catch (const talus::Error &e) {
            return std::string(e.what());
        }
        return std::string("no error");
    };
    const std::string lib = "  library: '" + umat("von_mises_umat") + "'\n";
    EXPECT_TRUE(
        talus::test::contains(error_of("  library: no_such.so\n"), "cannot load the UMAT library"))
        << error_of("  library: no_such.so\n");
    EXPECT_TRUE(
        talus::test::contains(error_of(lib + "  entry: umat\n"), "exports no symbol 'umat'"))
        << error_of(lib + "  entry: umat\n");
    EXPECT_TRUE(talus::test::contains(error_of(lib + "  calling_convention: pascal\n"),
                                      "calling_convention: expected 'fortran'"))
        << error_of(lib + "  calling_convention: pascal\n");
    EXPECT_TRUE(talus::test::contains(error_of(lib + "  nstatv: 2\n  state_names: a\n"),
                                      "state_names: 1 names for nstatv = 2"))
        << error_of(lib + "  nstatv: 2\n  state_names: a\n");
    EXPECT_TRUE(talus::test::contains(error_of(lib + "  nstatv: 2\n  depvar: [1, 2, 3]\n"),
                                      "depvar: 3 initial values for nstatv = 2"))
        << error_of(lib + "  nstatv: 2\n  depvar: [1, 2, 3]\n");
    EXPECT_TRUE(talus::test::contains(error_of(""), "missing required parameter 'library'"))
        << error_of("");
}

// In a scenario: the elastic UMAT and linear_elastic give the same run to
// round-off (a fixed time step, so that the two wave speeds, computed
// differently, cannot choose different steps).
TEST(UmatAdapter, ElasticUmatMatchesLinearElasticInAScenario) {
    auto run = [](const std::string &material) {
        const std::string yaml =
            "talus: 1\ndimension: 2\ngrid: {origin: [0, 0], size: [1, 1], cell: 0.05}\n"
            "materials:\n  m: {" +
            material +
            "}\ngroups:\n  a: {material: m, particles_per_cell: 2, velocity: [0.3, -0.2],\n"
            "      angular_velocity: 1.5, shape: {sphere: {center: [0.5, 0.55], radius: 0.25}}}\n"
            "boundaries: {y-: {friction: 0.3}}\ngravity: [0, -9.81]\n"
            "solver: {dt: 2.0e-4}\ntime: {end: 1}\n";
        auto s = talus::test::sim_from_text(yaml);
        for (int k = 0; k < 300; ++k)
            s->sim->step(1.0);
        return s;
    };
    const auto a = run("model: umat, density: 2000, library: '" + umat("elastic_umat") +
                       "', props: [2.0e6, 0.3]");
    const auto b =
        run("model: linear_elastic, density: 2000, youngs_modulus: 2.0e6, poisson_ratio: 0.3");
    const auto &pa = a->sim->sets()[0];
    const auto &pb = b->sim->sets()[0];
    ASSERT_EQ(pa.n, pb.n);
    double smax = 0.0;
    for (double v : pb.stress)
        smax = std::max(smax, std::abs(v));
    ASSERT_GT(smax, 0.0);
    for (std::size_t p = 0; p < pa.n; ++p) {
        for (int d = 0; d < 2; ++d)
            // Positions of order 1 m after 300 steps: round-off grows with
            // the steps but stays far below 1e-10 m.
            ASSERT_NEAR(pa.x[static_cast<std::size_t>(d)][p], pb.x[static_cast<std::size_t>(d)][p],
                        1e-10)
                << "particle " << p;
        // Each step's Hooke update sums the same products in another order
        // (~1e-16 of the stress); 300 steps of it, fed back through the
        // motion, stay far below 1e-9 of the largest stress.
        for (std::size_t c = 0; c < 6; ++c)
            ASSERT_NEAR(pa.stress[6 * p + c], pb.stress[6 * p + c], 1e-9 * smax)
                << "particle " << p;
    }
}

// Every argument in its place: the J2 UMAT records CELENT, KINC, NOEL, DTIME
// and DROT(2,1) in its state variables 8..12. In a rigid rotation stage of
// 30 deg about z in 10 increments, each increment's rotation is 3 deg:
// DROT(2,1) = sin(3 deg).
TEST(UmatAdapter, EveryArgumentArrivesInItsPlace) {
    const std::string yaml =
        "talus: 1\ncharacteristic_length: 0.37\nmaterial:\n  model: umat\n  density: 2000\n"
        "  library: '" +
        umat("von_mises_umat") +
        "'\n  props: [2.0e7, 0.25, 4.0e4, 2.0e6]\n  nstatv: 12\n"
        "stages:\n  - {name: load, preset: isotropic, pressure: 1.0e4, increments: 4}\n"
        "  - {name: turn, rotation: {axis: [0, 0, 1], angle: 30}, increments: 10, duration: "
        "2.0}\n";
    talus::PluginRegistry reg({}, false);
    const auto rows = run_case(yaml, reg);
    ASSERT_EQ(rows.size(), 15u);
    for (std::size_t i = 1; i < rows.size(); ++i) {
        const auto &q = rows[i].state;
        EXPECT_EQ(q[7], 0.37) << "row " << i;                        // CELENT
        EXPECT_EQ(q[8], static_cast<double>(i)) << "row " << i;      // KINC: the increment
        EXPECT_EQ(q[9], 1.0) << "row " << i;                         // NOEL: point id 0, + 1
        EXPECT_DOUBLE_EQ(q[10], i <= 4 ? 0.25 : 0.2) << "row " << i; // DTIME: 1/4, 2/10
        // DROT(2,1): identity while loading, 3 deg increments while turning
        // (the driver's polar decomposition: round-off of a few ulps).
        EXPECT_NEAR(q[11], i <= 4 ? 0.0 : std::sin(3.0 * std::numbers::pi / 180.0), 1e-14)
            << "row " << i;
    }
}

// PNEWDT < 1 is a cut-step request: the adapter returns it with the UMAT's
// factor, and the driver, retrying in parts, still lands on the closed form
// of simple shear (the J2 return is exact whatever the increment).
TEST(UmatAdapter, PnewdtBecomesACutStep) {
    // The UMAT refuses increments whose plastic multiplier exceeds 1e-4.
    const std::string yaml =
        "talus: 1\nmaterial:\n  model: umat\n  density: 2000\n  library: '" +
        umat("von_mises_umat") +
        "'\n  props: [2.0e7, 0.25, 4.0e4, 2.0e6, 1.0e-4]\n  nstatv: 7\n"
        "stages:\n  - {name: shear, preset: simple_shear, shear_strain: 0.01, constant: volume, "
        "increments: 5}\n";
    talus::PluginRegistry reg({}, false);
    const auto root = talus::yaml::load_string(yaml, "case.yaml");
    const talus::PointCase pc = talus::read_point_case(root, reg);

    // One call straight through the adapter: the whole first increment.
    talus::test::OnePoint p;
    p.q0 = pc.instance->state().initial();
    p.de = {0, 0, 0, 0, 0, 0.004};
    p.dt = 0.2;
    p.id = 0;
    talus_batch b = p.batch(1);
    const auto r = pc.instance->update(b);
    EXPECT_EQ(r.status, TALUS_STATUS_CUT_STEP);
    EXPECT_EQ(r.cut_factor, 0.5);
    EXPECT_TRUE(talus::test::contains(r.message, "the UMAT set PNEWDT = 0.5")) << r.message;

    // The driver retries in parts and ends on the closed form.
    const auto rows = talus::run_point_case(pc);
    ASSERT_EQ(rows.size(), 6u);
    const double gamma = 0.01; // tolerances as in the closed-form test
    EXPECT_NEAR(rows.back().stress[5], J2Shear::tau(gamma), 1e-9 * J2Shear::sy);
    EXPECT_NEAR(rows.back().state[0], J2Shear::plastic(gamma) / std::sqrt(3.0), 1e-12);
}
