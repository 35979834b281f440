// The material-point driver: peer test vectors, closed-form paths, cut-step
// sub-stepping, and the errors a user sees for bad case files.
#include "solver_helpers.hpp"

#include <talus/driver/point_driver.hpp>

#include <Eigen/Dense>
#include <gtest/gtest.h>

#include <fmt/format.h>

#include <cmath>
#include <fstream>
#include <sstream>

using talus::test::contains;

namespace {

// Unset TALUS_PLUGIN_PATH so the shipped plugins come from this build.
struct NoEnv {
    NoEnv() { unsetenv("TALUS_PLUGIN_PATH"); }
};

std::vector<talus::PointRow> run_text(const std::string &yaml, talus::PluginRegistry &reg) {
    const talus::yaml::Node root = talus::yaml::load_string(yaml, "case.yaml");
    const talus::PointCase pc = talus::read_point_case(root, reg);
    return talus::run_point_case(pc);
}

std::string error_of(const std::string &yaml) {
    NoEnv e;
    talus::PluginRegistry reg;
    try {
        run_text(yaml, reg);
    } catch (const talus::Error &err) {
        return err.what();
    }
    return "(no error)";
}

} // namespace

// Every row of the peer's linear-elastic unit-test vectors (E = 1e7,
// nu = 0.3, from zero stress), reproduced through the driver and the plugin
// binary. The peer's values are printed to 16-17 digits and the model is two
// multiply-adds per component, so 1e-9 relative is generous.
TEST(PointDriver, ReproducesPeerLinearElasticVectors) {
    NoEnv e;
    const auto rows =
        talus::test::read_numeric_csv(talus::test::data_dir() / "cbgeo_linear_elastic_vectors.csv");
    ASSERT_EQ(rows.size(), 4u);
    talus::PluginRegistry reg;
    for (std::size_t r = 0; r < rows.size(); ++r) {
        const auto &v = rows[r];
        ASSERT_EQ(v.size(), 12u);
        // Engineering shear in the file, tensor components in the driver.
        const std::string yaml =
            fmt::format("talus: 1\n"
                        "material: {{model: linear_elastic, density: 1000, youngs_modulus: 1.0e7, "
                        "poisson_ratio: 0.3}}\n"
                        "time: {{end: 1.0, increments: 1}}\n"
                        "strain:\n"
                        "  xx: [[0, 0], [1, {:.17g}]]\n  yy: [[0, 0], [1, {:.17g}]]\n  zz: [[0, "
                        "0], [1, {:.17g}]]\n"
                        "  xy: [[0, 0], [1, {:.17g}]]\n  yz: [[0, 0], [1, {:.17g}]]\n  xz: [[0, "
                        "0], [1, {:.17g}]]\n",
                        v[0], v[1], v[2], v[3] / 2, v[4] / 2, v[5] / 2);
        const auto out = run_text(yaml, reg);
        ASSERT_EQ(out.size(), 2u);
        const auto &sig = out.back().stress;
        double scale = 0.0;
        for (int k = 0; k < 6; ++k)
            scale = std::max(scale, std::abs(v[6 + static_cast<std::size_t>(k)]));
        for (int k = 0; k < 6; ++k)
            EXPECT_NEAR(sig[k], v[6 + static_cast<std::size_t>(k)], 1e-9 * scale)
                << "row " << r << " component " << k;
    }
}

// The shipped oedometer case against its closed form at every output row:
// sig_xx = s0 + M eps_xx, sig_yy = sig_zz = s0 + lambda eps_xx. The path is
// linear in each increment and the model is exact for any increment size,
// so only round-off separates them: 1e-10 of the stress.
TEST(PointDriver, OedometerConfigMatchesClosedForm) {
    NoEnv e;
    talus::PluginRegistry reg;
    const auto root = talus::yaml::load_file(
        (talus::test::source_dir() / "plugins/linear_elastic/cases/oedometer.yaml").string());
    const talus::PointCase pc = talus::read_point_case(root, reg);
    const auto rows = talus::run_point_case(pc);
    ASSERT_EQ(rows.size(), 41u);
    const double E = 2.0e7, nu = 0.3;
    const double lambda = E * nu / ((1 + nu) * (1 - 2 * nu)), G = E / (2 * (1 + nu));
    for (const auto &r : rows) {
        const double eps = r.time <= 1.0 ? -0.01 * r.time : -0.01 + 0.005 * (r.time - 1.0);
        EXPECT_NEAR(r.strain[0], eps, 1e-15);
        EXPECT_NEAR(r.stress[0], -1e4 + (lambda + 2 * G) * eps, 1e-10 * 3e5) << "t = " << r.time;
        EXPECT_NEAR(r.stress[1], -1e4 + lambda * eps, 1e-10 * 3e5) << "t = " << r.time;
        EXPECT_NEAR(r.stress[2], -1e4 + lambda * eps, 1e-10 * 3e5) << "t = " << r.time;
        EXPECT_EQ(r.stress[3], 0.0);
    }
}

