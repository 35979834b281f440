// libFuzzer target: the checks the plugin loader makes of a library
// descriptor (PluginLibrary::from_descriptor, the path of every dlopen'ed
// plugin after its entry point), on descriptors decoded from bytes
// (descriptor_bytes.hpp), and what the host then derives from an accepted
// one: parameter bounds and defaults as text, the state's initial vector.
// Any descriptor is either accepted or refused with an error naming the
// library and the field (docs/fuzzing.md).
#include "descriptor_bytes.hpp"
#include "fuzz_support.hpp"

#include <cstddef>
#include <cstdint>
#include <string>
#include <string_view>

namespace {
// Keeps the text the host derives from being optimised away.
volatile std::size_t sink = 0;
} // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t *data, std::size_t size) {
    talus::fuzz::ByteReader in(data, size);
    const talus::fuzz::DecodedLibrary decoded(in);
    talus::fuzz::expect_loads_or_located([&] {
        const auto lib =
            talus::PluginLibrary::from_descriptor(decoded.library(), talus::fuzz::kInputName);
        std::size_t text = 0;
        for (const talus::Model &m : lib->models()) {
            text += m.qualified_id().size();
            for (const talus::ParamInfo &p : m.params()) {
                text += p.bounds_text().size() + std::string_view(p.type_name()).size();
                if (p.type == TALUS_PARAM_REAL_ARRAY) text += p.count_text().size();
                text += p.value_text(p.default_param()).size();
                text += p.value_text(p.typical_param()).size();
                // The loader checks a scalar's typical value (a string's may
                // be absent, and a list's is the plugin's to choose).
                if (p.scalar() && !talus::check_parameter(p, p.typical_param()).empty())
                    talus::fuzz::finding("an accepted parameter's typical value fails its own "
                                         "check: " +
                                         p.key);
            }
            if (m.initial_state().size() != m.state_size())
                talus::fuzz::finding("the initial state's length is not the state size");
        }
        sink = text;
    });
    return 0;
}
