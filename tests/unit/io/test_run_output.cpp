// What `talus run` writes, against the solver it drives.
#include "solver_helpers.hpp"

#include <talus/driver/point_driver.hpp>
#include <talus/driver/run.hpp>
#include <talus/input/scenario_yaml.hpp>

#include <fmt/format.h>
#include <gtest/gtest.h>

#include <algorithm>
#include <filesystem>
#include <fstream>
#include <sstream>

namespace {

namespace fs = std::filesystem;

// Runs the scenario of `s` into `dir`, replacing a previous run's files.
void run_into(talus::test::Sim &s, const fs::path &dir, std::ostream &log) {
    talus::RunOptions opt;
    opt.output_dir = dir;
    opt.force = true;
    talus::run_scenario(s.scenario, opt, log);
}

// The last row of diagnostics.csv of a run of `yaml` into `dir`.
std::vector<double> last_row(const std::string &yaml, const fs::path &dir) {
    auto s = talus::test::sim_from_text(yaml);
    std::ostringstream log;
    run_into(*s, dir, log);
    return talus::test::read_numeric_csv(dir / "diagnostics.csv").back();
}

} // namespace

// Point 15 of the "no silent wrong results" work: steps were shortened to
// land on output times, so the trajectory changed with output.every. Two
// cadences (one output per step or so, and none but the end) must give the
// same state at the end, bit for bit: same steps, same arithmetic.
TEST(RunOutput, ResultsDoNotDependOnTheOutputCadence) {
    const std::string base =
        "talus: 1\ndimension: 2\ngrid: {origin: [0, 0], size: [1, 0.5], cell: 0.025}\n"
        "materials:\n  m: {model: linear_elastic, density: 1000, youngs_modulus: 1.0e6, "
        "poisson_ratio: 0.3}\n"
        "groups:\n  b: {material: m, velocity: [0.5, 0], shape: {box: {min: [0.2, 0.1], max: "
        "[0.5, 0.3]}}}\n"
        "boundaries: {y-: {friction: 0.3}}\ngravity: [0, -9.81]\ntime: {end: 0.05}\n";
    const fs::path tmp = fs::temp_directory_path() / "talus_cadence_test";
    const auto a = last_row(base + "output: {every: 0.0003, vtk: false}\n", tmp / "a");
    const auto b = last_row(base + "output: {every: 0.05, vtk: false}\n", tmp / "b");
    ASSERT_EQ(a.size(), b.size());
    EXPECT_EQ(a[0], b[0]); // the same number of steps
    EXPECT_EQ(a[1], 0.05); // ending on the end time exactly
    for (std::size_t k = 0; k < a.size(); ++k)
        EXPECT_EQ(a[k], b[k]) << "column " << k;
    // The fine cadence wrote a row after the first step reaching each
    // output time k * 0.0003: the row's time t satisfies 0 <= t - k * 0.0003
    // < dt (the step that reached it), and times increase. (1e-12: the
    // round-off of summing ~200 steps of 2.5e-4 s.)
    const auto rows = talus::test::read_numeric_csv(tmp / "a" / "diagnostics.csv");
    EXPECT_GT(rows.size(), 100u);
    for (std::size_t r = 1; r + 1 < rows.size(); ++r) {
        EXPECT_GT(rows[r][1], rows[r - 1][1]);
        const double due = std::floor(rows[r][1] / 0.0003 + 1e-9) * 0.0003;
        EXPECT_GE(rows[r][1] - due, -1e-12) << "row " << r;
        EXPECT_LT(rows[r][1] - due, rows[r][2] + 1e-12) << "row " << r;
    }
    fs::remove_all(tmp);
}