// A cut-step request is honoured by sub-stepping. The fixture refuses
// increments above 2e-4 with factor 0.5, so each 1e-3 increment is halved
// three times (1e-3 -> 5e-4 -> 2.5e-4 -> 1.25e-4): 8 accepted calls per
// increment, and the elastic result is the closed form regardless.
TEST(PointDriver, CutStepRequestsAreSubStepped) {
    NoEnv e;
    talus::PluginRegistry reg({talus::test::fixture_dir()});
    const auto rows =
        run_text("talus: 1\n"
                 "plugins: [fixture_cut_step]\n"
                 "material: {model: picky_elastic, density: 1000, youngs_modulus: 1.0e7, "
                 "poisson_ratio: 0.25}\n"
                 "time: {end: 5.0, increments: 5}\n"
                 "strain: {yy: [[0, 0], [5, 0.005]]}\n",
                 reg);
    ASSERT_EQ(rows.size(), 6u);
    EXPECT_EQ(rows.back().state.at(0), 40.0);
    const double E = 1e7, nu = 0.25;
    const double lambda = E * nu / ((1 + nu) * (1 - 2 * nu)), G = E / (2 * (1 + nu));
    EXPECT_NEAR(rows.back().stress[1], (lambda + 2 * G) * 0.005, 1e-9 * E * 0.005);
    EXPECT_NEAR(rows.back().stress[0], lambda * 0.005, 1e-9 * E * 0.005);
}

TEST(PointDriver, PiecewiseLinearInterpolatesAndHoldsEnds) {
    const talus::PiecewiseLinear f({{1.0, 2.0}, {3.0, 6.0}, {4.0, 0.0}});
    EXPECT_EQ(f(0.0), 2.0);
    EXPECT_EQ(f(1.0), 2.0);
    EXPECT_EQ(f(2.0), 4.0);
    EXPECT_EQ(f(3.5), 3.0);
    EXPECT_EQ(f(10.0), 0.0);
}

TEST(PointDriver, CsvHeaderAndInvariants) {
    NoEnv e;
    talus::PluginRegistry reg({talus::test::fixture_dir()});
    const auto root = talus::yaml::load_string("talus: 1\nplugins: [fixture_cut_step]\n"
                                               "material: {model: picky_elastic, density: 1, "
                                               "youngs_modulus: 1.0e7, poisson_ratio: 0.25}\n"
                                               "initial_stress: [-100, -200, -300, 10, 0, 0]\n"
                                               "time: {end: 1, increments: 1}\nstrain: {}\n",
                                               "c.yaml");
    const talus::PointCase pc = talus::read_point_case(root, reg);
    std::ostringstream csv;
    talus::write_point_csv(csv, *pc.instance, pc.axis, talus::run_point_case(pc));
    std::string header, first;
    std::istringstream in(csv.str());
    std::getline(in, header);
    std::getline(in, first);
    EXPECT_EQ(header, "time,stage,eps_xx,eps_yy,eps_zz,eps_xy,eps_yz,eps_xz,sig_xx,sig_yy,sig_zz,"
                      "sig_xy,sig_yz,sig_xz,p,q,eps_v,eps_q,eps_a,sig_a,sig_r,q_a,calls");
    // p = -tr/3 = 200; q = sqrt(3 J2) with J2 = ((100)^2 + 0 + (100)^2)/2 + 10^2 = 10100;
    // axis z: sig_a = 300, sig_r = (100 + 200)/2 = 150, q_a = 150 (compression positive).
    EXPECT_TRUE(contains(first, ",-100,-200,-300,10,0,0,200," +
                                    fmt::format("{:.17g}", std::sqrt(3.0 * 10100.0)) +
                                    ",0,0,0,300,150,150,0"))
        << first;
}

