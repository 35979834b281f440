// The loader: every fault a plugin library can have gets its own actionable
// message, the search order is the documented one, and a misbehaving update
// is contained (failure status, never a crash or a NaN reaching the host).
#include "test_paths.hpp"

#include <talus/material/plugin_loader.hpp>

#include <gtest/gtest.h>

#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <fstream>
#include <limits>
#include <span>
#include <string>
#include <vector>

namespace fs = std::filesystem;
using talus::test::contains;
using talus::test::fixture;

namespace {

std::string load_error(const fs::path &file) {
    try {
        talus::PluginLibrary::open(file);
    } catch (const talus::Error &e) {
        return e.what();
    }
    return "(no error)";
}

// A scratch directory removed at the end of the test.
struct TempDir {
    fs::path path;
    TempDir() {
        char tmpl[] = "/tmp/talus_test_XXXXXX";
        path = mkdtemp(tmpl);
    }
    ~TempDir() { fs::remove_all(path); }
};

// Unset TALUS_PLUGIN_PATH for the test and restore it afterwards.
struct EnvGuard {
    std::string old;
    bool had = false;
    EnvGuard() {
        if (const char *v = std::getenv("TALUS_PLUGIN_PATH")) {
            old = v;
            had = true;
        }
        unsetenv("TALUS_PLUGIN_PATH");
    }
    ~EnvGuard() {
        if (had)
            setenv("TALUS_PLUGIN_PATH", old.c_str(), 1);
        else
            unsetenv("TALUS_PLUGIN_PATH");
    }
};

// One point of elastic loading through an instance, for the update tests.
talus::MaterialInstance::Result one_point(const talus::MaterialInstance &m, double *stress_out) {
    const double de[6] = {1e-4, 0, 0, 0, 0, 0};
    const double F[9] = {1, 0, 0, 0, 1, 0, 0, 0, 1};
    const double rho = 1000.0, s0[6] = {0, 0, 0, 0, 0, 0};
    double c = 0.0;
    talus_batch b{};
    b.flags = TALUS_BATCH_WANT_WAVE_SPEED;
    b.n_points = 1;
    b.dt = 1.0;
    b.strain_increment = de;
    b.F_start = F;
    b.F_end = F;
    b.density = &rho;
    b.stress_start = s0;
    b.stress_end = stress_out;
    b.wave_speed = &c;
    return m.update(b);
}

} // namespace

TEST(Loader, LoadsTheShippedLinearElasticPlugin) {
    EnvGuard env;
    talus::PluginRegistry reg;
    const talus::PluginLibrary &lib = reg.load("linear_elastic");
    ASSERT_EQ(lib.models().size(), 1u);
    const talus::Model &m = lib.models()[0];
    EXPECT_EQ(m.id(), "linear_elastic");
    EXPECT_TRUE(m.has_tangent());
    EXPECT_FALSE(m.finite_strain());
    ASSERT_EQ(m.params().size(), 2u);
    EXPECT_EQ(m.params()[0].key, "youngs_modulus");
    EXPECT_EQ(m.params()[0].unit, "Pa");
    EXPECT_TRUE(m.params()[0].required());
    // Bounds are the positive-definiteness conditions, exclusive.
    EXPECT_FALSE(m.params()[0].in_bounds(0.0));
    EXPECT_TRUE(m.params()[0].in_bounds(1.0));
    EXPECT_FALSE(m.params()[1].in_bounds(0.5));
    EXPECT_FALSE(m.params()[1].in_bounds(-1.0));
    EXPECT_TRUE(m.params()[1].in_bounds(0.49));
    EXPECT_EQ(m.state_size(), 0u);
    // The same file loaded twice is one library.
    EXPECT_EQ(&reg.load((talus::test::plugin_dir() / "talus_linear_elastic.so").string()), &lib);
}

