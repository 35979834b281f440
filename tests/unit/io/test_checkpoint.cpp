// Checkpoints: a snapshot through an HDF5 file and back continues a run bit
// for bit, across a stage change and a material switch, and so does one
// in the older layout of plane strain's F; a checkpoint of
// other binaries is refused, naming the difference; a file that is not a
// checkpoint is refused.
#include "solver_helpers.hpp"

#include <talus/driver/run.hpp>
#include <talus/io/checkpoint.hpp>

#include <gtest/gtest.h>

#include <fmt/format.h>

#include <algorithm>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <limits>
#include <sstream>

namespace {

namespace fs = std::filesystem;

// A Mohr-Coulomb block (plugin state) settling under gravity, then
// weakened: a stage change and a material switch within the run.
const std::string kScenario =
    "talus: 1\ndimension: 2\ngrid: {origin: [0, 0], size: [1, 0.6], cell: 0.05}\n"
    "materials:\n"
    "  soil: {model: mohr_coulomb, density: 2000, youngs_modulus: 1.0e7, poisson_ratio: 0.3, "
    "friction_angle: 35, dilation_angle: 0, cohesion: 5.0e3}\n"
    "  weak: {model: mohr_coulomb, density: 2000, youngs_modulus: 1.0e7, poisson_ratio: 0.3, "
    "friction_angle: 15, dilation_angle: 0, cohesion: 100}\n"
    "groups:\n  block: {material: soil, shape: {box: {min: [0.1, 0], max: [0.5, 0.4]}}, "
    "initial_stress: {geostatic: {k0: 0.5}}}\n"
    "boundaries: {y-: {friction: 0.5}}\ngravity: [0, -9.81]\n"
    "stages:\n  - {name: settle, duration: 0.02, damping: {type: local, coefficient: 0.7}}\n"
    "  - {name: weak, duration: 0.05, set_material: {block: weak}}\n";

// Runs to the end, changing stage when one ends.
void finish(talus::Simulation &sim) {
    for (;;) {
        while (sim.stage_end_reached() == talus::StageEnd::running)
            sim.step(sim.stage_end() - sim.time());
        if (sim.stage() + 1 == sim.stages().size()) return;
        sim.begin_next_stage();
    }
}

void expect_same_particles(const talus::Simulation &a, const talus::Simulation &b) {
    ASSERT_EQ(a.steps(), b.steps());
    EXPECT_EQ(a.time(), b.time());
    ASSERT_EQ(a.sets().size(), b.sets().size());
    for (std::size_t k = 0; k < a.sets().size(); ++k) {
        const talus::ParticleSet &p = a.sets()[k], &q = b.sets()[k];
        ASSERT_EQ(p.n, q.n);
        EXPECT_TRUE(p.id == q.id);
        EXPECT_TRUE(p.x[0] == q.x[0] && p.x[1] == q.x[1]);
        EXPECT_TRUE(p.v[0] == q.v[0] && p.v[1] == q.v[1]);
        EXPECT_TRUE(p.stress == q.stress);
        EXPECT_TRUE(p.state == q.state);
        EXPECT_TRUE(p.F == q.F);
    }
}

} // namespace

