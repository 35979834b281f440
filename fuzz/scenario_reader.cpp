// libFuzzer target: the scenario reader and the checks `talus validate`
// makes before the first step (docs/fuzzing.md). Any input either loads or
// gives a located error.
#include "fuzz_support.hpp"

#include <talus/driver/run.hpp>
#include <talus/input/scenario_yaml.hpp>
#include <talus/input/yaml_input.hpp>

#include <cstddef>
#include <cstdint>
#include <string>

namespace {

// prepare_run generates every particle: inputs asking for more than this
// are checked by the memory estimate alone (the check a real run makes
// first), so that one input costs milliseconds, not seconds.
constexpr double kPrepareBytes = 64e6;

} // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t *data, std::size_t size) {
    const std::string text(reinterpret_cast<const char *>(data), size);
    if (talus::fuzz::names_a_library(text)) return -1; // not added to the corpus
    talus::fuzz::expect_loads_or_located([&] {
        const talus::yaml::Node root = talus::yaml::load_string(text, talus::fuzz::kInputName);
        talus::Scenario sc = talus::read_scenario(root, talus::fuzz::registry());
        double total = 0.0, available = 0.0;
        const talus::ResourceEstimate est = talus::check_memory(sc, total, available);
        if (est.bytes > kPrepareBytes) return;
        talus::SolverOptions solver;
        solver.threads = 1;
        (void)talus::prepare_run(sc, solver);
    });
    return 0;
}