TEST(PointDriverErrors, MisspeltParameterSuggestsTheRightKey) {
    const std::string msg = error_of("talus: 1\nmaterial:\n  model: linear_elastic\n  density: 1\n"
                                     "  poisson_ratio: 0.3\n  yongs_modulus: 1e7\n"
                                     "time: {end: 1, increments: 1}\nstrain: {}\n");
    EXPECT_TRUE(contains(msg, "case.yaml:6:3: error: unknown key 'material.yongs_modulus'; did you "
                              "mean 'youngs_modulus'?"))
        << msg;
}

TEST(PointDriverErrors, ValueOutOfBoundsStatesTheBounds) {
    const std::string msg = error_of("talus: 1\nmaterial: {model: linear_elastic, density: 1, "
                                     "youngs_modulus: 1e7, poisson_ratio: 0.5}\n"
                                     "time: {end: 1, increments: 1}\nstrain: {}\n");
    EXPECT_TRUE(contains(msg, "case.yaml:2:83: error: 'material.poisson_ratio' value 0.5 is out of "
                              "range: expected -1 < poisson_ratio < 0.5 (unit -)"))
        << msg;
}

TEST(PointDriverErrors, WrongTypeSaysANumberWasExpected) {
    const std::string msg = error_of("talus: 1\nmaterial: {model: linear_elastic, density: 1, "
                                     "youngs_modulus: stiff, poisson_ratio: 0.3}\n"
                                     "time: {end: 1, increments: 1}\nstrain: {}\n");
    EXPECT_TRUE(contains(msg, "'material.youngs_modulus' expected a number, got 'stiff'")) << msg;
}

TEST(PointDriverErrors, MissingRequiredParameterIsDescribed) {
    const std::string msg =
        error_of("talus: 1\nmaterial: {model: linear_elastic, density: 1, "
                 "poisson_ratio: 0.3}\ntime: {end: 1, increments: 1}\nstrain: {}\n");
    EXPECT_TRUE(contains(msg,
                         "missing required parameter 'youngs_modulus' of model 'linear_elastic': "
                         "Young's modulus E. (unit Pa, expected youngs_modulus > 0, e.g. 1e+07)"))
        << msg;
}

TEST(PointDriverErrors, UnknownModelAndUnknownTopLevelKey) {
    EXPECT_TRUE(contains(error_of("talus: 1\nmaterial: {model: mohr_colomb, density: 1}\n"
                                  "time: {end: 1, increments: 1}\nstrain: {}\n"),
                         "case.yaml:2:19: error: 'material.model' no plugin offers the material "
                         "model 'mohr_colomb'"));
    EXPECT_TRUE(contains(error_of("talus: 1\nmaterial: {model: linear_elastic, density: 1, "
                                  "youngs_modulus: 1e7, poisson_ratio: 0.3}\n"
                                  "time: {end: 1, increments: 1}\nstrian: {}\n"),
                         "case.yaml:4:1: error: unknown key 'strian'; did you mean 'strain'?"));
}

TEST(PointDriverErrors, PathMustBeWellFormed) {
    const std::string head = "talus: 1\nmaterial: {model: linear_elastic, density: 1, "
                             "youngs_modulus: 1e7, poisson_ratio: 0.3}\n";
    EXPECT_TRUE(
        contains(error_of(head + "time: {end: 1, increments: 1}\nstrain: {xx: [[0, 0], [0, 1]]}\n"),
                 "times must increase strictly"));
    EXPECT_TRUE(contains(error_of(head + "time: {end: 1, increments: 0}\nstrain: {}\n"),
                         "expected 1 <= increments"));
    EXPECT_TRUE(contains(error_of(head + "time: {end: 1, increments: 1}\nstrain: {xq: 0}\n"),
                         "unknown key 'strain.xq'"));
    EXPECT_TRUE(contains(error_of("talus: 2\n"), "unsupported file format version 2"));
    EXPECT_TRUE(contains(
        error_of(head + "initial_stress: [1, 2]\ntime: {end: 1, increments: 1}\nstrain: {}\n"),
        "expected 6 stress components"));
}