// Checkpoints taken in the first stage and in the second, written and read
// back, continue to the state of the run never interrupted, bit for bit.
TEST(Checkpoint, AFileWrittenAndReadContinuesTheRunBitForBit) {
    const fs::path dir = fs::temp_directory_path() / "talus_checkpoint_test";
    fs::create_directories(dir);
    auto whole = talus::test::sim_from_text(kScenario);
    finish(*whole->sim);
    for (const long at : {40L, 200L}) {
        auto first = talus::test::sim_from_text(kScenario);
        talus::Simulation &sim = *first->sim;
        for (;;) {
            while (sim.steps() < at && sim.stage_end_reached() == talus::StageEnd::running)
                sim.step(sim.stage_end() - sim.time());
            if (sim.steps() == at) break;
            sim.begin_next_stage();
        }
        talus::Checkpoint c;
        c.scenario_text = kScenario;
        c.state = sim.snapshot();
        c.plugins = talus::plugin_identities(first->scenario);
        const fs::path file = dir / "c.h5";
        talus::write_checkpoint(file, c);
        const talus::Checkpoint back = talus::read_checkpoint(file);
        EXPECT_EQ(back.scenario_text, kScenario);
        EXPECT_TRUE(
            talus::identity_differences(back, talus::plugin_identities(first->scenario)).empty());
        auto second = talus::test::sim_from_text(kScenario);
        talus::Simulation resumed(second->scenario, {}, back.state);
        EXPECT_EQ(resumed.stage(), at == 40 ? 0u : 1u);
        finish(resumed);
        expect_same_particles(*whole->sim, resumed);
    }
    fs::remove_all(dir);
}

// A checkpoint whose particles hold a value that is not finite is damaged
// (a run never keeps one: the step that makes one fails), and the plugins
// are told their inputs are finite: the restart is refused, naming the
// column and the particle, whichever column it is in.
TEST(Checkpoint, ANonFiniteParticleValueIsRefused) {
    auto first = talus::test::sim_from_text(kScenario);
    for (int k = 0; k < 5; ++k)
        first->sim->step(1.0);
    const talus::Snapshot good = first->sim->snapshot();
    for (const char *column : {"state", "stress", "x", "F"}) {
        talus::Snapshot bad = good;
        std::vector<talus::Snapshot::Column> &cols = bad.sets.at(0).columns;
        const auto it =
            std::find_if(cols.begin(), cols.end(), [&](const auto &c) { return c.name == column; });
        ASSERT_NE(it, cols.end()) << column;
        const std::size_t particle = 7;
        const double nan = std::numeric_limits<double>::quiet_NaN();
        // Its second value (the only one of a scalar column).
        const std::size_t at = it->stride * particle + (it->stride > 1 ? 1 : 0);
        std::memcpy(it->bytes.data() + sizeof(double) * at, &nan, sizeof nan);
        auto second = talus::test::sim_from_text(kScenario);
        try {
            talus::Simulation resumed(second->scenario, {}, bad);
            ADD_FAILURE() << "a NaN in '" << column << "' was restored";
        } catch (const talus::Error &e) {
            const std::string msg = e.what();
            EXPECT_NE(msg.find(fmt::format("non-finite value (nan) in '{}' of particle {}", column,
                                           first->sim->sets()[0].id[particle])),
                      std::string::npos)
                << msg;
        }
    }
}

