// The material-point driver: peer test vectors, closed-form paths, cut-step
// sub-stepping, and the errors a user sees for bad case files.
#include "solver_helpers.hpp"

#include <talus/point_driver.hpp>

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
        (talus::test::source_dir() / "configs/point/linear_elastic_oedometer.yaml").string());
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
    talus::write_point_csv(csv, pc.instance->model(), talus::run_point_case(pc));
    std::string header, first;
    std::istringstream in(csv.str());
    std::getline(in, header);
    std::getline(in, first);
    EXPECT_EQ(header, "time,eps_xx,eps_yy,eps_zz,eps_xy,eps_yz,eps_xz,sig_xx,sig_yy,sig_zz,sig_xy,"
                      "sig_yz,sig_xz,p,q,calls");
    // p = -tr/3 = 200; q = sqrt(3 J2) with J2 = ((100)^2 + 0 + (100)^2)/2 + 10^2 = 10100.
    EXPECT_TRUE(contains(first, ",-100,-200,-300,10,0,0,200," +
                                    fmt::format("{:.17g}", std::sqrt(3.0 * 10100.0)) + ",0"))
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
        EXPECT_TRUE(contains(err.what(), "failed in the increment starting at t = 0: exception at "
                                         "point 0: the model gave up on purpose"))
            << err.what();
    }
}