// A cadence far below the time step: output and checkpoint times were
// counted up to one by one after each step (about 10^9 multiples of 1e-12 s
// per step of 8e-4 s here; for 1e-300 s the run never ended, deaf even to
// SIGTERM, which is now refused before the first step: the corpus'
// *_every_too_fine.yaml). Now the next time is computed: every step writes
// one row and one checkpoint (at most one per step, as documented).
TEST(RunOutput, ACadenceFarBelowTheStepWritesEveryStepAndEnds) {
    const std::string yaml =
        "talus: 1\ndimension: 2\ngrid: {origin: [0, 0], size: [1, 1], cell: 0.1}\n"
        "materials:\n  m: {model: linear_elastic, density: 1000, youngs_modulus: 1.0e6, "
        "poisson_ratio: 0.3}\n"
        "groups:\n  g: {material: m, shape: {box: {min: [0.2, 0.2], max: [0.4, 0.4]}}}\n"
        "gravity: [0, -9.81]\ntime: {end: 0.001}\n"
        "output: {every: 1.0e-12, vtk: false}\n"
        "checkpoint: {every: 1.0e-12, keep: 10}\n";
    const fs::path tmp = fs::temp_directory_path() / "talus_fine_cadence_test";
    fs::remove_all(tmp);
    fs::create_directories(tmp);
    // From a file: a checkpoint stores the scenario's text.
    const fs::path file = tmp / "fine.yaml";
    std::ofstream(file) << yaml;
    auto s = talus::test::make_sim(talus::yaml::load_file(file.string()), {});
    std::ostringstream log;
    run_into(*s, tmp / "out", log);
    const auto rows = talus::test::read_numeric_csv(tmp / "out" / "diagnostics.csv");
    const long steps = static_cast<long>(rows.back()[0]);
    ASSERT_GE(steps, 2);
    // The start, then one row per step.
    EXPECT_EQ(static_cast<long>(rows.size()), steps + 1);
    long checkpoints = 0;
    for (const auto &e : fs::directory_iterator(tmp / "out" / "checkpoints"))
        checkpoints += e.path().extension() == ".h5" ? 1 : 0;
    EXPECT_EQ(checkpoints, steps);
    fs::remove_all(tmp);
}

// `validate` and `run` note a slender group with at most 2 particles per
// cell (docs/scenario-reference.md, "Particles per cell in slender bodies"):
// a 1 x 0.1 m beam is 10 times longer than thick; a 0.3 x 0.1 m block (3
// times) is not slender, and 3 particles per cell need no note.
TEST(RunOutput, ValidateNotesASlenderGroupWithFewParticlesPerCell) {
    auto notes_for = [](const std::string &max, int ppc) {
        talus::PluginRegistry registry;
        unsetenv("TALUS_PLUGIN_PATH");
        talus::Scenario sc = talus::read_scenario(
            talus::yaml::load_string(
                fmt::format("talus: 1\ndimension: 2\ngrid: {{origin: [0, 0], size: [1.2, 0.4], "
                            "cell: 0.025}}\n"
                            "materials:\n  m: {{model: linear_elastic, density: 1000, "
                            "youngs_modulus: 1.0e6, poisson_ratio: 0.3}}\n"
                            "groups:\n  beam: {{material: m, particles_per_cell: {}, shape: {{box: "
                            "{{min: [0, 0.1], max: [{}, 0.2]}}}}}}\n"
                            "time: {{end: 0.01}}\n",
                            ppc, max),
                "beam.yaml"),
            registry);
        std::string all;
        for (const std::string &n : talus::prepare_run(sc, {}).plan.notes)
            all += n + "\n";
        return all;
    };
    const std::string slender = notes_for("1.0", 2);
    EXPECT_NE(slender.find("beam.yaml:7:"), std::string::npos) << slender;
    EXPECT_NE(slender.find("'groups.beam' is slender (1 m long, 0.1 m thick: 8 particles across)"),
              std::string::npos)
        << slender;
    EXPECT_NE(slender.find("consider particles_per_cell: 3 or 4"), std::string::npos);
    EXPECT_EQ(notes_for("1.0", 3).find("slender"), std::string::npos);
    EXPECT_EQ(notes_for("0.3", 2).find("slender"), std::string::npos);
}

