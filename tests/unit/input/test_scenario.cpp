// Scenario files: every error names file:line:column, the key, what was
// expected; the reference documentation lists every key the reader accepts
// and its examples are valid scenarios.
#include "solver_helpers.hpp"

#include <gtest/gtest.h>

#include <fstream>
#include <set>

using talus::test::contains;

namespace {

const std::string kGood =
    "talus: 1\n"
    "dimension: 2\n"
    "grid: {origin: [0, 0], size: [1, 1], cell: 0.1}\n"
    "materials:\n"
    "  sand: {model: linear_elastic, density: 1800, youngs_modulus: 1.0e7, poisson_ratio: 0.3}\n"
    "groups:\n"
    "  column: {material: sand, shape: {box: {min: [0, 0], max: [0.2, 0.4]}}}\n"
    "time: {end: 0.1}\n";

std::string error_of(const std::string &text) {
    unsetenv("TALUS_PLUGIN_PATH");
    talus::PluginRegistry reg;
    try {
        talus::read_scenario(talus::yaml::load_string(text, "s.yaml"), reg);
    } catch (const talus::Error &e) {
        return e.what();
    }
    return "(no error)";
}

std::string with(const std::string &from, const std::string &to) {
    std::string s = kGood;
    const auto at = s.find(from);
    EXPECT_NE(at, std::string::npos) << from;
    return s.replace(at, from.size(), to);
}

} // namespace

TEST(ScenarioErrors, TheGoodOneIsValid) { EXPECT_EQ(error_of(kGood), "(no error)"); }

TEST(ScenarioErrors, MisspeltKey) {
    const std::string m = error_of(with("time: {end: 0.1}", "tiem: {end: 0.1}"));
    EXPECT_TRUE(contains(m, "s.yaml:8:1: error: unknown key 'tiem'; did you mean 'time'?")) << m;
    const std::string p = error_of(with("poisson_ratio: 0.3", "poison_ratio: 0.3"));
    EXPECT_TRUE(
        contains(p, "s.yaml:5:71: error: unknown key 'materials.sand.poison_ratio'; did you mean "
                    "'poisson_ratio'?"))
        << p;
}

TEST(ScenarioErrors, ValueOutOfBoundsWithUnitAndBounds) {
    const std::string m = error_of(with("poisson_ratio: 0.3", "poisson_ratio: 0.7"));
    EXPECT_TRUE(
        contains(m, "s.yaml:5:86: error: 'materials.sand.poisson_ratio' value 0.7 is out of range: "
                    "expected -1 < poisson_ratio < 0.5 (unit -)"))
        << m;
    EXPECT_TRUE(
        contains(error_of(with("cell: 0.1", "cell: -0.1")), "'grid.cell' expected cell (m) > 0"));
    EXPECT_TRUE(
        contains(error_of(with("cell: 0.1", "cell: 0.3")), "is not a whole number of cells"));
}

TEST(ScenarioErrors, WrongType) {
    const std::string m = error_of(with("youngs_modulus: 1.0e7", "youngs_modulus: [1, 2]"));
    EXPECT_TRUE(
        contains(m, "s.yaml:5:64: error: 'materials.sand.youngs_modulus' expected a number"))
        << m;
    EXPECT_TRUE(contains(error_of(with("dimension: 2", "dimension: two")),
                         "'dimension' expected an integer, got 'two'"));
    EXPECT_TRUE(contains(error_of(with("size: [1, 1]", "size: [1, 1, 1]")),
                         "expected 2 numbers (m), one per dimension"));
}

TEST(ScenarioErrors, MissingPlugin) {
    const std::string m = error_of(with("time:", "plugins: [no_such_plugin]\ntime:"));
    EXPECT_TRUE(contains(
        m,
        "s.yaml:8:11: error: 'plugins[0]' plugin library 'no_such_plugin' not found; looked for:"))
        << m;
    const std::string u = error_of(with("model: linear_elastic", "model: cam_clay"));
    EXPECT_TRUE(contains(
        u, "s.yaml:5:17: error: 'materials.sand.model' no plugin offers the material model "
           "'cam_clay'"))
        << u;
}

TEST(ScenarioErrors, GroupWithUnknownMaterial) {
    const std::string m = error_of(with("material: sand", "material: snad"));
    EXPECT_TRUE(
        contains(m, "s.yaml:7:22: error: 'groups.column.material' no material named 'snad' under "
                    "materials (did you mean 'sand'?)"))
        << m;
}