// Formats 1 and 2 kept a plane-strain particle's F whole, 9 values; now
// it is the in-plane block (ParticleSet::F). Such a snapshot continues as
// the run itself does, bit for bit, and one whose F leaves the plane
// (F_zz not 1, or an out-of-plane shear) is refused as damaged.
TEST(Checkpoint, APlaneStrainFOfNineValuesStillRestores) {
    auto whole = talus::test::sim_from_text(kScenario);
    for (int k = 0; k < 5; ++k)
        whole->sim->step(1.0);
    talus::Snapshot old = whole->sim->snapshot();
    const std::int64_t third_id = whole->sim->sets()[0].id[3]; // the particle made wrong below
    std::vector<talus::Snapshot::Column> &cols = old.sets.at(0).columns;
    const auto F =
        std::find_if(cols.begin(), cols.end(), [](const auto &c) { return c.name == "F"; });
    ASSERT_NE(F, cols.end());
    ASSERT_EQ(F->stride, 4u);
    const std::size_t n = old.sets[0].n;
    std::vector<double> in(4 * n), full(9 * n, 0.0);
    std::memcpy(in.data(), F->bytes.data(), F->bytes.size());
    for (std::size_t p = 0; p < n; ++p) {
        const double *f = &in[4 * p];
        double *g = &full[9 * p];
        g[0] = f[0], g[1] = f[1], g[3] = f[2], g[4] = f[3], g[8] = 1.0;
    }
    F->stride = 9;
    F->bytes.resize(full.size() * sizeof(double));
    std::memcpy(F->bytes.data(), full.data(), F->bytes.size());
    auto second = talus::test::sim_from_text(kScenario);
    talus::Simulation resumed(second->scenario, {}, old);
    for (int k = 0; k < 20; ++k) {
        whole->sim->step(1.0);
        resumed.step(1.0);
    }
    expect_same_particles(*whole->sim, resumed);

    // F_zz and an out-of-plane shear leave the plane; a NaN in the plane
    // (F_yx) is caught by the check every column gets, once converted.
    for (const int component : {8, 5, 3}) {
        talus::Snapshot bad = old;
        auto &c = *std::find_if(bad.sets[0].columns.begin(), bad.sets[0].columns.end(),
                                [](const auto &col) { return col.name == "F"; });
        const double value = component == 8   ? 1.01
                             : component == 5 ? 0.01
                                              : std::numeric_limits<double>::quiet_NaN();
        std::memcpy(c.bytes.data() + sizeof(double) * (9 * 3 + component), &value, sizeof value);
        auto third = talus::test::sim_from_text(kScenario);
        try {
            talus::Simulation resumed_bad(third->scenario, {}, bad);
            ADD_FAILURE() << "an F with component " << component << " " << value << " restored";
        } catch (const talus::Error &e) {
            const std::string msg = e.what();
            const std::string expected =
                component == 3 ? fmt::format("non-finite value (nan) in 'F' of particle {}: the "
                                             "checkpoint is damaged",
                                             third_id)
                               : fmt::format("F out of the plane at particle {}", third_id);
            EXPECT_NE(msg.find(expected), std::string::npos) << msg;
        }
    }
}

// A plugin file that changed since the checkpoint is named with the
// change, and the restart is refused unless forced.
TEST(Checkpoint, OtherPluginBinariesAreRefusedNamingTheDifference) {
    auto s = talus::test::sim_from_text(kScenario);
    talus::Checkpoint written;
    written.scenario_text = kScenario;
    written.plugins = talus::plugin_identities(s->scenario);
    written.state = s->sim->snapshot();
    const fs::path file = fs::temp_directory_path() / "talus_checkpoint_identity.h5";
    talus::write_checkpoint(file, written);
    talus::Checkpoint c = talus::read_checkpoint(file); // stamped with this Talus
    fs::remove(file);
    c.plugins[1].sha256 = "0123";
    c.plugins[0].library_version = "0.9.0";
    const auto diff = talus::identity_differences(c, talus::plugin_identities(s->scenario));
    ASSERT_EQ(diff.size(), 2u);
    EXPECT_NE(diff[0].find("material 'soil': the library version was 0.9.0, is now"),
              std::string::npos)
        << diff[0];
    EXPECT_NE(diff[1].find("material 'weak': the plugin's SHA-256 was 0123, is now "),
              std::string::npos)
        << diff[1];
    talus::RunOptions opt;
    opt.restart = &c;
    opt.output_dir = fs::temp_directory_path();
    std::ostringstream log;
    try {
        talus::run_scenario(s->scenario, opt, log);
        FAIL() << "a checkpoint of other binaries was continued";
    } catch (const talus::Error &e) {
        const std::string m = e.what();
        EXPECT_NE(m.find("the checkpoint was written by other binaries"), std::string::npos) << m;
        EXPECT_NE(m.find("pass --force-restart"), std::string::npos) << m;
    }
}

TEST(Checkpoint, AFileThatIsNotACheckpointIsRefused) {
    const fs::path file = fs::temp_directory_path() / "talus_not_a_checkpoint.h5";
    std::ofstream(file) << "talus: 1\n";
    try {
        talus::read_checkpoint(file);
        FAIL();
    } catch (const talus::Error &e) {
        EXPECT_NE(std::string(e.what()).find("not an HDF5 file"), std::string::npos) << e.what();
    }
    fs::remove(file);
}
