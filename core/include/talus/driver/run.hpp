// `talus run` and `talus validate`: everything decided before the first
// step (the same code for both, so validate accepts what run accepts), the
// time loop, and everything a run writes (VTK particles with a .pvd
// collection, diagnostics.csv, probes.csv, progress lines).
#pragma once

#include <talus/io/checkpoint.hpp>
#include <talus/mpm/simulation.hpp>
#include <talus/verbosity.hpp>

#include <cstdint>
#include <filesystem>
#include <iosfwd>
#include <memory>
#include <string>
#include <vector>

namespace talus {

struct RunOptions {
    std::filesystem::path output_dir; // empty: a folder named after the scenario
    bool force = false;               // overwrite a previous run's files
    // Run even when the plan exceeds the limits (kMaxSteps, kMaxOutputFiles).
    bool allow_large = false;
    // Progress on stderr: a carriage-return line on a terminal; otherwise
    // (log files, batch jobs) a plain line every `progress_interval` s.
    bool progress = false;
    bool progress_tty = false;
    double progress_interval = 10.0;
    SolverOptions solver;
    // Choose each step's thread count, between 1 and solver.threads
    // (OpenMP's default for 0), from the steps' measured wall times, so that
    // a run next to another busy process is not held at every barrier by a
    // thread that lost its core (ThreadGovernor). The results do not
    // depend on the thread count, bit for bit. Off with several ranks (a
    // rank's steps wait for the others'), and by default: a caller that
    // sets the threads gets them. `talus run` turns it on unless --threads
    // is given.
    bool adapt_threads = false;
    // When set, the run ends by writing final_particles.csv in the output
    // folder: id, group, coordinates and this field of every particle (a
    // scalar state variable of the materials, or one of kFinalFieldBuiltins).
    // Checked before the first step.
    std::string final_field;
    // The scenario's text, stored in every checkpoint (empty: read from
    // the scenario's file when the run starts).
    std::string scenario_text;
    // Continue this checkpoint's run in `output_dir`, which holds its
    // output: the files written after the checkpoint are dropped and the
    // run goes on from its state. Refused when Talus or a plugin differs
    // from the checkpoint's, unless force_restart.
    const Checkpoint *restart = nullptr;
    bool force_restart = false;
    // quiet: warnings only (progress is then off too); verbose: every
    // output and checkpoint, and the plugins loaded.
    Verbosity verbosity = Verbosity::normal;
};

// A run stopped by SIGTERM or SIGINT, after writing a checkpoint (the
// message names it and the command that continues). Exit with 128 + signal.
class Interrupted : public Error {
  public:
    Interrupted(const std::string &what, int signal) : Error(what), signal_(signal) {}
    int signal() const { return signal_; }

  private:
    int signal_;
};

// Fields every particle has, for RunOptions::final_field: mean stress p and
// von Mises q as in the VTK output, J = det F, the speed and the magnitude
// of the displacement.
inline constexpr const char *kFinalFieldBuiltins[] = {"displacement", "speed", "p", "q", "J"};

// A run estimated to take more steps, or to write more VTK files, than
// these is almost always a mistake in the input (a unit, a cadence):
// `validate` warns, `run` refuses unless told otherwise.
inline constexpr double kMaxSteps = 1e8;
inline constexpr double kMaxOutputFiles = 1e5;
// Output and checkpoint times are k * every with k counted in a double:
// at most 2^53 of them up to time.end.
inline constexpr double kMaxCadenceCount = 9007199254740992.0;

// What validate reports and run checks before the first step.
struct RunPlan {
    ResourceEstimate estimate;            // from the input, before allocation
    double memory_total = 0.0;            // bytes of physical memory
    double memory_available = 0.0;        // bytes available now (0: unknown)
    std::size_t particles = 0;            // generated
    double first_dt = 0.0;                // fixed, or the stable step of the initial state
    double steps = 0.0;                   // end time / first_dt: an estimate
    double output_files = 0.0;            // VTK files the cadence asks for
    std::vector<std::string> notes;       // worth knowing, not wrong
    std::vector<std::string> over_limits; // refused by run unless allow_large
};

// Throws a located talus::Error when the grid and particles the scenario
// asks for cannot fit in this machine's memory (the estimate is in the
// message); called before anything is allocated.
ResourceEstimate check_memory(const Scenario &scenario, double &memory_total,
                              double &memory_available);

// The checks of everything decided before the first step: memory, the
// particles of every group (inside the grid, not empty), loads, fixities
// and probes that select something, the plugins' view of the initial state,
// a fixed dt against the stability limit, the step and file counts. Throws
// talus::Error on the first problem; returns the set-up simulation.
struct Prepared {
    std::unique_ptr<Simulation> sim;
    RunPlan plan;
    std::vector<std::int64_t> probe_particles; // per probe (-1: not a particle probe)
};
Prepared prepare_run(Scenario &scenario, const SolverOptions &solver);

// The output folder a run of `scenario_file` would use by default.
std::filesystem::path default_output_dir(const std::string &scenario_file);

// What a run did. A restart continues a run: `steps` and `outputs` count
// the whole run, `seconds`, the rate and `checkpoints` this process's part
// (from step `first_step`, after `outputs_before` outputs).
struct RunSummary {
    long steps = 0;
    double time = 0.0;
    double seconds = 0.0;
    std::size_t particles = 0;
    double particle_steps_per_second = 0.0;
    int outputs = 0;
    int checkpoints = 0;
    bool restarted = false;
    long first_step = 0;
    int outputs_before = 0;
    int ranks = 1;
    std::filesystem::path output_dir;
};

// Runs the scenario to its end time. Refuses (before any work) to write into
// a folder holding a previous run's files unless options.force. Warnings go
// to `log`. Throws talus::Error on failure: a failed write names the file
// and the OS's reason; a failed step (plugin, inversion, a particle leaving)
// first writes the state at that moment (failure_step<N>.vtu and a last
// diagnostics row) and says where. Files written before stay.
RunSummary run_scenario(Scenario &scenario, const RunOptions &options, std::ostream &log);

} // namespace talus