// Point 4 of the material-point driver work: when a plugin fails at a
// particle inside `talus run` (or keeps asking for smaller steps), the run
// writes a driver case with that call's inputs, and `talus point` replays it
// to the same failure: the plugin's message, which prints the stress it
// computed, its state (the count of accepted increments) and det F to 17
// digits, must come out identical, so every input reached the plugin
// unchanged. A block of the fixture `brittle_elastic` under gravity on a
// floor fails once its von Mises stress passes 50 Pa.
TEST(RunOutput, AFailedPluginCallIsReplayedByTheDriver) {
    for (const bool cut : {false, true}) {
        SCOPED_TRACE(cut ? "asks for cuts" : "fails");
        const std::string yaml = fmt::format(
            "talus: 1\ndimension: 2\nplugins: ['{}']\n"
            "grid: {{origin: [0, 0], size: [1, 1], cell: 0.05}}\n"
            "materials:\n  m: {{model: brittle_elastic, density: 1000, youngs_modulus: 1.0e5, "
            "poisson_ratio: 0.3, strength: 50, ask_cut: {}}}\n"
            "groups:\n  b: {{material: m, shape: {{box: {{min: [0.2, 0.0], max: [0.8, 0.4]}}}}}}\n"
            "boundaries: {{y-: fixed}}\ngravity: [0, -9.81]\ntime: {{end: 1.0}}\n"
            "output: {{every: 1.0, vtk: false}}\n",
            (talus::test::fixture_dir() / "fixture_fails_on_state.so").string(),
            cut ? "true" : "false");
        const fs::path dir = fs::temp_directory_path() / "talus_replay_test";
        fs::remove_all(dir);
        auto s = talus::test::sim_from_text(yaml);
        talus::RunOptions opt;
        opt.output_dir = dir;
        opt.force = true;
        std::ostringstream log;
        std::string run_error;
        try {
            talus::run_scenario(s->scenario, opt, log);
        } catch (const talus::Error &e) {
            run_error = e.what();
        }
        ASSERT_FALSE(run_error.empty()) << "the run must fail";
        const fs::path replay = dir / "failed_call.yaml";
        EXPECT_TRUE(talus::test::contains(run_error, "talus point " + replay.string()))
            << run_error;
        ASSERT_TRUE(fs::exists(replay));
        // The plugin's own words in the run's message.
        const auto at = run_error.find("von Mises stress ");
        ASSERT_NE(at, std::string::npos) << run_error;
        const std::string said = run_error.substr(at, run_error.find(')', at) - at + 1);
        EXPECT_TRUE(talus::test::contains(said, "accepted increments (J = ")) << said;

        talus::PluginRegistry reg;
        const auto root = talus::yaml::load_file(replay.string());
        const talus::PointCase pc = talus::read_point_case(root, reg);
        std::string replay_error;
        try {
            talus::run_point_case(pc);
        } catch (const talus::Error &e) {
            replay_error = e.what();
        }
        EXPECT_TRUE(talus::test::contains(replay_error, said))
            << "run: " << said << "\nreplay: " << replay_error;
        EXPECT_TRUE(talus::test::contains(replay_error, cut ? "asks for a smaller step (factor 0.5)"
                                                            : "failed: "))
            << replay_error;
        fs::remove_all(dir);
    }
}

// final_particles.csv (`talus run --plot`): one row per particle with its
// final position and the field. A block in free fall (no face reached) has
// moved by the same closed-form distance everywhere.
TEST(RunOutput, FinalParticlesHoldEveryParticleAndTheField) {
    const std::string yaml =
        "talus: 1\ndimension: 2\ngrid: {origin: [0, 0], size: [1, 1], cell: 0.05}\n"
        "materials:\n  m: {model: mohr_coulomb, density: 2000, youngs_modulus: 1.0e7, "
        "poisson_ratio: 0.3, friction_angle: 30}\n"
        "groups:\n  b: {material: m, shape: {box: {min: [0.3, 0.6], max: [0.6, 0.8]}}}\n"
        "gravity: [0, -9.81]\ntime: {end: 0.1}\noutput: {vtk: false}\n";
    const fs::path dir = fs::temp_directory_path() / "talus_final_particles_test";
    auto s = talus::test::sim_from_text(yaml);
    talus::RunOptions opt;
    opt.output_dir = dir;
    opt.force = true;
    opt.final_field = "displacement";
    std::ostringstream log;
    const talus::RunSummary rs = talus::run_scenario(s->scenario, opt, log);
    const auto rows = talus::test::read_numeric_csv(dir / "final_particles.csv");
    // The box is 6 x 4 cells of 2 x 2 particles: 96 rows, every id once.
    ASSERT_EQ(rows.size(), 96u);
    ASSERT_EQ(rs.particles, 96u);
    std::vector<double> ids;
    for (const auto &r : rows) {
        ASSERT_EQ(r.size(), 5u); // id, group, x, y, displacement
        ids.push_back(r[0]);
    }
    std::sort(ids.begin(), ids.end());
    EXPECT_EQ(std::adjacent_find(ids.begin(), ids.end()), ids.end());
    // Free fall, the same for every particle: g t^2 / 2 plus the first-order
    // term of the explicit update (the velocity after a step moves the
    // particle), at most g t dt_max / 2. dt is at most cfl h / c, and
    // c = sqrt((lambda + 2 mu) / rho) = 82.0 m/s here, so h / 80 bounds it.
    const double g = 9.81, t = 0.1, dt_max = 0.3 * 0.05 / 80.0;
    const double fall = 0.5 * g * t * t, tol = 0.5 * g * t * dt_max + 1e-12;
    double lowest = 1e300;
    for (const auto &r : rows) {
        EXPECT_NEAR(r[4], fall, tol);
        lowest = std::min(lowest, r[3]);
    }
    // The coordinates are the final ones: the lowest particle row started
    // at 0.6 + h/4 (two per cell) and fell by the same distance.
    EXPECT_NEAR(lowest, 0.6 + 0.05 / 4 - fall, tol);
}