TEST(Loader, FileNotFoundListsEveryPlaceSearched) {
    EnvGuard env;
    setenv("TALUS_PLUGIN_PATH", "/env/dir/a:/env/dir/b", 1);
    talus::PluginRegistry reg({"/cli/dir"});
    std::string msg;
    try {
        reg.load("no_such_plugin");
    } catch (const talus::Error &e) {
        msg = e.what();
    }
    // In the documented order: --plugin-path, TALUS_PLUGIN_PATH, build dir.
    const auto p_cli = msg.find("/cli/dir/talus_no_such_plugin.so");
    const auto p_env_a = msg.find("/env/dir/a/talus_no_such_plugin.so");
    const auto p_env_b = msg.find("/env/dir/b/talus_no_such_plugin.so");
    const auto p_build = msg.find((talus::test::plugin_dir() / "talus_no_such_plugin.so").string());
    ASSERT_NE(p_cli, std::string::npos) << msg;
    ASSERT_NE(p_env_a, std::string::npos) << msg;
    ASSERT_NE(p_env_b, std::string::npos) << msg;
    ASSERT_NE(p_build, std::string::npos) << msg;
    EXPECT_LT(p_cli, p_env_a);
    EXPECT_LT(p_env_a, p_env_b);
    EXPECT_LT(p_env_b, p_build);
    EXPECT_TRUE(contains(msg, "--plugin-path")) << msg;
}

TEST(Loader, SearchOrderPrefersPluginPathThenEnvironmentThenBuildDir) {
    EnvGuard env;
    TempDir cli, envdir;
    const fs::path shipped = talus::test::plugin_dir() / "talus_linear_elastic.so";
    fs::copy_file(shipped, cli.path / "talus_linear_elastic.so");
    fs::copy_file(shipped, envdir.path / "talus_linear_elastic.so");
    setenv("TALUS_PLUGIN_PATH", envdir.path.c_str(), 1);
    {
        talus::PluginRegistry reg({cli.path});
        EXPECT_EQ(reg.load("linear_elastic").path().parent_path(), fs::canonical(cli.path));
    }
    {
        talus::PluginRegistry reg;
        EXPECT_EQ(reg.load("linear_elastic").path().parent_path(), fs::canonical(envdir.path));
    }
    {
        talus::PluginRegistry reg({}, /*use_environment=*/false);
        EXPECT_EQ(reg.load("linear_elastic").path().parent_path(),
                  fs::canonical(talus::test::plugin_dir()));
    }
    // A model id found by scanning: the earlier directory shadows the later
    // file of the same name, so there is no duplicate.
    {
        talus::PluginRegistry reg({cli.path});
        EXPECT_EQ(reg.find_model("linear_elastic").library().path().parent_path(),
                  fs::canonical(cli.path));
    }
}

TEST(Loader, ExplicitPathThatDoesNotExist) {
    talus::PluginRegistry reg;
    try {
        reg.load("/nowhere/talus_x.so");
        FAIL() << "expected an error";
    } catch (const talus::Error &e) {
        EXPECT_TRUE(contains(e.what(), "/nowhere/talus_x.so: plugin library not found"))
            << e.what();
    }
}

TEST(Loader, NotALoadableLibraryQuotesDlerror) {
    const std::string msg = load_error(fixture("not_a_library"));
    EXPECT_TRUE(contains(msg, "not a loadable shared library:")) << msg;
    // dlerror's own words about the file (glibc: "invalid ELF header" or
    // "file too short"), so the user sees the real cause.
    EXPECT_TRUE(contains(msg, "ELF") || contains(msg, "too short")) << msg;
}

TEST(Loader, NoEntrySymbol) {
    const std::string msg = load_error(fixture("no_entry"));
    EXPECT_TRUE(contains(msg, "no exported symbol 'talus_material_entry'")) << msg;
}

TEST(Loader, AbiMajorMismatchRefusedByThePlugin) {
    const std::string msg = load_error(fixture("wrong_major"));
    EXPECT_TRUE(contains(msg, "refused to load (host speaks ABI 1.2)")) << msg;
    EXPECT_TRUE(contains(msg, "built for Talus material ABI 2.0")) << msg;
}

TEST(Loader, AbiMajorMismatchCaughtByTheHost) {
    const std::string msg = load_error(fixture("wrong_major_silent"));
    EXPECT_TRUE(contains(msg, "ABI major version mismatch: the plugin was built for Talus material "
                              "ABI 2.0, this host speaks ABI 1.2"))
        << msg;
}

