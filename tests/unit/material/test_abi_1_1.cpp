// The ABI 1.1 additions as the host sees them, through two plugins that use
// every one: fixture_abi11_c (plain C on the raw header) and
// fixture_context_sdk (the C++ SDK). The plugins copy what they were given
// into their state, so each test compares it with what the host passed.
#include "one_point_batch.hpp"
#include "test_paths.hpp"

#include <talus/input/material_yaml.hpp>
#include <talus/input/yaml_input.hpp>
#include <talus/material/plugin_loader.hpp>

#include <gtest/gtest.h>

#include <filesystem>

#include <array>
#include <atomic>
#include <cstdint>
#include <string>
#include <thread>
#include <vector>

using talus::test::contains;
using talus::test::fixture;
using talus::test::OnePoint;

namespace {

// The log lines the plugins send while alive.
struct LogCapture {
    std::vector<std::string> lines;
    talus::PluginLogSink previous;
    LogCapture() {
        previous = talus::set_plugin_log_sink([this](const std::string &l) { lines.push_back(l); });
    }
    ~LogCapture() { talus::set_plugin_log_sink(previous); }
};

std::vector<talus::ParamValue> abi11_values(std::vector<double> weights, std::string label,
                                            double n_extra) {
    std::vector<talus::ParamValue> v(4);
    v[0].scalar = 1e6;
    v[1].reals = std::move(weights);
    v[2].text = std::move(label);
    v[3].scalar = n_extra;
    return v;
}

} // namespace

TEST(Abi11, TheRawPluginsDescriptorsAreRead) {
    talus::PluginRegistry reg({}, false);
    const talus::PluginLibrary &lib = reg.load(fixture("abi11_c").string());
    // Built against this header: the minor it was built with.
    EXPECT_EQ(lib.abi_minor(), static_cast<unsigned>(TALUS_ABI_VERSION_MINOR));
    const talus::Model &m = lib.models().at(0);
    EXPECT_EQ(m.qualified_id(), "abi11_fixture/abi11_model");
    EXPECT_FALSE(m.reentrant());
    EXPECT_TRUE(m.instance_state());
    EXPECT_TRUE(m.wants_rotation());
    EXPECT_TRUE(m.has_init_state());
    ASSERT_EQ(m.params().size(), 4u);
    const talus::ParamInfo &w = m.params()[1];
    EXPECT_EQ(w.type, TALUS_PARAM_REAL_ARRAY);
    EXPECT_EQ(w.count_text(), "1 to 4 values");
    EXPECT_EQ(m.params()[2].type, TALUS_PARAM_STRING);
    EXPECT_EQ(m.params()[2].default_param().text, "none");
    EXPECT_EQ(m.params()[2].typical_param().text, "sandy");
    // The library's extension hook answers the id it knows, and only that.
    const void *answer = lib.extension("talus_test.answer");
    ASSERT_NE(answer, nullptr);
    EXPECT_EQ(*static_cast<const int *>(answer), 42);
    EXPECT_EQ(lib.extension("talus_test.other"), nullptr);
    // A 1.0 plugin has no hook: asking is safe.
    const talus::PluginLibrary &old = reg.load(fixture("good_c").string());
    EXPECT_EQ(old.abi_minor(), 0u);
    EXPECT_EQ(old.extension("talus_test.answer"), nullptr);
    EXPECT_FALSE(old.models().at(0).has_init_state());
    // The content hash is a SHA-256 in hex.
    EXPECT_EQ(lib.content_hash().size(), 64u);
    EXPECT_NE(lib.content_hash(), old.content_hash());
}

