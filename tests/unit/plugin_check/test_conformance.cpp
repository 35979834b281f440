// The conformance suite passes correct plugins and fails each broken one on
// the check that its fault breaks: every check is shown able to fail.
#include "test_paths.hpp"

#include <talus/plugin_check/conformance.hpp>

#include <gtest/gtest.h>

#include <set>
#include <sstream>

using talus::test::contains;
using talus::test::fixture;

namespace {

const talus::CheckOutcome *find(const talus::ConformanceReport &r, const std::string &name) {
    for (const auto &o : r.outcomes)
        if (o.name == name) return &o;
    return nullptr;
}

std::string dump(const talus::ConformanceReport &r) {
    std::ostringstream s;
    talus::print_report(s, r);
    return s.str();
}

} // namespace

TEST(Conformance, LinearElasticPassesEveryCheck) {
    const auto rep = talus::check_plugin(talus::test::plugin_dir() / "talus_linear_elastic.so",
                                         talus::CheckOptions{});
    EXPECT_TRUE(rep.passed()) << dump(rep);
    std::set<std::string> names;
    for (const auto &o : rep.outcomes)
        names.insert(o.name);
    for (const char *n :
         {"exports", "load", "create", "loading paths", "zero increment", "batch size", "in place",
          "tangent", "wave speed", "nan input", "threads", "fp environment"})
        EXPECT_TRUE(names.count(n)) << "check '" << n << "' did not run\n" << dump(rep);
}

TEST(Conformance, PlainCPluginPasses) {
    const auto rep = talus::check_plugin(fixture("good_c"), talus::CheckOptions{});
    EXPECT_TRUE(rep.passed()) << dump(rep);
}

TEST(Conformance, InProcessModeGivesTheSameVerdict) {
    talus::CheckOptions opt;
    opt.isolate = false;
    EXPECT_TRUE(
        talus::check_plugin(talus::test::plugin_dir() / "talus_linear_elastic.so", opt).passed());
    EXPECT_FALSE(talus::check_plugin(fixture("wrong_tangent"), opt).passed());
}

TEST(Conformance, UnknownParameterOverrideIsReported) {
    talus::CheckOptions opt;
    opt.params = {{"youngs_modulus", "2e8"}, {"poison_ratio", "0.2"}};
    const auto rep =
        talus::check_plugin(talus::test::plugin_dir() / "talus_linear_elastic.so", opt);
    const auto *c = find(rep, "create");
    ASSERT_NE(c, nullptr) << dump(rep);
    EXPECT_FALSE(c->passed);
    EXPECT_TRUE(contains(c->detail, "--param poison_ratio: the model has no such parameter"))
        << c->detail;
    // A value that is not of the parameter's type, or out of its bounds.
    opt.params = {{"youngs_modulus", "2e8x"}};
    const auto rep1 =
        talus::check_plugin(talus::test::plugin_dir() / "talus_linear_elastic.so", opt);
    c = find(rep1, "create");
    ASSERT_NE(c, nullptr);
    EXPECT_TRUE(contains(c->detail, "--param youngs_modulus=2e8x: '2e8x' is not a number"))
        << c->detail;
    opt.params = {{"poisson_ratio", "0.5"}};
    const auto rep2 =
        talus::check_plugin(talus::test::plugin_dir() / "talus_linear_elastic.so", opt);
    c = find(rep2, "create");
    ASSERT_NE(c, nullptr);
    EXPECT_TRUE(contains(c->detail, "expected -1 < poisson_ratio < 0.5")) << c->detail;
}