TEST(Loader, InvalidDescriptorNamesTheField) {
    const std::string msg = load_error(fixture("bad_descriptor"));
    EXPECT_TRUE(contains(msg, "invalid plugin descriptor: model 'fixture_model' parameter #0: "
                              "fields 'min_value' (1) and 'max_value' (0) are not an interval"))
        << msg;
}

// A required list parameter whose min_count the host cannot build the
// typical list of (found by the descriptor fuzzer: 4e9 values, 32 GB) is
// refused by name; the largest allowed count, 65536, loads.
TEST(Loader, ListParameterRequiringTooManyValuesIsRefused) {
    auto descriptor_with = [](std::uint32_t min_count, auto &&check) {
        talus_param_desc p{};
        p.struct_size = sizeof p;
        p.type = TALUS_PARAM_REAL_ARRAY;
        p.flags = TALUS_PARAM_REQUIRED;
        p.key = "props";
        p.unit = "-";
        p.doc = "values";
        p.min_value = -HUGE_VAL;
        p.max_value = HUGE_VAL;
        p.typical_value = 1.0;
        p.min_count = min_count;
        const talus_param_desc *params[] = {&p};
        talus_model m{};
        m.struct_size = sizeof m;
        m.n_params = 1;
        m.id = "listed";
        m.name = "listed";
        m.version = "1";
        m.doc = "a model with a list parameter";
        m.params = params;
        m.create = [](const double *, std::uint32_t, talus_instance **, talus_error *) {
            return TALUS_STATUS_FAILED;
        };
        m.destroy = [](talus_instance *) {};
        m.update = [](const talus_instance *, const talus_batch *, talus_error *) {
            return TALUS_STATUS_FAILED;
        };
        m.create_ex = [](const talus_create_args *, talus_instance **, talus_error *) {
            return TALUS_STATUS_FAILED;
        };
        const talus_model *models[] = {&m};
        talus_library lib{};
        lib.struct_size = sizeof lib;
        lib.abi_major = TALUS_ABI_VERSION_MAJOR;
        lib.abi_minor = TALUS_ABI_VERSION_MINOR;
        lib.n_models = 1;
        lib.name = "lists";
        lib.version = "1";
        lib.models = models;
        check(lib);
    };
    descriptor_with(65536, [](const talus_library &lib) {
        const auto loaded = talus::PluginLibrary::from_descriptor(&lib, "lists.so");
        EXPECT_EQ(loaded->models().at(0).params().at(0).typical_param().reals.size(), 65536u);
    });
    descriptor_with(65537, [](const talus_library &lib) {
        try {
            (void)talus::PluginLibrary::from_descriptor(&lib, "lists.so");
            ADD_FAILURE() << "a min_count of 65537 was accepted";
        } catch (const talus::Error &e) {
            EXPECT_TRUE(contains(e.what(), "lists.so: invalid plugin descriptor: model 'listed' "
                                           "parameter #0: field 'min_count' (65537) is above the "
                                           "65536 values"))
                << e.what();
        }
    });
}

// Model ids may repeat across libraries (ABI 1.1 qualified ids): the short
// id is then refused as ambiguous, naming the qualified ids, and the
// qualified id picks one. Two libraries of the same name are refused.
TEST(Loader, RepeatedModelIdNeedsTheQualifiedId) {
    EnvGuard env;
    const auto duplicate = talus::test::fixture_dir() / "scan" / "talus_duplicate.so";
    talus::PluginRegistry explicit_reg;
    explicit_reg.load(fixture("good_c").string());
    explicit_reg.load(duplicate.string());
    try {
        explicit_reg.find_model("good_c_elastic");
        FAIL() << "expected an ambiguity error";
    } catch (const talus::Error &e) {
        EXPECT_TRUE(contains(e.what(), "the material model id 'good_c_elastic' is offered by 2 "
                                       "libraries; name one by its qualified id"))
            << e.what();
        EXPECT_TRUE(contains(e.what(), "good_c_elastic_library/good_c_elastic")) << e.what();
        EXPECT_TRUE(contains(e.what(), "duplicate/good_c_elastic")) << e.what();
    }
    const talus::Model &m = explicit_reg.find_model("duplicate/good_c_elastic");
    EXPECT_EQ(m.library().path(), std::filesystem::weakly_canonical(duplicate));
    EXPECT_EQ(m.qualified_id(), "duplicate/good_c_elastic");
    // A qualified id names its library exactly: an empty one is no library.
    EXPECT_THROW(explicit_reg.find_model("/good_c_elastic"), talus::Error);
    // Found by scanning a directory that holds both.
    talus::PluginRegistry scan_reg({talus::test::fixture_dir() / "scan"});
    try {
        scan_reg.find_model("good_c_elastic");
        FAIL() << "expected an ambiguity error";
    } catch (const talus::Error &e) {
        EXPECT_TRUE(contains(e.what(), "is offered by 2 libraries")) << e.what();
    }
    EXPECT_EQ(scan_reg.find_model("good_c_elastic_library/good_c_elastic").id(), "good_c_elastic");
    // The same library twice under two file names.
    talus::PluginRegistry twice;
    twice.load(fixture("good_c").string());
    try {
        twice.load((talus::test::fixture_dir() / "scan" / "talus_good_c.so").string());
        FAIL() << "expected a repeated library name";
    } catch (const talus::Error &e) {
        EXPECT_TRUE(contains(e.what(), "two plugin libraries are named 'good_c_elastic_library'"))
            << e.what();
    }
}

