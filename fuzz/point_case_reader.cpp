// libFuzzer target: the material-point driver's case reader (`talus point`),
// presets expanded and the programme printed as --show-stages does
// (docs/fuzzing.md). Any input either loads or gives a located error.
#include "fuzz_support.hpp"

#include <talus/driver/point_driver.hpp>
#include <talus/input/yaml_input.hpp>

#include <cstddef>
#include <cstdint>
#include <sstream>
#include <string>

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t *data, std::size_t size) {
    const std::string text(reinterpret_cast<const char *>(data), size);
    if (talus::fuzz::names_a_library(text)) return -1;
    talus::fuzz::expect_loads_or_located([&] {
        const talus::yaml::Node root = talus::yaml::load_string(text, talus::fuzz::kInputName);
        const talus::PointCase pc = talus::read_point_case(root, talus::fuzz::registry());
        std::ostringstream out;
        talus::print_stages(out, pc);
    });
    return 0;
}