TEST(PointDriverErrors, PluginFailureNamesModelAndTime) {
    NoEnv e;
    talus::PluginRegistry reg({talus::test::fixture_dir()});
    try {
        run_text("talus: 1\nplugins: [fixture_throws_sdk]\n"
                 "material: {model: thrower, density: 1, stiffness: 1e6}\n"
                 "time: {end: 1, increments: 2}\nstrain: {xx: [[0, 0], [1, 1e-3]]}\n",
                 reg);
        FAIL() << "expected a failure";
    } catch (const talus::Error &err) {
        EXPECT_TRUE(contains(err.what(), "model 'thrower' (")) << err.what();
        EXPECT_TRUE(contains(err.what(), "stage 'path' (number 1), t = 0: model 'thrower'"))
            << err.what();
        EXPECT_TRUE(
            contains(err.what(), "failed: exception at point 0: the model gave up on purpose"))
            << err.what();
    }
}

namespace {

std::string mc_material(double phi, double c, double psi, double E, double nu) {
    return fmt::format("material: {{model: mohr_coulomb, density: 1800, youngs_modulus: {:.17g}, "
                       "poisson_ratio: {:.17g}, friction_angle: {:.17g}, cohesion: {:.17g}, "
                       "dilation_angle: {:.17g}, tension_cutoff: 1.0e12}}\n",
                       E, nu, phi, c, psi);
}

double q_of(const talus::PointRow &r, const talus::PointCase &pc, const char *name) {
    return *talus::point_quantity(r, *pc.instance, pc.axis, name);
}

} // namespace

// Every row of tests/data/mc_triaxial_drained.csv (compression positive):
// a drained triaxial (CID) preset from the isotropic state, stopped by an
// exit condition the moment the point yields, then sheared on. Checked:
// the axial and volumetric strain at yield and the peak deviator to 1e-8
// relative (the reference's closed form prints 10 digits; the driver lands
// on the yield point to 2^-45 of an increment and converges Newton to 1e-10
// of the stress), the deviator staying at its peak, and the post-yield
// dilatancy ratio d eps_v / d eps_a to 1e-8 (perfect plasticity: the elastic
// strains stop changing, so the ratio is the flow rule's -2 sin psi / (1 -
// sin psi) exactly).
TEST(PointDriver, MohrCoulombDrainedTriaxialMatchesEveryClosedFormRow) {
    NoEnv e;
    const auto rows =
        talus::test::read_numeric_csv(talus::test::data_dir() / "mc_triaxial_drained.csv");
    ASSERT_EQ(rows.size(), 21u);
    talus::PluginRegistry reg;
    for (std::size_t k = 0; k < rows.size(); ++k) {
        const auto &v = rows[k];
        const double phi = v[0], c = v[1], psi = v[2], E = v[3], nu = v[4], s3 = v[5];
        const double qf = v[7], ea_y = v[10], ev_y = v[11], dil = v[12];
        SCOPED_TRACE(fmt::format("row {}: phi {} c {} psi {} sigma3 {}", k, phi, c, psi, s3));
        const std::string yaml = fmt::format(
            "talus: 1\n{}initial_stress: [{}, {}, {}, 0, 0, 0]\n"
            "stages:\n"
            "  - {{name: to yield, preset: triaxial_drained, axial_strain: {:.17g}, "
            "increments: 40, until: 'yield_mode > 0.5'}}\n"
            "  - {{name: beyond, preset: triaxial_drained, axial_strain: {:.17g}, increments: "
            "20}}\n",
            mc_material(phi, c, psi, E, nu), -s3, -s3, -s3, 2.0 * ea_y, ea_y);
        const auto root = talus::yaml::load_string(yaml, "cid.yaml");
        const talus::PointCase pc = talus::read_point_case(root, reg);
        const auto out = talus::run_point_case(pc);
        // The last row of stage 1 is the yield point.
        std::size_t y = 0;
        for (std::size_t i = 0; i < out.size(); ++i)
            if (out[i].stage == 1) y = i;
        EXPECT_NEAR(q_of(out[y], pc, "eps_a"), ea_y, 1e-8 * ea_y);
        EXPECT_NEAR(q_of(out[y], pc, "eps_v"), ev_y, 1e-8 * ev_y);
        EXPECT_NEAR(q_of(out[y], pc, "q_a"), qf, 1e-8 * qf);
        double peak = 0.0;
        for (const auto &r : out)
            peak = std::max(peak, q_of(r, pc, "q_a"));
        EXPECT_NEAR(peak, qf, 1e-8 * qf);
        EXPECT_NEAR(q_of(out.back(), pc, "q_a"), qf, 1e-8 * qf);
        const auto &a = out[out.size() - 2], &b = out.back();
        const double ratio = (q_of(b, pc, "eps_v") - q_of(a, pc, "eps_v")) /
                             (q_of(b, pc, "eps_a") - q_of(a, pc, "eps_a"));
        EXPECT_NEAR(ratio, dil, 1e-8 * std::max(1.0, std::abs(dil)));
    }
}

