// `talus run`: the time loop and everything it writes (VTK particles with a
// .pvd collection, diagnostics.csv, probes.csv, a progress line).
#pragma once

#include <talus/solver.hpp>

#include <filesystem>
#include <iosfwd>
#include <string>

namespace talus {

struct RunOptions {
    std::filesystem::path output_dir; // empty: a folder named after the scenario
    bool force = false;               // overwrite a previous run's files
    // Progress on stderr: a carriage-return line on a terminal; otherwise
    // (log files, batch jobs) a plain line every `progress_interval` s.
    bool progress = false;
    bool progress_tty = false;
    double progress_interval = 10.0;
    SolverOptions solver;
};

struct RunSummary {
    long steps = 0;
    double time = 0.0;
    double seconds = 0.0;
    std::size_t particles = 0;
    double particle_steps_per_second = 0.0;
    int outputs = 0;
    std::filesystem::path output_dir;
};

// The output folder a run of `scenario_file` would use by default.
std::filesystem::path default_output_dir(const std::string &scenario_file);

// Runs the scenario to its end time. Refuses (before any work) to write into
// a folder holding a previous run's files unless options.force. Warnings go
// to `log`. Throws talus::Error on failure; the files written up to the
// failure stay, so the run can be inspected.
RunSummary run_scenario(Scenario &scenario, const RunOptions &options, std::ostream &log);

// VTK XML unstructured grid of the particles (binary appended data).
void write_vtu(const std::filesystem::path &file, const Simulation &sim,
               const std::vector<std::string> &state_fields);

} // namespace talus