TEST(Loader, UnknownModelSuggestsTheClosestId) {
    EnvGuard env;
    talus::PluginRegistry reg;
    try {
        reg.find_model("linear_elastik");
        FAIL() << "expected an error";
    } catch (const talus::Error &e) {
        EXPECT_TRUE(contains(e.what(), "no plugin offers the material model 'linear_elastik' (did "
                                       "you mean 'linear_elastic'?)"))
            << e.what();
    }
}

TEST(Loader, SdkGuardTurnsAnExceptionIntoAFailureNamingThePoint) {
    talus::PluginRegistry reg;
    const talus::Model &m = reg.load(fixture("throws_sdk").string()).models()[0];
    const double p[] = {1e6};
    const auto inst = m.create(p);
    double s[6];
    const auto r = one_point(*inst, s);
    EXPECT_EQ(r.status, TALUS_STATUS_FAILED);
    EXPECT_EQ(r.point, 0);
    EXPECT_FALSE(r.host_detected);
    EXPECT_TRUE(contains(r.message, "exception at point 0: the model gave up on purpose"))
        << r.message;
}

TEST(Loader, ExceptionEscapingARawPluginIsContained) {
    talus::PluginRegistry reg;
    const talus::Model &m = reg.load(fixture("throws_raw").string()).models()[0];
    const double p[] = {1e7, 0.3};
    const auto inst = m.create(p);
    double s[6];
    const auto r = one_point(*inst, s);
    EXPECT_EQ(r.status, TALUS_STATUS_FAILED);
    EXPECT_TRUE(contains(r.message, "exception escaped")) << r.message;
}

// The host's screen of a plugin's outputs: a NaN stress returned with
// status OK becomes a failure naming the point, whoever wrote the plugin.
static void expect_host_catches_nan(const std::string &fixture_name,
                                    std::span<const double> params) {
    talus::PluginRegistry reg;
    const talus::Model &m = reg.load(fixture(fixture_name).string()).models()[0];
    const auto inst = m.create(params);
    double s[6];
    const auto r = one_point(*inst, s);
    EXPECT_EQ(r.status, TALUS_STATUS_FAILED);
    EXPECT_TRUE(r.host_detected);
    EXPECT_EQ(r.point, 0);
    EXPECT_TRUE(contains(r.message, "returned status OK but a non-finite stress")) << r.message;
}

TEST(Loader, NaNFromAPluginNeverReachesTheHost) {
    const double p[] = {1e7, 0.3};
    expect_host_catches_nan("returns_nan", p);
}

// The SDK screens inputs only; its models' outputs go through the same
// host screen.
TEST(Loader, NaNFromAnSdkPluginIsCaughtByTheHostsScreen) {
    const double p[] = {1e6};
    expect_host_catches_nan("nan_sdk", p);
}