// The undrained (constant volume) triaxial of Mohr-Coulomb against its
// closed form, derived from the model (compression positive; elastic
// relations d eps_v = dp'/K, d eps_q = dq/3G as in Wood, Soil Behaviour
// and Critical State Soil Mechanics, 1990, ch. 3):
//   elastic: p' = p0, q = 3G eps_a (eps_v = 0 makes eps_q = eps_a);
//   at yield on the compression edge q = M p' + k, M = 6 sin phi / (3 -
//   sin phi), k = 6 c cos phi / (3 - sin phi);
//   after: the flow on the edge gives d eps_v^p = -N d eps_q^p, N = 6 sin
//   psi / (3 - sin psi); constant volume makes d eps_v^p = -dp'/K, so
//   dp'/d eps_a = 1 / (M / 3G + 1 / (K N)) and q = M p' + k: the path
//   climbs the failure line (dilation raises p').
// 1e-8 of p0 at every row: the rows are increment ends, where the return is
// exact and Newton converged to 1e-10.
TEST(PointDriver, MohrCoulombUndrainedTriaxialFollowsTheClosedFormPath) {
    NoEnv e;
    talus::PluginRegistry reg;
    const double E = 2e7, nu = 0.25, phi = 32, psi = 8, c = 5e3, p0 = 150e3;
    const std::string yaml = fmt::format(
        "talus: 1\n{}initial_stress: [{}, {}, {}, 0, 0, 0]\n"
        "stages:\n  - {{preset: triaxial_undrained, axial_strain: 0.04, increments: 160}}\n",
        mc_material(phi, c, psi, E, nu), -p0, -p0, -p0);
    const auto root = talus::yaml::load_string(yaml, "ciu.yaml");
    const talus::PointCase pc = talus::read_point_case(root, reg);
    const auto out = talus::run_point_case(pc);
    const double K = E / (3 * (1 - 2 * nu)), G = E / (2 * (1 + nu));
    const double sp = std::sin(phi * M_PI / 180), sq = std::sin(psi * M_PI / 180);
    const double M = 6 * sp / (3 - sp), k = 6 * c * std::cos(phi * M_PI / 180) / (3 - sp);
    const double N = 6 * sq / (3 - sq);
    const double qy = M * p0 + k, ea_y = qy / (3 * G);
    const double S = 1.0 / (M / (3 * G) + 1.0 / (K * N));
    int plastic = 0;
    for (const auto &r : out) {
        const double ea = q_of(r, pc, "eps_a");
        const double p = ea <= ea_y ? p0 : p0 + S * (ea - ea_y);
        const double q = ea <= ea_y ? 3 * G * ea : M * p + k;
        EXPECT_NEAR(q_of(r, pc, "p"), p, 1e-8 * p0) << "eps_a " << ea;
        EXPECT_NEAR(q_of(r, pc, "q_a"), q, 1e-8 * p0) << "eps_a " << ea;
        // Newton stops when every condition holds to 1e-10 of the stress
        // scale, a strain row weighted by the modulus M: 1e-10 |sigma| / M
        // is ~2e-12 here.
        EXPECT_NEAR(q_of(r, pc, "eps_v"), 0.0, 5e-12);
        plastic += ea > ea_y;
    }
    EXPECT_GT(plastic, 100);                        // most of the path is on the failure line
    EXPECT_GT(q_of(out.back(), pc, "p"), 1.5 * p0); // and it climbs it
}

