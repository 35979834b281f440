// `talus plugin check`: the conformance suite every material plugin must
// pass. It tests the contract of talus/material_abi.h, not the physics of a
// model: descriptors, zero increment, batch-size and aliasing invariance,
// tangent against finite differences, wave speed, NaN handling, exported
// symbols, floating-point environment, reentrancy.
#pragma once

#include <filesystem>
#include <iosfwd>
#include <string>
#include <utility>
#include <vector>

namespace talus {

struct CheckOptions {
    // Size of one strain increment of the loading paths the checks build
    // their states with; 1e-4 is small for any solid yet far above round-off.
    double strain_scale = 1e-4;
    double density = 2000.0; // kg/m^3, the host-owned density of the test point
    // Parameter values replacing the plugin's typical values, by key, as
    // text: a number, a comma-separated list (list parameters) or a string.
    std::vector<std::pair<std::string, std::string>> params;
    // Run the checks in a child process so that a crashing plugin is
    // reported as a failed check instead of taking the checker down.
    bool isolate = true;
};

struct CheckOutcome {
    std::string model; // empty for library-wide checks
    std::string name;
    bool passed = false;
    std::string detail;
};

struct ConformanceReport {
    std::filesystem::path library;
    std::vector<CheckOutcome> outcomes;
    bool passed() const;
    std::size_t failures() const;
};

ConformanceReport check_plugin(const std::filesystem::path &library, const CheckOptions &options);

void print_report(std::ostream &out, const ConformanceReport &report);

} // namespace talus