// The SDK's screen of a batch's inputs (one pass over the whole batch,
// then a search for the point): every kind of bad value, at every point of
// a batch, fails the call naming that point, and no earlier point hides it.
TEST(Loader, TheSdkNamesThePointWithANonFiniteOrInvalidInput) {
    talus::PluginRegistry reg;
    const talus::Model &m = reg.load("linear_elastic").models()[0];
    const double p[] = {1e7, 0.3};
    const auto inst = m.create(p);
    // The instance keeps what it was made from (provenance, the benchmark's
    // inlined Hooke update).
    ASSERT_EQ(inst->parameters().size(), 2u);
    EXPECT_EQ(inst->parameters()[0].scalar, p[0]);
    EXPECT_EQ(inst->parameters()[1].scalar, p[1]);
    // Longer than two of the screens' vector loops (16 values a turn with
    // AVX-512) and a remainder, so that a bad point is met in every part.
    constexpr std::size_t n = 37;
    const double inf = std::numeric_limits<double>::infinity();
    const double nan = std::numeric_limits<double>::quiet_NaN();
    struct Bad {
        const char *what;
        double value;
        int array; // 0 strain increment, 1 stress, 2 density
        std::size_t component;
    };
    const Bad bads[] = {{"NaN strain", nan, 0, 3},        {"inf strain", -inf, 0, 5},
                        {"NaN stress", nan, 1, 0},        {"inf stress", inf, 1, 4},
                        {"NaN density", nan, 2, 0},       {"zero density", 0.0, 2, 0},
                        {"negative density", -1.0, 2, 0}, {"inf density", inf, 2, 0}};
    // With TALUS_BATCH_INPUTS_FINITE (the host says it has screened them)
    // the SDK leaves its screen out, and a value that was bad after all
    // comes out as a non-finite stress or a wave speed that is not positive
    // and finite (infinite, NaN or, from an infinite density, zero), which
    // the host's screen of the outputs catches at the same point: still an
    // error.
    for (const bool host_screened : {false, true})
        for (const Bad &bad : bads)
            for (std::size_t at = 0; at < n; ++at) {
                std::vector<double> de(6 * n, 1e-6), s0(6 * n, -1e3), F(9 * n, 0.0), rho(n, 2000.0);
                for (std::size_t k = 0; k < n; ++k)
                    F[9 * k] = F[9 * k + 4] = F[9 * k + 8] = 1.0;
                std::vector<double> s1(6 * n), c(n);
                if (bad.array == 0) de[6 * at + bad.component] = bad.value;
                if (bad.array == 1) s0[6 * at + bad.component] = bad.value;
                if (bad.array == 2) rho[at] = bad.value;
                talus_batch b{};
                b.flags =
                    TALUS_BATCH_WANT_WAVE_SPEED | (host_screened ? TALUS_BATCH_INPUTS_FINITE : 0u);
                b.n_points = n;
                b.dt = 1e-3;
                b.strain_increment = de.data();
                b.F_start = F.data();
                b.F_end = F.data();
                b.density = rho.data();
                b.stress_start = s0.data();
                b.stress_end = s1.data();
                b.wave_speed = c.data();
                const auto r = inst->update(b);
                const std::string where = std::string(bad.what) + " at " + std::to_string(at) +
                                          (host_screened ? ", inputs said finite" : "");
                EXPECT_EQ(r.status, TALUS_STATUS_FAILED) << where;
                EXPECT_EQ(r.host_detected, host_screened) << where;
                EXPECT_EQ(r.point, static_cast<std::int64_t>(at)) << where;
                EXPECT_EQ(contains(r.message, "non-finite input"), !host_screened) << r.message;
            }
}

TEST(Loader, CreateReportsThePluginsRejection) {
    talus::PluginRegistry reg;
    const talus::Model &m = reg.load("linear_elastic").models()[0];
    const double too_few[] = {1e7};
    try {
        m.create(too_few);
        FAIL() << "expected an error";
    } catch (const talus::Error &e) {
        EXPECT_TRUE(contains(e.what(), "1 parameter values given, 2 expected")) << e.what();
    }
}

