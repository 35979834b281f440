// What every fuzz target asks of an input: it loads, or it ends in a
// talus::Error whose message starts with the input's name (the
// file:line:column the reader promises). Any other outcome is a finding:
// another exception type is reported and the process aborted (libFuzzer
// then saves the input); a crash, a hang (-timeout) or an allocation past
// -malloc_limit_mb is caught by libFuzzer and the sanitizers themselves.
#pragma once

#include <talus/error.hpp>
#include <talus/material/plugin_loader.hpp>

#include <cstdio>
#include <cstdlib>
#include <exception>
#include <string>
#include <string_view>

namespace talus::fuzz {

// The name the input stands under in messages (as a file name would).
inline constexpr const char *kInputName = "fuzz-input.yaml";

[[noreturn]] inline void finding(const std::string &what) {
    std::fprintf(stderr, "talus fuzz: FINDING: %s\n", what.c_str());
    std::fflush(stderr);
    std::abort();
}

// The shipped plugins of this build tree only: no environment variable or
// --plugin-path widens what an input can load.
inline PluginRegistry &registry() {
    static PluginRegistry r({}, false);
    return r;
}

// A text the harness does not hand to the reader: anything that names a
// shared object (".so"). A scenario may name plugin files and a UMAT
// adapter a library to dlopen; loading arbitrary system libraries into the
// fuzzing process would test them, not Talus.
inline bool names_a_library(std::string_view text) {
    return text.find(".so") != std::string_view::npos;
}

// Runs `load`; accepts success or a located talus::Error.
template <class F>
void expect_loads_or_located(F &&load) {
    try {
        load();
    } catch (const talus::Error &e) {
        const std::string_view msg = e.what();
        if (msg.substr(0, std::string_view(kInputName).size()) != kInputName)
            finding(std::string("an error that does not say where: ") + e.what());
    } catch (const std::exception &e) {
        finding(std::string("an exception other than talus::Error escaped: ") + e.what());
    } catch (...) {
        finding("an exception of unknown type escaped");
    }
}

} // namespace talus::fuzz