// A preset is shorthand for the general form: the drained triaxial written
// out by hand (axial strain imposed, the other five stresses held) gives the
// same rows bit for bit; the undrained one with its two constraints too.
TEST(PointDriver, PresetsEqualTheirGeneralForm) {
    NoEnv e;
    talus::PluginRegistry reg;
    const std::string head = "talus: 1\n" + mc_material(30, 1e4, 5, 1e7, 0.3) +
                             "initial_stress: [-1e5, -1e5, -1e5, 0, 0, 0]\nstages:\n";
    auto run = [&](const std::string &stages) {
        const auto root = talus::yaml::load_string(head + stages, "p.yaml");
        const talus::PointCase pc = talus::read_point_case(root, reg);
        return talus::run_point_case(pc);
    };
    const auto pairs = std::vector<std::pair<std::string, std::string>>{
        {"  - {preset: triaxial_drained, axial_strain: 0.03, increments: 30}\n",
         "  - increments: 30\n    control: {zz: {strain_change: -0.03}}\n"},
        {"  - {preset: triaxial_undrained, axial_strain: 0.03, increments: 30}\n",
         "  - increments: 30\n    control: {zz: {strain_change: -0.03}}\n    free: [xx, yy]\n"
         "    constraints:\n      - {strain: {xx: 1, yy: 1, zz: 1}, change: 0}\n"
         "      - {stress: {xx: 1, yy: -1}}\n"},
    };
    for (const auto &[preset, general] : pairs) {
        const auto a = run(preset), b = run(general);
        ASSERT_EQ(a.size(), b.size());
        for (std::size_t i = 0; i < a.size(); ++i) {
            EXPECT_EQ(a[i].stress, b[i].stress) << preset;
            EXPECT_EQ(a[i].strain, b[i].strain) << preset;
        }
    }
}

// Cyclic simple shear at constant volume (DSS) on Mohr-Coulomb: the cycles
// are there (the shear strain reaches +-amplitude), the stress never leaves
// the surface (every stress the model returns is admissible), the volume
// stays constant, and the point yields.
TEST(PointDriver, CyclicSimpleShearPresetCyclesWithinTheStrength) {
    NoEnv e;
    talus::PluginRegistry reg;
    const std::string yaml =
        "talus: 1\n" + mc_material(30, 0, 0, 1e7, 0.3) +
        "initial_stress: [-5e4, -5e4, -1e5, 0, 0, 0]\nstages:\n"
        "  - {preset: cyclic_simple_shear, amplitude: 0.01, cycles: 3, increments: 25}\n";
    const auto root = talus::yaml::load_string(yaml, "dss.yaml");
    const talus::PointCase pc = talus::read_point_case(root, reg);
    const auto out = talus::run_point_case(pc);
    ASSERT_EQ(out.back().stage, 9); // 3 cycles x 3 legs
    double gmax = 0, gmin = 0;
    for (const auto &r : out) {
        gmax = std::max(gmax, 2 * r.strain[5]);
        gmin = std::min(gmin, 2 * r.strain[5]);
        EXPECT_NEAR(q_of(r, pc, "eps_v"), 0.0, 5e-12); // as in the undrained test
        // Mohr-Coulomb with c = 0, phi = 30: (s1 - s3) <= -(s1 + s3) sin phi.
        Eigen::Matrix3d s;
        s << r.stress[0], r.stress[3], r.stress[5], r.stress[3], r.stress[1], r.stress[4],
            r.stress[5], r.stress[4], r.stress[2];
        const Eigen::Vector3d l = Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d>(s).eigenvalues();
        // 1e-9 of the stress: the model's surface test allows 1e-10 of it,
        // and this eigen solve adds a few ulps.
        EXPECT_LE((l[2] - l[0]) + (l[2] + l[0]) * 0.5, 1e-9 * 1e5);
    }
    // The shear strain is a strain condition: met to 1e-10 |sigma| / M
    // (~1e-12 in gamma here) like the volume above.
    EXPECT_NEAR(gmax, 0.01, 5e-12);
    EXPECT_NEAR(gmin, -0.01, 5e-12);
    EXPECT_GT(q_of(out.back(), pc, "plastic_deviatoric_strain"), 0.0);
}

// Exit conditions: a stage that never meets its condition is an error
// naming the stage, the condition and where the quantity got to.
TEST(PointDriverErrors, ExitConditionNeverReachedIsAnError) {
    const std::string m =
        error_of("talus: 1\n" + mc_material(30, 0, 0, 1e7, 0.3) +
                 "initial_stress: [-1e5, -1e5, -1e5, 0, 0, 0]\nstages:\n"
                 "  - {name: shear, preset: triaxial_drained, axial_strain: 0.05, increments: 50, "
                 "until: 'q_a >= 3e5'}\n");
    EXPECT_TRUE(contains(m, "stage 'shear' (number 1)")) << m;
    EXPECT_TRUE(contains(m, "without reaching 'q_a >= 3e5' (q_a = 200000")) << m;
}