TEST(Abi11, ListAndStringParametersReachTheModelAndSizeItsState) {
    talus::PluginRegistry reg({}, false);
    const talus::Model &m = reg.load(fixture("abi11_c").string()).models().at(0);
    const auto inst = m.create(abi11_values({1.0, 2.0}, "sandy", 3), {"materials.x", "/tmp"});
    // 5 scalars and `extra` with n_extra = 3 components.
    const talus::StateLayout &layout = inst->state();
    ASSERT_EQ(layout.vars.size(), 6u);
    EXPECT_EQ(layout.size, 8u);
    EXPECT_EQ(layout.vars[5].name, "extra");
    EXPECT_EQ(layout.vars[5].size, 3u);
    EXPECT_EQ(layout.vars[5].offset, 5u);
    EXPECT_EQ(m.state_size(), 0u); // the model's own table is not used
    const auto other = m.create(abi11_values({1.0}, "x", 0));
    EXPECT_EQ(other->state().size, 5u);

    // Set-up: tension in the initial stress is set to zero and reported in
    // the host's log, naming the point; init_mark = 1 + strlen("sandy").
    LogCapture log;
    OnePoint p;
    p.q0 = layout.initial();
    p.s0 = {5.0, -1.0, -2.0, 0.5, 0.0, 0.0};
    talus_batch b = p.batch(0);
    auto r = inst->start(b);
    ASSERT_TRUE(r.ok()) << r.message;
    EXPECT_EQ(p.s1[0], 0.0);
    EXPECT_EQ(p.s1[1], -1.0);
    EXPECT_EQ(p.q1[4], 6.0);
    EXPECT_EQ(p.q1[0], 0.0);  // step 0: the set-up call
    EXPECT_EQ(p.q1[1], 7.0);  // the point id
    EXPECT_EQ(p.q1[2], 0.25); // the characteristic length
    ASSERT_EQ(log.lines.size(), 1u);
    EXPECT_EQ(log.lines[0],
              "warning: plugin abi11_fixture: point 7: tensile initial stress set to zero");

    // An increment: modulus = stiffness * sum(weights) = 3e6; the rotation's
    // Q[1][0] is recorded.
    p.s0 = p.s1;
    p.q0 = p.q1;
    p.de = {1e-6, 0, 0, 0, 0, 0};
    p.R = {0.6, -0.8, 0, 0.8, 0.6, 0, 0, 0, 1};
    b = p.batch(12);
    r = inst->update(b);
    ASSERT_TRUE(r.ok()) << r.message;
    EXPECT_DOUBLE_EQ(p.s1[0], 3.0);
    EXPECT_EQ(p.q1[0], 12.0);
    EXPECT_EQ(p.q1[3], 0.8);
    EXPECT_EQ(p.q1[4], 6.0); // kept from the set-up call
}

TEST(Abi11, ListAndStringParametersAreReadAndCheckedFromYaml) {
    talus::PluginRegistry reg({}, false);
    reg.load(fixture("abi11_c").string());
    auto read = [&](const std::string &body) {
        const auto root = talus::yaml::load_string(body, "m.yaml");
        return talus::read_material(root, reg);
    };
    const talus::MaterialSpec spec =
        read("model: abi11_fixture/abi11_model\ndensity: 1800\nstiffness: 2e6\n"
             "weights: [0.5, 1.5]\nlabel: loose sand\nn_extra: 2\n"
             "initial_state: {extra: [3, 4]}\n");
    EXPECT_EQ(spec.params[1].reals, (std::vector<double>{0.5, 1.5}));
    EXPECT_EQ(spec.params[2].text, "loose sand");
    EXPECT_EQ(spec.state.size, 7u); // the instance's layout
    ASSERT_EQ(spec.initial_state.size(), 7u);
    EXPECT_EQ(spec.initial_state[5], 3.0);
    EXPECT_EQ(spec.initial_state[6], 4.0);
    // A file named without a folder is in the working folder; base_dir
    // says so absolutely, so that nothing resolves through a search path.
    EXPECT_EQ(spec.context.base_dir, std::filesystem::current_path().string());

    auto error_of = [&](const std::string &body) {
        try {
            read(body);
        } catch (const talus::Error &e) {
            return std::string(e.what());
        }
        return std::string("no error");
    };
    const std::string base = "model: abi11_model\ndensity: 1800\nstiffness: 2e6\n";
    EXPECT_TRUE(contains(error_of(base + "weights: 2\n"),
                         "m.yaml:4:10: error: 'weights' expected a list of 1 to 4 values "
                         "(e.g. [1, 1])"))
        << error_of(base + "weights: 2\n");
    EXPECT_TRUE(contains(error_of(base + "weights: [1, 2, 3, 4, 5]\n"),
                         "value [1, 2, 3, 4, 5] is out of range: expected 1 to 4 values, got 5"))
        << error_of(base + "weights: [1, 2, 3, 4, 5]\n");
    EXPECT_TRUE(contains(error_of(base + "weights: [1, 20]\n"),
                         "value #2 (20): expected 0 <= weights <= 10"))
        << error_of(base + "weights: [1, 20]\n");
    EXPECT_TRUE(
        contains(error_of(base), "missing required parameter 'weights' of model 'abi11_model'"))
        << error_of(base);
    // The plugin's own verdict on the values (a zero sum), at the material.
    EXPECT_TRUE(contains(error_of(base + "weights: [0]\n"), "the weights must have a positive sum"))
        << error_of(base + "weights: [0]\n");
    // State variables of the instance's layout only.
    const std::string two = base + "weights: [1]\nn_extra: 2\ninitial_state: {extar: 1}\n";
    EXPECT_TRUE(contains(error_of(two), "did you mean 'extra'")) << error_of(two);
    const std::string none = base + "weights: [1]\ninitial_state: {extra: 1}\n";
    EXPECT_TRUE(contains(error_of(none), "model 'abi11_model' has no state variable a user may "
                                         "initialise"))
        << error_of(none);
}