// A 1.1 plugin with list, string and integer parameters, an instance state
// layout, init_state and the batch context passes the checks at its typical
// values, and takes list and string overrides.
TEST(Conformance, AbiOnePointOnePluginPasses) {
    talus::CheckOptions opt;
    opt.isolate = false;
    const auto rep = talus::check_plugin(fixture("abi11_c"), opt);
    EXPECT_TRUE(rep.passed()) << dump(rep);
    const auto *c = find(rep, "create");
    ASSERT_NE(c, nullptr);
    EXPECT_TRUE(contains(c->detail, "weights=[1], label=\"sandy\", n_extra=2")) << c->detail;
    opt.params = {{"weights", "1,2.5"}, {"label", "clay"}};
    const auto rep3 = talus::check_plugin(fixture("abi11_c"), opt);
    c = find(rep3, "create");
    ASSERT_NE(c, nullptr);
    EXPECT_TRUE(contains(c->detail, "weights=[1, 2.5], label=\"clay\"")) << c->detail;
    opt.params = {{"weights", "1,2,3,4,5"}};
    const auto rep4 = talus::check_plugin(fixture("abi11_c"), opt);
    c = find(rep4, "create");
    ASSERT_NE(c, nullptr);
    EXPECT_FALSE(c->passed);
    EXPECT_TRUE(contains(c->detail, "expected 1 to 4 values, got 5")) << c->detail;
}

struct BrokenCase {
    const char *fixture;
    const char *check;  // the check that must fail
    const char *detail; // a phrase its message must contain
};

class BrokenFixture : public testing::TestWithParam<BrokenCase> {};

TEST_P(BrokenFixture, FailsTheRightCheckWithTheRightMessage) {
    const BrokenCase &c = GetParam();
    const auto rep = talus::check_plugin(fixture(c.fixture), talus::CheckOptions{});
    EXPECT_FALSE(rep.passed()) << dump(rep);
    const talus::CheckOutcome *o = find(rep, c.check);
    ASSERT_NE(o, nullptr) << "no outcome for check '" << c.check << "'\n" << dump(rep);
    EXPECT_FALSE(o->passed) << dump(rep);
    EXPECT_TRUE(contains(o->detail, c.detail)) << "expected '" << c.detail << "' in: " << o->detail;
}

INSTANTIATE_TEST_SUITE_P(
    Conformance, BrokenFixture,
    testing::Values(
        BrokenCase{"no_entry", "load", "no exported symbol 'talus_material_entry'"},
        BrokenCase{"no_entry", "exports", "found 0"},
        BrokenCase{"not_a_library", "load", "not a loadable shared library"},
        BrokenCase{"wrong_major", "load", "built for Talus material ABI 2.0"},
        BrokenCase{"wrong_major_silent", "load", "ABI major version mismatch"},
        BrokenCase{"bad_descriptor", "load", "fields 'min_value' (1) and 'max_value' (0)"},
        BrokenCase{"extra_export", "exports", "talus_helper_leaked"},
        BrokenCase{"returns_nan", "loading paths", "returned status OK but a non-finite stress"},
        BrokenCase{"throws_sdk", "loading paths", "the model gave up on purpose"},
        BrokenCase{"throws_raw", "loading paths", "exception escaped"},
        BrokenCase{"crashes", "loading paths", "during this check"},
        BrokenCase{"zero_drift", "zero increment", "largest relative change"},
        BrokenCase{"batch_dependent", "batch size", "largest relative difference"},
        BrokenCase{"aliasing", "in place", "largest relative difference"},
        BrokenCase{"wrong_tangent", "tangent", "entry D[3][3]"},
        BrokenCase{"swallows_nan", "nan input", "the plugin returned OK"},
        BrokenCase{"fp_env", "fp environment",
                   "create of model 'fixture_model': rounding upward instead of to nearest"},
        BrokenCase{"not_objective", "objectivity", "largest difference from R sigma R^T"},
        BrokenCase{"nondeterministic", "determinism", "gave different outputs for the same"},
        BrokenCase{"overruns", "buffers", "update wrote 1 value(s) past the end of stress_end"},
        BrokenCase{"ftz_at_load", "fp environment",
                   "loading the library (its constructors; -ffast-math sets flush-to-zero as a "
                   "library loads): flush-to-zero on; denormals-are-zero on"}),
    [](const testing::TestParamInfo<BrokenCase> &i) {
        return std::string(i.param.fixture) + "_" + std::to_string(i.index);
    });