// Bad stage input: unknown preset with a suggestion, a constraint count that
// does not match the free components, an unknown exit variable.
TEST(PointDriverErrors, StageInputIsChecked) {
    const std::string head = "talus: 1\n" + mc_material(30, 0, 0, 1e7, 0.3) + "stages:\n";
    EXPECT_TRUE(contains(error_of(head + "  - {preset: triaxial_drianed, axial_strain: 0.1, "
                                         "increments: 5}\n"),
                         "unknown preset 'triaxial_drianed' (did you mean 'triaxial_drained'?)"));
    EXPECT_TRUE(contains(error_of(head + "  - {increments: 5, free: [xx]}\n"),
                         "0 constraint(s) but 1 free component(s)"));
    EXPECT_TRUE(contains(error_of(head + "  - {increments: 5, control: {zz: {strain_change: "
                                         "-0.1}}, until: 'qq >= 5'}\n"),
                         "names an unknown quantity 'qq'"));
    EXPECT_TRUE(contains(error_of(head + "  - {increments: 5, control: {zz: {strian: 0.1}}}\n"),
                         "did you mean 'strain'"));
}

// Objectivity through the driver's rigid rotation: a pre-stressed point
// rotated by 120 degrees about a skew axis keeps its stress invariants and
// its stress turns with the body (sigma = R sigma0 R^T), for the
// strain-increment Mohr-Coulomb (the driver rotates the stress exactly and
// hands a zero strain increment) and the finite-strain Neo-Hookean (stress
// from F = R F0, here after a stretch). 1e-9 of the stress: 60 rotation
// increments each round the stress at 1e-16.
TEST(PointDriver, RigidRotationKeepsTheInvariantsForBothModels) {
    NoEnv e;
    talus::PluginRegistry reg;
    const std::string rot =
        "  - {name: turn, rotation: {axis: [1, 2, 3], angle: 120}, increments: 60}\n";
    const std::vector<std::string> cases = {
        "talus: 1\n" + mc_material(30, 1e4, 5, 1e7, 0.3) +
            "initial_stress: [-1e5, -6e4, -8e4, 1e4, -5e3, 2e3]\nstages:\n" + rot,
        "talus: 1\nmaterial: {model: neo_hookean, density: 1000, youngs_modulus: 1e6, "
        "poisson_ratio: 0.3}\nstages:\n"
        "  - {increments: 10, control: {xx: {strain_change: 0.2}, yy: {strain_change: -0.1}, "
        "xy: {strain_change: 0.05}}}\n" +
            rot,
    };
    for (const std::string &yaml : cases) {
        const auto root = talus::yaml::load_string(yaml, "rot.yaml");
        const talus::PointCase pc = talus::read_point_case(root, reg);
        const auto out = talus::run_point_case(pc);
        std::size_t s0 = 0;
        for (std::size_t i = 0; i < out.size(); ++i)
            if (out[i].stage < out.back().stage) s0 = i;
        const Eigen::Vector3d n = Eigen::Vector3d(1, 2, 3).normalized();
        const Eigen::Matrix3d R = Eigen::AngleAxisd(120 * M_PI / 180, n).toRotationMatrix();
        auto mat = [](const Eigen::Matrix<double, 6, 1> &s) {
            Eigen::Matrix3d m;
            m << s[0], s[3], s[5], s[3], s[1], s[4], s[5], s[4], s[2];
            return m;
        };
        const Eigen::Matrix3d before = mat(out[s0].stress), after = mat(out.back().stress);
        const double scale = before.cwiseAbs().maxCoeff();
        ASSERT_GT(scale, 1e3) << pc.instance->model().id();
        EXPECT_LT((after - R * before * R.transpose()).cwiseAbs().maxCoeff(), 1e-9 * scale)
            << pc.instance->model().id();
        EXPECT_NEAR(after.trace(), before.trace(), 1e-9 * scale);
        EXPECT_NEAR(q_of(out.back(), pc, "q"), q_of(out[s0], pc, "q"), 1e-9 * scale);
        EXPECT_NEAR(after.determinant(), before.determinant(), 1e-9 * std::pow(scale, 3));
    }
}