TEST(ScenarioErrors, EnumeratedValuesSuggest) {
    EXPECT_TRUE(contains(
        error_of(kGood + "solver: {scheme: mulsl}\n"),
        "unknown value 'mulsl' (did you mean 'musl'?); expected one of: usl, usf, musl, usavg"));
    EXPECT_TRUE(contains(error_of(kGood + "boundaries: {x-: fixd}\n"),
                         "unknown value 'fixd' (did you mean 'fixed'?)"));
    EXPECT_TRUE(
        contains(error_of(kGood + "boundaries: {z-: fixed}\n"), "a 2D scenario has no face 'z-'"));
    EXPECT_TRUE(contains(error_of(kGood + "output: {probes: [{name: a, centre_of_mass: colum}]}\n"),
                         "no group named 'colum' (did you mean 'column'?)"));
    EXPECT_TRUE(contains(error_of(kGood + "solver: {transfer: {type: apic, alpha: 0.5}}\n"),
                         "alpha applies to the flip transfer only"));
}

// docs/scenario-reference.md documents every key the reader accepts (as
// `path.to.key` in a table row) and names no key the reader does not know;
// every complete example in it (a ```yaml block starting with "talus: 1")
// is a valid scenario.
TEST(ScenarioDocs, ReferenceListsEveryKeyAndItsExamplesAreValid) {
    std::ifstream in(talus::test::source_dir() / "docs/scenario-reference.md");
    ASSERT_TRUE(in.good());
    std::stringstream ss;
    ss << in.rdbuf();
    const std::string doc = ss.str();
    // Table rows of the form "| `key` | ...".
    std::set<std::string> documented;
    std::istringstream lines(doc);
    for (std::string line; std::getline(lines, line);) {
        if (line.rfind("| `", 0) != 0) continue;
        const std::size_t end = line.find("` |", 3);
        if (end != std::string::npos) documented.insert(line.substr(3, end - 3));
    }
    const std::vector<std::string> keys = talus::scenario_schema();
    for (const std::string &k : keys)
        EXPECT_TRUE(documented.count(k)) << "undocumented key: " << k;
    for (const std::string &d : documented)
        EXPECT_TRUE(std::find(keys.begin(), keys.end(), d) != keys.end())
            << "documented but not read: " << d;
    int examples = 0;
    std::size_t pos = 0;
    while ((pos = doc.find("```yaml\n", pos)) != std::string::npos) {
        const std::size_t end = doc.find("```\n", pos + 8);
        const std::string block = doc.substr(pos + 8, end - pos - 8);
        pos = end;
        if (block.rfind("talus: 1", 0) != 0) continue;
        ++examples;
        EXPECT_EQ(error_of(block), "(no error)") << block;
    }
    EXPECT_GE(examples, 2);
}

// Every scenario shipped in configs/ is valid.
TEST(ScenarioDocs, EveryConfigValidates) {
    int n = 0;
    for (const auto &e :
         std::filesystem::recursive_directory_iterator(talus::test::source_dir() / "configs")) {
        if (e.path().extension() != ".yaml" || e.path().parent_path().filename() == "point")
            continue;
        unsetenv("TALUS_PLUGIN_PATH");
        talus::PluginRegistry reg;
        EXPECT_NO_THROW(talus::read_scenario(talus::yaml::load_file(e.path().string()), reg))
            << e.path();
        ++n;
    }
    EXPECT_GE(n, 4);
}

// Two groups or two materials of the same name: yaml-cpp would give the
// first definition to both lookups and drop the second silently. Rejected,
// with both locations.
TEST(ScenarioErrors, DuplicateNamesAreRejectedWithBothLocations) {
    const std::string g = error_of(
        with("  column: {material: sand, shape: {box: {min: [0, 0], max: [0.2, 0.4]}}}\n",
             "  column: {material: sand, shape: {box: {min: [0, 0], max: [0.2, 0.4]}}}\n"
             "  column: {material: sand, shape: {box: {min: [0.5, 0], max: [0.7, 0.4]}}}\n"));
    EXPECT_TRUE(contains(g, "s.yaml:8:3: error: 'groups.column' is given twice (first at "
                            "s.yaml:7:3); keys must be unique"))
        << g;
    const std::string m =
        error_of(with("  sand: {model: linear_elastic, density: 1800, youngs_modulus: 1.0e7, "
                      "poisson_ratio: 0.3}\n",
                      "  sand: {model: linear_elastic, density: 1800, youngs_modulus: 1.0e7, "
                      "poisson_ratio: 0.3}\n"
                      "  sand: {model: linear_elastic, density: 2000, youngs_modulus: 2.0e7, "
                      "poisson_ratio: 0.3}\n"));
    EXPECT_TRUE(contains(m, "s.yaml:6:3: error: 'materials.sand' is given twice (first at "
                            "s.yaml:5:3)"))
        << m;
}