// A misspelt field is refused before the run starts: nothing is written.
TEST(RunOutput, AMisspeltPlotFieldIsRefusedBeforeTheRun) {
    const std::string yaml =
        "talus: 1\ndimension: 2\ngrid: {origin: [0, 0], size: [1, 1], cell: 0.05}\n"
        "materials:\n  m: {model: mohr_coulomb, density: 2000, youngs_modulus: 1.0e7, "
        "poisson_ratio: 0.3, friction_angle: 30}\n"
        "groups:\n  b: {material: m, shape: {box: {min: [0.3, 0.6], max: [0.6, 0.8]}}}\n"
        "gravity: [0, -9.81]\ntime: {end: 0.1}\n";
    const fs::path dir = fs::temp_directory_path() / "talus_misspelt_field_test";
    fs::remove_all(dir);
    auto s = talus::test::sim_from_text(yaml);
    talus::RunOptions opt;
    opt.output_dir = dir;
    opt.final_field = "plastic_deviatoric_strian";
    std::ostringstream log;
    try {
        talus::run_scenario(s->scenario, opt, log);
        FAIL() << "the run started";
    } catch (const talus::Error &e) {
        EXPECT_TRUE(talus::test::contains(e.what(), "did you mean 'plastic_deviatoric_strain'"))
            << e.what();
    }
    EXPECT_FALSE(fs::exists(dir));
}

namespace {

// The column of the damping tests, in stages.
std::string staged_column(const std::string &stages) {
    return "talus: 1\ndimension: 2\ngrid: {origin: [0, 0], size: [0.2, 1.2], cell: 0.05}\n"
           "materials:\n  soil: {model: linear_elastic, density: 2000, youngs_modulus: 2.0e7, "
           "poisson_ratio: 0.3}\n"
           "groups:\n  column: {material: soil, shape: {box: {min: [0, 0], max: [0.2, 1.0]}}}\n"
           "boundaries: {x-: slip, x+: slip, y-: fixed}\ngravity: [0, -9.81]\n"
           "output: {every: 0.07}\nstages:\n" +
           stages;
}

std::vector<std::string> lines_of(const fs::path &file) {
    std::ifstream in(file);
    std::vector<std::string> out;
    for (std::string line; std::getline(in, line);)
        out.push_back(line);
    return out;
}

} // namespace