// A laboratory file drives a stage: the measured axial strain (percent,
// compression positive) and cell pressure (kPa) of a drained triaxial test
// at their times. At every row the lateral stresses equal the cell pressure
// read from the file and the axial strain the measured one (to the Newton
// tolerance, 1e-10 of the stress); where the cell pressure is constant the
// result equals the drained triaxial preset's (the same conditions).
TEST(PointDriver, LabFileDrivesTheComponentsItNames) {
    NoEnv e;
    const std::filesystem::path dir = std::filesystem::temp_directory_path() / "talus_lab_test";
    std::filesystem::create_directories(dir);
    {
        std::ofstream f(dir / "lab.csv");
        f << "# a drained triaxial record\nt_s, axial_pct, cell_kpa\n";
        for (int k = 0; k <= 10; ++k)
            f << fmt::format("{}, {}, {}\n", 2.0 * k, 0.3 * k,
                             k <= 5 ? 50.0 : 50.0 + 4.0 * (k - 5));
    }
    const std::string mat = "talus: 1\n" + mc_material(30, 0, 5, 1e7, 0.3) +
                            "initial_stress: [-5e4, -5e4, -5e4, 0, 0, 0]\nstages:\n";
    talus::PluginRegistry reg;
    const auto root = talus::yaml::load_string(
        mat + "  - name: lab\n    lab_file:\n      file: lab.csv\n      time: t_s\n"
              "      columns:\n        zz: {strain: axial_pct, scale: -0.01}\n"
              "        xx: {stress: cell_kpa, scale: -1000}\n"
              "        yy: {stress: cell_kpa, scale: -1000}\n",
        (dir / "case.yaml").string());
    const talus::PointCase pc = talus::read_point_case(root, reg);
    ASSERT_EQ(pc.stages[0].increments, 10);
    EXPECT_EQ(pc.stages[0].duration, 20.0);
    const auto out = talus::run_point_case(pc);
    ASSERT_EQ(out.size(), 11u);
    for (int k = 0; k <= 10; ++k) {
        const auto &r = out[static_cast<std::size_t>(k)];
        const double cell = (k <= 5 ? 50.0 : 50.0 + 4.0 * (k - 5)) * 1000.0;
        EXPECT_NEAR(r.stress[0], -cell, 1e-10 * 3e5) << "row " << k;
        EXPECT_NEAR(r.stress[1], -cell, 1e-10 * 3e5) << "row " << k;
        // A strain condition: met to 1e-10 |sigma| / M, ~2e-12 here.
        EXPECT_NEAR(r.strain[2], -0.003 * k, 5e-12) << "row " << k;
    }
    const auto preset = talus::read_point_case(
        talus::yaml::load_string(mat + "  - {preset: triaxial_drained, axial_strain: 0.015, "
                                       "increments: 5}\n",
                                 "p.yaml"),
        reg);
    const auto ref = talus::run_point_case(preset);
    for (std::size_t k = 0; k <= 5; ++k)
        // Both runs converge to 1e-10 of the stress (up to 3e5 Pa here).
        EXPECT_NEAR(q_of(out[k], pc, "q_a"), q_of(ref[k], preset, "q_a"), 1e-9 * 3e5) << k;
    std::filesystem::remove_all(dir);
}

// A prescribed deformation gradient: simple shear F = I + gamma e_x e_y of
// the Neo-Hookean model against its closed form (b = F F^T, J = 1: sigma =
// mu (b - I), so sigma_xx = mu gamma^2, sigma_xy = mu gamma, the rest 0),
// through 20 increments of the F table (the model computes from F_end, so
// the path does not matter). 1e-12 of mu: a few roundings of b.
TEST(PointDriver, PrescribedDeformationGradientGivesTheClosedFormSimpleShear) {
    NoEnv e;
    talus::PluginRegistry reg;
    const auto root = talus::yaml::load_string(
        "talus: 1\nmaterial: {model: neo_hookean, density: 1000, youngs_modulus: 2.6e6, "
        "poisson_ratio: 0.3}\nstages:\n"
        "  - {increments: 20, deformation_gradient: {xy: [[0, 0], [1, 0.8]]}}\n",
        "shear.yaml");
    const talus::PointCase pc = talus::read_point_case(root, reg);
    const auto out = talus::run_point_case(pc);
    ASSERT_EQ(out.size(), 21u);
    const double mu = 2.6e6 / 2.6;
    for (std::size_t k = 0; k < out.size(); ++k) {
        const double g = 0.8 * static_cast<double>(k) / 20.0;
        const auto &s = out[k].stress;
        EXPECT_NEAR(s[0], mu * g * g, 1e-12 * mu) << k;
        EXPECT_NEAR(s[3], mu * g, 1e-12 * mu) << k;
        for (int c : {1, 2, 4, 5})
            EXPECT_NEAR(s[c], 0.0, 1e-12 * mu) << k << " component " << c;
    }
}
