// SolverOptions::material_hook, the seam talus_bench's plugin-overhead A/B
// uses (bench/README.md): the host's own Hooke update must give the plugin's
// run bit for bit, or the A/B would compare different work; and a hook that
// declines must leave the run to the plugins.
#include "inline_hooke.hpp"
#include "solver_helpers.hpp"

#include <gtest/gtest.h>

#include <atomic>
#include <cstring>

namespace {

std::string block_yaml(int dim, const std::string &model_params) {
    const std::string grid = dim == 2 ? "grid: {origin: [0, 0], size: [1, 1], cell: 0.05}\n"
                                      : "grid: {origin: [0, 0, 0], size: [1, 1, 1], cell: 0.1}\n";
    // On the floor and moving into it: the stresses grow from the first
    // step, and every point's increment differs.
    const std::string box = dim == 2 ? "{box: {min: [0.2, 0.0], max: [0.8, 0.5]}}"
                                     : "{box: {min: [0.2, 0.2, 0.0], max: [0.8, 0.7, 0.4]}}";
    const std::string v = dim == 2 ? "[0.3, -1]" : "[0.3, 0, -1]";
    const std::string floor = dim == 2 ? "y-" : "z-";
    const std::string g = dim == 2 ? "[0, -9.81]" : "[0, 0, -9.81]";
    return "talus: 1\ndimension: " + std::to_string(dim) + "\n" + grid + "materials:\n  m: {" +
           model_params + "}\n" +
           "groups:\n  a: {material: m, particles_per_cell: 2, velocity: " + v + ", shape: " + box +
           "}\n" + "boundaries: {" + floor + ": {friction: 0.3}}\ngravity: " + g +
           "\ntime: {end: 1}\n";
}

struct Run {
    talus::PluginRegistry registry;
    talus::Scenario scenario;
    std::unique_ptr<talus::Simulation> sim;
};

std::unique_ptr<Run> run(const std::string &yaml, talus::MaterialBlockHook hook, int steps) {
    unsetenv("TALUS_PLUGIN_PATH");
    auto r = std::make_unique<Run>();
    r->scenario = talus::read_scenario(talus::yaml::load_string(yaml, "hook.yaml"), r->registry);
    talus::SolverOptions so;
    so.material_hook = hook;
    r->sim = std::make_unique<talus::Simulation>(r->scenario, so);
    for (int k = 0; k < steps; ++k)
        r->sim->step(1.0);
    return r;
}

// Byte for byte: == would take -0.0 for +0.0.
bool same_bytes(const talus::Column<double> &a, const talus::Column<double> &b) {
    return a.size() == b.size() &&
           (a.size() == 0 || std::memcmp(a.data(), b.data(), a.size() * sizeof(double)) == 0);
}

void expect_same_bits(const talus::Simulation &a, const talus::Simulation &b) {
    ASSERT_EQ(a.sets().size(), b.sets().size());
    for (std::size_t s = 0; s < a.sets().size(); ++s) {
        const talus::ParticleSet &p = a.sets()[s], &q = b.sets()[s];
        ASSERT_EQ(p.n, q.n);
        for (std::size_t d = 0; d < static_cast<std::size_t>(p.dim); ++d) {
            EXPECT_TRUE(same_bytes(p.x[d], q.x[d])) << "x" << d;
            EXPECT_TRUE(same_bytes(p.v[d], q.v[d])) << "v" << d;
        }
        EXPECT_TRUE(same_bytes(p.stress, q.stress)) << "stress";
        EXPECT_TRUE(same_bytes(p.c, q.c)) << "wave speed";
        EXPECT_TRUE(same_bytes(p.work, q.work)) << "stress work";
    }
}

std::atomic<long> declined{0};
bool decline(const talus::MaterialInstance &, std::size_t, const double *, const double *,
             const double *, double *, double *) {
    ++declined;
    return false;
}

std::atomic<long> taken{0};
bool counting_hooke(const talus::MaterialInstance &m, std::size_t n, const double *s0,
                    const double *de, const double *rho, double *s1, double *c) {
    const bool done = talus::bench::inline_hooke(m, n, s0, de, rho, s1, c);
    if (done) ++taken;
    return done;
}

const char *kElastic = "model: linear_elastic, density: 2000, youngs_modulus: 1.0e7, "
                       "poisson_ratio: 0.3";

} // namespace

// 60 steps of a block driven into the floor: the stresses are far from
// their start (about rho c v = 1e5 Pa) and every point's increment differs.
TEST(MaterialHook, TheHostsHookeUpdateGivesThePluginsRunBitForBit) {
    for (int dim : {2, 3}) {
        const std::string yaml = block_yaml(dim, kElastic);
        taken = 0;
        auto plugin = run(yaml, nullptr, 60);
        auto host = run(yaml, counting_hooke, 60);
        EXPECT_GT(taken.load(), 60) << "the hook took no blocks in " << dim << "D";
        expect_same_bits(*plugin->sim, *host->sim);
        // The hook must have replaced the update, not run beside it: the
        // stresses are not left at their start.
        double largest = 0;
        for (double s : host->sim->sets()[0].stress)
            largest = std::max(largest, std::abs(s));
        EXPECT_GT(largest, 1.0e3);
    }
}

TEST(MaterialHook, AHookThatDeclinesLeavesTheRunToThePlugins) {
    const std::string yaml = block_yaml(2, kElastic);
    declined = 0;
    auto plugin = run(yaml, nullptr, 30);
    auto hooked = run(yaml, decline, 30);
    EXPECT_GT(declined.load(), 30);
    expect_same_bits(*plugin->sim, *hooked->sim);
}

TEST(MaterialHook, TheHostsHookeUpdateTakesNoOtherModel) {
    const std::string yaml =
        block_yaml(2, "model: mohr_coulomb, density: 2000, youngs_modulus: 1.0e7, "
                      "poisson_ratio: 0.3, friction_angle: 30, cohesion: 0");
    taken = 0;
    auto plugin = run(yaml, nullptr, 30);
    auto hooked = run(yaml, counting_hooke, 30);
    EXPECT_EQ(taken.load(), 0);
    expect_same_bits(*plugin->sim, *hooked->sim);
}