TEST(Loader, CheckParameterExplainsBounds) {
    talus::ParamInfo nu{"poisson_ratio",
                        "-",
                        "",
                        TALUS_PARAM_REAL,
                        TALUS_PARAM_MIN_EXCLUSIVE | TALUS_PARAM_MAX_EXCLUSIVE,
                        0.0,
                        -1.0,
                        0.5,
                        0.3};
    EXPECT_EQ(talus::check_parameter(nu, 0.3), "");
    EXPECT_EQ(talus::check_parameter(nu, 0.5), "expected -1 < poisson_ratio < 0.5 (unit -)");
    talus::ParamInfo n{"iterations", "-", "", TALUS_PARAM_INTEGER, 0, 10, 1, 100, 10};
    EXPECT_EQ(talus::check_parameter(n, 2.5), "expected an integer");
    EXPECT_EQ(talus::check_parameter(n, 0.0), "expected 1 <= iterations <= 100 (unit -)");
    EXPECT_EQ(talus::check_parameter(n, NAN), "expected a finite number");
}

namespace {

// A batch of n points for the path fixtures (pairs_sdk, groups_sdk): the
// points quick(k) picks have a zero strain increment (the quick pass takes
// them), the others 1e-4 along x; F = I, density 1000, state: the tag k,
// ids k + 1000.
struct PathBatch {
    std::size_t n;
    std::vector<double> de, F, rho, c, tag;
    std::vector<std::int64_t> ids;
    template <class Quick>
    PathBatch(std::size_t points, Quick quick)
        : n(points), de(6 * n, 0.0), F(9 * n, 0.0), rho(n, 1000.0), c(n, 0.0), tag(n), ids(n) {
        for (std::size_t k = 0; k < n; ++k) {
            de[6 * k] = quick(k) ? 0.0 : 1e-4;
            for (int i = 0; i < 3; ++i)
                F[9 * k + 4 * static_cast<std::size_t>(i)] = 1.0;
            ids[k] = static_cast<std::int64_t>(k) + 1000;
            tag[k] = static_cast<double>(k);
        }
    }
    // The batch through inst, in place or into separate end arrays: the
    // end stresses in s1, the end states in q1.
    template <class Instance>
    auto run(const Instance &inst, bool in_place, std::vector<double> &s1,
             std::vector<double> &q1) {
        std::vector<double> s0(6 * n, 0.0), q0 = tag;
        s1.assign(6 * n, -1.0);
        q1.assign(n, -1.0);
        talus_batch b{};
        b.flags = TALUS_BATCH_WANT_WAVE_SPEED;
        b.n_points = n;
        b.dt = 1.0;
        b.strain_increment = de.data();
        b.F_start = F.data();
        b.F_end = F.data();
        b.density = rho.data();
        b.stress_start = in_place ? s1.data() : s0.data();
        b.state_start = in_place ? q1.data() : q0.data();
        b.stress_end = s1.data();
        b.state_end = q1.data();
        b.wave_speed = c.data();
        b.point_id = ids.data();
        if (in_place) {
            std::fill(s1.begin(), s1.end(), 0.0);
            q1 = tag;
        }
        return inst.update(b);
    }
    // The points of the chunk from c0 (64 points) the quick pass leaves, in
    // order.
    std::vector<std::size_t> left_in_chunk(std::size_t c0) const {
        std::vector<std::size_t> rest;
        for (std::size_t k = c0; k < std::min(n, c0 + 64); ++k)
            if (de[6 * k] != 0.0) rest.push_back(k);
        return rest;
    }
    // What every path gives: the quick points' marker, the start state as
    // the model saw it, the end state and the wave speed.
    void expect_every_point(const std::vector<double> &s1, const std::vector<double> &q1) const {
        for (std::size_t k = 0; k < n; ++k) {
            if (de[6 * k] == 0.0) {
                EXPECT_EQ(s1[6 * k], 1.0) << k;
            }
            EXPECT_EQ(s1[6 * k + 1], tag[k]) << k;
            EXPECT_EQ(q1[k], tag[k] + 100.0) << k;
            EXPECT_EQ(c[k], 1.0) << k;
        }
    }
    // A failing point (strain increment[1] > 0) is reported by its index.
    template <class Instance>
    void expect_failure_named(const Instance &inst, std::size_t k) {
        de[6 * k + 1] = 1.0;
        std::vector<double> s1, q1;
        const auto r = run(inst, false, s1, q1);
        EXPECT_EQ(r.status, TALUS_STATUS_FAILED);
        EXPECT_EQ(r.point, static_cast<std::int64_t>(k));
        const std::string want = "exception at point " + std::to_string(k) + ": point " +
                                 std::to_string(k + 1000) + " refuses";
        EXPECT_NE(r.message.find(want), std::string::npos) << r.message;
    }
};

} // namespace