// Where each stage ends is in the output whatever the cadence: stages.csv
// says when and how each ended and which VTK file holds its last state,
// that file carries the stage in its field data, and diagnostics.csv has
// a row at that time and a stage column.
TEST(RunOutput, StagesAreMarkedInTheOutput) {
    const fs::path dir = fs::temp_directory_path() / "talus_stages_output";
    auto s = talus::test::sim_from_text(staged_column(
        "  - name: geostatic\n    duration: 3\n    damping: {type: local, coefficient: 0.8}\n"
        "    until: {kinetic_energy_ratio: 1.0e-6}\n"
        "  - {name: loaded, duration: 0.05, loads: [{box: {min: [0, 0.97], max: [0.2, 1.0]}, "
        "traction: [0, -1000]}]}\n"));
    std::ostringstream log;
    run_into(*s, dir, log);
    EXPECT_NE(log.str().find("stage 'geostatic' ended at"), std::string::npos) << log.str();
    const auto stages = lines_of(dir / "stages.csv");
    ASSERT_EQ(stages.size(), 3u);
    EXPECT_EQ(stages[0], "stage,name,first_step,start_time,last_step,end_time,end,"
                         "kinetic_energy_ratio,last_output");
    auto field = [](const std::string &row, int k) {
        std::stringstream ss(row);
        std::string cell;
        for (int i = 0; i <= k; ++i)
            std::getline(ss, cell, ',');
        return cell;
    };
    EXPECT_EQ(field(stages[1], 1), "geostatic");
    EXPECT_EQ(field(stages[1], 6), "quiescent");
    EXPECT_LT(std::stod(field(stages[1], 7)), 1e-6);
    EXPECT_EQ(field(stages[2], 1), "loaded");
    EXPECT_EQ(field(stages[2], 6), "duration");
    // The second stage starts where the first ended.
    EXPECT_EQ(std::stol(field(stages[2], 2)), std::stol(field(stages[1], 4)) + 1);
    EXPECT_EQ(field(stages[2], 3), field(stages[1], 5));
    const double end0 = std::stod(field(stages[1], 5));
    EXPECT_LT(end0, 3.0);
    // The file written at the first stage's end.
    const fs::path vtu = dir / fmt::format("particles_{:05d}.vtu", std::stoi(field(stages[1], 8)));
    std::ifstream in(vtu);
    std::stringstream text;
    text << in.rdbuf();
    EXPECT_NE(text.str().find(fmt::format("Name=\"TimeValue\" NumberOfTuples=\"1\" "
                                          "format=\"ascii\">{:.17g}<",
                                          end0)),
              std::string::npos);
    EXPECT_NE(text.str().find("Name=\"Stage\" NumberOfTuples=\"1\" format=\"ascii\">0<"),
              std::string::npos);
    // diagnostics.csv: the stage column, and a row at the stage's end.
    const auto diag = lines_of(dir / "diagnostics.csv");
    EXPECT_EQ(diag[0].substr(diag[0].rfind(',') + 1), "stage");
    const auto rows = talus::test::read_numeric_csv(dir / "diagnostics.csv");
    bool at_end = false;
    for (const auto &r : rows) {
        EXPECT_EQ(r.back(), r[1] <= end0 ? 0.0 : 1.0) << "t = " << r[1];
        at_end = at_end || r[1] == end0;
    }
    EXPECT_TRUE(at_end);
    fs::remove_all(dir);
}

// A stage that must end at rest but runs out of time stops the run: a
// located error naming the stage and the ratio reached, a non-zero exit
// (the Error), and its last state in the output.
TEST(RunOutput, AStageNotAtRestStopsTheRunWithItsStateWritten) {
    const fs::path dir = fs::temp_directory_path() / "talus_stage_not_at_rest";
    auto s = talus::test::sim_from_text(staged_column("  - name: geostatic\n    duration: 0.1\n"
                                                      "    until: {kinetic_energy_ratio: 1.0e-6}\n"
                                                      "  - {name: never, duration: 0.1}\n"));
    std::ostringstream log;
    try {
        run_into(*s, dir, log);
        FAIL() << "the run went on";
    } catch (const talus::Error &e) {
        const std::string m = e.what();
        EXPECT_NE(m.find("test.yaml:14:12: error: 'stages[0].until'"), std::string::npos) << m;
        EXPECT_NE(m.find("the state at the stage's end is in particles_00002.vtu and the last row "
                         "of diagnostics.csv"),
                  std::string::npos)
            << m;
        EXPECT_NE(m.find("stage 'geostatic' did not come to rest within its duration of 0.1 s"),
                  std::string::npos)
            << m;
    }
    const auto stages = lines_of(dir / "stages.csv");
    ASSERT_EQ(stages.size(), 2u);
    EXPECT_NE(stages[1].find(",duration_not_quiescent,"), std::string::npos);
    EXPECT_EQ(talus::test::read_numeric_csv(dir / "diagnostics.csv").back()[1], 0.1);
    fs::remove_all(dir);
}