// The host serialises calls into a model declared not reentrant; the
// fixture fails any call that finds another one running. The same calls
// made straight into the plugin, around the host, do overlap: the check the
// fixture makes is a real one.
TEST(Abi11, CallsIntoANotReentrantModelAreSerialised) {
    talus::PluginRegistry reg({}, false);
    const talus::Model &m = reg.load(fixture("abi11_c").string()).models().at(0);
    const auto inst = m.create(abi11_values({1.0}, "x", 0));
    // A second instance made through the raw descriptor, called raw.
    const std::vector<talus::ParamValue> values = abi11_values({1.0}, "x", 0);
    std::vector<talus_param_value> raw(4);
    std::vector<const talus_param_value *> ptrs(4);
    for (std::size_t i = 0; i < 4; ++i) {
        raw[i] = talus_param_value{sizeof(talus_param_value),
                                   m.params()[i].type,
                                   values[i].reals.empty() ? 1 : values[i].reals.size(),
                                   values[i].scalar,
                                   values[i].reals.data(),
                                   values[i].text.c_str()};
        ptrs[i] = &raw[i];
    }
    const talus_create_args args{sizeof(talus_create_args), 4, ptrs.data(), "raw", ""};
    talus_instance *raw_inst = nullptr;
    talus_error err{};
    err.struct_size = sizeof err;
    ASSERT_EQ(m.raw().create_ex(&args, &raw_inst, &err), TALUS_STATUS_OK) << err.message;

    auto hammer = [&](bool through_host) {
        std::atomic<int> failures{0};
        auto work = [&] {
            OnePoint p;
            p.q0 = inst->state().initial();
            p.de = {1e-6, 0, 0, 0, 0, 0};
            for (int k = 0; k < 300; ++k) {
                talus_batch b = p.batch(1);
                if (through_host) {
                    if (!inst->update(b).ok()) ++failures;
                } else {
                    b.struct_size = sizeof b;
                    b.state_size = inst->state_size();
                    talus_error e{};
                    e.struct_size = sizeof e;
                    if (m.raw().update(raw_inst, &b, &e) != TALUS_STATUS_OK) ++failures;
                }
            }
        };
        std::thread a(work), c(work);
        a.join();
        c.join();
        return failures.load();
    };
    EXPECT_EQ(hammer(true), 0);
    // Two threads of 300 calls of about 20 us each on two cores: they meet.
    EXPECT_GT(hammer(false), 0);
    m.raw().destroy(raw_inst);
}

// The SDK's view of the same additions: ParamValues::list and text, the
// context in PointIn, init_state, log_warning.
TEST(Abi11, TheSdkPassesTheContextToTheModel) {
    talus::PluginRegistry reg({}, false);
    const talus::Model &m = reg.load(fixture("context_sdk").string()).models().at(0);
    EXPECT_TRUE(m.wants_rotation());
    EXPECT_TRUE(m.has_init_state());
    EXPECT_TRUE(m.reentrant());
    std::vector<talus::ParamValue> v(3);
    v[0].scalar = 1e6;
    v[1].reals = {0.5, 0.25, 0.25};
    v[2].text = "clay";
    const auto inst = m.create(v);
    LogCapture log;
    OnePoint p;
    p.q0 = inst->state().initial();
    p.s0 = {-1.0, 2.0, -2.0, 0.0, 0.0, 0.0};
    talus_batch b = p.batch(0);
    auto r = inst->start(b);
    ASSERT_TRUE(r.ok()) << r.message;
    EXPECT_EQ(p.s1[1], 0.0);
    EXPECT_EQ(p.q1[4], 5.0); // 1 + strlen("clay")
    ASSERT_EQ(log.lines.size(), 1u);
    EXPECT_EQ(log.lines[0],
              "warning: plugin context_sdk_fixture: point 7: tensile initial stress set to zero");
    p.s0 = p.s1;
    p.q0 = p.q1;
    p.de = {0, 2e-6, 0, 0, 0, 0};
    p.R = {0.6, -0.8, 0, 0.8, 0.6, 0, 0, 0, 1};
    p.id = 123;
    b = p.batch(5);
    r = inst->update(b);
    ASSERT_TRUE(r.ok()) << r.message;
    EXPECT_DOUBLE_EQ(p.s1[1], 2.0); // 1e6 * (0.5 + 0.25 + 0.25) * 2e-6
    EXPECT_EQ(p.q1[0], 5.0);
    EXPECT_EQ(p.q1[1], 123.0);
    EXPECT_EQ(p.q1[2], 0.25);
    EXPECT_EQ(p.q1[3], 0.8);
    // Without init_state the set-up call goes to update (a 1.0 model).
    const talus::Model &le =
        reg.load((talus::test::plugin_dir() / "talus_linear_elastic.so").string()).models().at(0);
    EXPECT_FALSE(le.has_init_state());
}