// The SDK's batch loop with a model's optional quick pass and pair update
// (the fixture's outputs say which path each point took): the quick pass
// sees each chunk of at most 64 points with the end state already a copy
// of the start state; the points it leaves go to update_pair two at a time
// in order, the odd one out of a chunk to update; in place as well as not.
// A failure inside a pair names the point that failed, not the pair's
// first.
TEST(Loader, SdkBatchLoopQuickPassPairsAndTheFailingPoint) {
    talus::PluginRegistry reg;
    const talus::Model &m = reg.load(fixture("pairs_sdk").string()).models()[0];
    const double p[] = {1e6};
    const auto inst = m.create(p);
    // Chunks of 64, 64 and 22; every third point is quick.
    PathBatch batch(150, [](std::size_t k) { return k % 3 == 0; });
    for (const bool in_place : {false, true}) {
        SCOPED_TRACE(in_place ? "in place" : "separate arrays");
        std::vector<double> s1, q1;
        const auto r = batch.run(*inst, in_place, s1, q1);
        ASSERT_TRUE(r.ok()) << r.message;
        for (std::size_t c0 = 0; c0 < batch.n; c0 += 64) {
            const std::vector<std::size_t> rest = batch.left_in_chunk(c0);
            for (std::size_t j = 0; j < rest.size(); ++j) {
                const double path = rest.size() % 2 == 1 && j + 1 == rest.size() ? 3.0 : 2.0;
                EXPECT_EQ(s1[6 * rest[j]], path) << rest[j];
            }
        }
        batch.expect_every_point(s1, q1);
    }
    // Point 5 is the second of the first chunk's second pair (the points
    // left: 1 2, 4 5, 7 8, ...).
    batch.expect_failure_named(*inst, 5);
}

// The same with a group update: the points the quick pass leaves go to
// update_group in order, kGroupSize (8) at a time and the rest of a chunk
// as one smaller group, a lone last point to update; in place as well as
// not. A failure inside a group names the point that failed.
TEST(Loader, SdkBatchLoopGroupsAndTheFailingPoint) {
    talus::PluginRegistry reg;
    const talus::Model &m = reg.load(fixture("groups_sdk").string()).models()[0];
    const double p[] = {1e6};
    const auto inst = m.create(p);
    // Chunks of 64, 64 and 22. Every third point is quick, and from 128 on
    // every other: the last chunk leaves 11 points (a group of 8, one of 3).
    PathBatch batch(150, [](std::size_t k) { return k < 128 ? k % 3 == 0 : k % 2 == 0; });
    for (const bool in_place : {false, true}) {
        SCOPED_TRACE(in_place ? "in place" : "separate arrays");
        std::vector<double> s1, q1;
        const auto r = batch.run(*inst, in_place, s1, q1);
        ASSERT_TRUE(r.ok()) << r.message;
        std::size_t groups_seen = 0;
        for (std::size_t c0 = 0; c0 < batch.n; c0 += 64) {
            const std::vector<std::size_t> rest = batch.left_in_chunk(c0);
            // Groups of 8 from the chunk's start, the remainder one group.
            for (std::size_t j = 0; j < rest.size(); ++j) {
                const std::size_t size = std::min<std::size_t>(8, rest.size() - j / 8 * 8);
                if (size == 1) {
                    EXPECT_EQ(s1[6 * rest[j]], 3.0) << rest[j];
                } else {
                    EXPECT_EQ(s1[6 * rest[j]], 4.0) << rest[j];
                    EXPECT_EQ(s1[6 * rest[j] + 2], static_cast<double>(size)) << rest[j];
                    groups_seen += j % 8 == 0;
                }
            }
        }
        EXPECT_EQ(groups_seen, 6u + 6u + 2u); // 42, 43 and 11 points left
        batch.expect_every_point(s1, q1);
    }
    // Point 11 is the last of the first chunk's first group (the points
    // left: 1 2 4 5 7 8 10 11 ...).
    batch.expect_failure_named(*inst, 11);
}
