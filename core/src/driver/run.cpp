#include <talus/driver/run.hpp>

#include "clamp_watch.hpp"
#include "governed_steps.hpp"
#include "run_folder.hpp"
#include "stop_signals.hpp"

#include <talus/driver/point_driver.hpp>
#include <talus/input/yaml_input.hpp>
#include <talus/io/checkpoint.hpp>
#include <talus/io/csv_field.hpp>
#include <talus/io/output_file.hpp>
#include <talus/io/provenance.hpp>
#include <talus/io/pvd_file.hpp>
#include <talus/io/vtk_output.hpp>
#include <talus/material/crash_report.hpp>
#include <talus/sdk/voigt.hpp>

#include <fmt/format.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <csignal>
#include <cstdint>
#include <cstdio>
#include <fstream>
#include <iterator>
#include <limits>
#include <map>
#include <optional>
#include <ostream>
#include <unistd.h>

namespace talus {

namespace fs = std::filesystem;

fs::path default_output_dir(const std::string &scenario_file) {
    return fs::current_path() / fs::path(scenario_file).stem();
}

// ------------------------------------------------------ before the run --

namespace {

std::string bytes_text(double b) {
    if (b >= 1e12) return fmt::format("{:.3g} TB", b / 1e12);
    if (b >= 1e9) return fmt::format("{:.3g} GB", b / 1e9);
    if (b >= 1e6) return fmt::format("{:.3g} MB", b / 1e6);
    return fmt::format("{:.3g} kB", b / 1e3);
}

// MemAvailable of /proc/meminfo in bytes, 0 where there is none.
double memory_available() {
    std::ifstream in("/proc/meminfo");
    std::string key;
    double kb = 0.0;
    std::string unit;
    while (in >> key >> kb >> unit)
        if (key == "MemAvailable:") return kb * 1024.0;
    return 0.0;
}

} // namespace

ResourceEstimate check_memory(const Scenario &sc, double &total, double &available) {
    const ResourceEstimate e = estimate_resources(sc);
    const long pages = ::sysconf(_SC_PHYS_PAGES), page = ::sysconf(_SC_PAGE_SIZE);
    total = pages > 0 && page > 0 ? static_cast<double>(pages) * static_cast<double>(page) : 0.0;
    available = memory_available();
    if (total > 0.0 && e.bytes > total)
        throw Error(sc.grid_origin.error(fmt::format(
            "the scenario needs about {} of memory ({:.3g} particles, {:.3g} grid nodes), more "
            "than this machine has ({}); coarsen grid.cell, lower particles_per_cell, or "
            "shrink the grid or the groups",
            bytes_text(e.bytes), e.particles, e.nodes, bytes_text(total))));
    return e;
}

namespace {

// The particle nearest each probe point at t = 0 (-1 for other probes; on
// a tie the lowest id, so that any number of ranks picks the same). A
// point farther than a cell from every particle is a mistake in the point.
std::vector<std::int64_t> probe_particles(const Scenario &sc, const Simulation &sim) {
    const Comm &comm = sim.comm();
    std::vector<std::int64_t> ids;
    for (const Probe &p : sc.output.probes) {
        std::int64_t id = -1;
        if (p.kind == Probe::Kind::particle) {
            double best = std::numeric_limits<double>::infinity();
            for (const auto &s : sim.sets())
                for (std::size_t k = 0; k < s.n; ++k) {
                    double d2 = 0.0;
                    for (int d = 0; d < sc.dim; ++d)
                        d2 += std::pow(s.x[static_cast<std::size_t>(d)][k] -
                                           p.point[static_cast<std::size_t>(d)],
                                       2);
                    if (d2 < best || (d2 == best && s.id[k] < id)) {
                        best = d2;
                        id = s.id[k];
                    }
                }
            if (comm.distributed()) {
                // The nearest over the ranks, then the lowest id at that
                // distance (ids are below 2^53: exact as doubles).
                const double nearest = comm.min(best);
                id = static_cast<std::int64_t>(
                    comm.min(best == nearest && id >= 0 ? static_cast<double>(id)
                                                        : std::numeric_limits<double>::infinity()));
                best = nearest;
            }
            if (std::sqrt(best) > sc.cell) // the global nearest: the same on every rank
                fail_together(
                    comm,
                    p.origin.error(fmt::format(
                        "probe '{}': no particle within a cell ({:g} m) of its point; the nearest "
                        "is {:.4g} m away (a probe follows the particle nearest its point at t = "
                        "0)",
                        p.name, sc.cell, std::sqrt(best))));
        }
        ids.push_back(id);
    }
    return ids;
}

} // namespace

namespace {

// A body a few cells thick that bends through large rotations needs more
// than 2 x 2 quadrature points per cell: measured on a cantilever,
// +6.3 % deflection at 2 per cell, +2.3 % at 3, +1.2 % at 4
// (docs/scenario-reference.md, "Particles per cell in slender bodies").
// Slender: the particles' bounding box (plus one spacing) at least 5 times
// longer than thick.
void slender_group_notes(const Scenario &sc, const Simulation &sim,
                         std::vector<std::string> &notes) {
    const int D = sc.dim;
    const std::size_t G = sc.groups.size();
    std::vector<std::array<double, 3>> lo(G, {1e300, 1e300, 1e300}),
        hi(G, {-1e300, -1e300, -1e300});
    for (const ParticleSet &s : sim.sets())
        for (std::size_t p = 0; p < s.n; ++p) {
            const auto g = static_cast<std::size_t>(s.group[p]);
            for (int d = 0; d < D; ++d) {
                const auto dd = static_cast<std::size_t>(d);
                lo[g][dd] = std::min(lo[g][dd], s.x0[dd][p]);
                hi[g][dd] = std::max(hi[g][dd], s.x0[dd][p]);
            }
        }
    // Over the ranks (the arrays of three doubles are contiguous).
    static_assert(sizeof(std::array<double, 3>) == 3 * sizeof(double));
    if (G > 0) {
        sim.comm().min(lo.front().data(), 3 * G);
        sim.comm().max(hi.front().data(), 3 * G);
    }
    for (std::size_t g = 0; g < G; ++g) {
        const GroupSpec &gs = sc.groups[g];
        if (gs.particles_per_cell > 2 || lo[g][0] > hi[g][0]) continue;
        const double spacing = sc.cell / gs.particles_per_cell;
        double thin = 1e300, along = 0.0;
        for (int d = 0; d < D; ++d) {
            const double e =
                hi[g][static_cast<std::size_t>(d)] - lo[g][static_cast<std::size_t>(d)] + spacing;
            thin = std::min(thin, e);
            along = std::max(along, e);
        }
        if (along < 5.0 * thin) continue;
        notes.push_back(gs.origin.note(fmt::format(
            "is slender ({:.3g} m long, {:.3g} m thick: {:.0f} particles across); if it bends "
            "through large rotations, {} particles per cell per direction leave it a few percent "
            "too flexible (a cantilever: +6 % at 2, +2 % at 3, +1 % at 4; "
            "docs/scenario-reference.md); consider particles_per_cell: 3 or 4",
            along, thin, std::round(thin / spacing), gs.particles_per_cell)));
    }
}

} // namespace

Prepared prepare_run(Scenario &sc, const SolverOptions &solver) {
    Prepared out;
    RunPlan &plan = out.plan;
    together(solver.comm,
             [&] { plan.estimate = check_memory(sc, plan.memory_total, plan.memory_available); });
    if (plan.memory_available > 0.0 && plan.estimate.bytes > plan.memory_available)
        plan.notes.push_back(fmt::format(
            "talus: note: the run needs about {} of memory, more than is available now ({} of {})",
            bytes_text(plan.estimate.bytes), bytes_text(plan.memory_available),
            bytes_text(plan.memory_total)));
    for (const NamedMaterial &m : sc.materials) {
        const PluginLibrary &lib = m.spec.model->library();
        if (lib.build().known && !lib.build().optimised)
            plan.notes.push_back(
                fmt::format("talus: warning: material '{}': the plugin {} was built without "
                            "optimisation (-O0); "
                            "expect it to run about ten times slower (rebuild it with "
                            "CMAKE_BUILD_TYPE=Release)",
                            m.name, lib.path().string()));
    }
    if (solver.threads > Simulation::processors())
        plan.notes.push_back(fmt::format(
            "talus: note: --threads {} is more than the {} processor(s) this process may run on: "
            "every step waits at its barriers for threads that share a core, so the run is slower "
            "than with {} (the results are the same at any count)",
            solver.threads, Simulation::processors(), Simulation::processors()));
    try {
        out.sim = std::make_unique<Simulation>(sc, solver);
    } catch (const std::bad_alloc &) {
        // Past a limit the estimate does not see (ulimit -v, a cgroup, the
        // other processes): say what and how much instead of bad_alloc.
        throw Error(fmt::format("{}: out of memory while making the grid and the particles "
                                "(about {} needed; {} available to the machine)",
                                sc.file, bytes_text(plan.estimate.bytes),
                                bytes_text(plan.memory_available)));
    }
    const Simulation &sim = *out.sim;
    plan.particles = sim.particle_count();
    out.probe_particles = probe_particles(sc, sim);
    const double dt_crit = sim.critical_dt();
    sim.check_fixed_dt(dt_crit);
    if (sc.solver.dt && *sc.solver.dt > dt_crit) {
        out.sim->fixed_dt_warning_given();
        plan.notes.push_back(sc.solver.dt_origin.warning(fmt::format(
            "the fixed dt {:.4g} s exceeds cfl h / max(c + |v|) = {:.4g} s at t = 0: below the "
            "stability limit ({:.4g} s) but without the cfl margin",
            *sc.solver.dt, dt_crit, dt_crit / sc.solver.cfl)));
    }
    slender_group_notes(sc, sim, plan.notes);
    plan.first_dt = sc.solver.dt ? *sc.solver.dt : dt_crit;
    // Outputs come at most once per step: a cadence far below the step
    // writes a file after every step, most often a unit slip.
    if (sc.output.vtk && sc.output.every > 0.0 && sc.output.every < 0.1 * plan.first_dt)
        plan.notes.push_back(sc.output.every_origin.warning(fmt::format(
            "{:g} s is far below the time step ({:.3g} s at t = 0): outputs come "
            "at most once per step, so every step writes a VTK file (about {:.3g} of them); is "
            "it in the right unit?",
            sc.output.every, plan.first_dt, std::ceil(sc.end_time / plan.first_dt) + 1.0)));
    // A stage's last step is cut to end on its duration: each stage takes
    // at least one step, however short.
    plan.steps = 0.0;
    for (const StageSpec &st : sc.stages)
        plan.steps += std::max(1.0, std::ceil(st.duration / plan.first_dt));
    if (sc.stages.empty()) plan.steps = std::ceil(sc.end_time / plan.first_dt);
    if (sc.output.vtk) {
        // The start, one file per output time and one at the end of every
        // stage (where no output time fell on its last step), at most one
        // per step.
        const double due = sc.output.every > 0.0 ? std::ceil(sc.end_time / sc.output.every) : 1.0;
        const double stage_ends = static_cast<double>(std::max<std::size_t>(sc.stages.size(), 1));
        plan.output_files = std::min(due + stage_ends, plan.steps) + 1.0;
    }
    if (plan.steps > kMaxSteps)
        plan.over_limits.push_back(sc.end_origin.warning(fmt::format(
            "about {:.3g} steps of {:.3g} s (the stable step of the initial state{}) to reach "
            "t = {:g} s: more than {:.0e}; check the end time, the units, the grid cell and the "
            "velocities",
            plan.steps, plan.first_dt, sc.solver.dt ? ", here fixed" : "", sc.end_time,
            kMaxSteps)));
    // Output and checkpoint times are counted as k * every: a cadence
    // finer than time.end / 2^53 cannot be counted (doubles stop holding
    // every integer there).
    if (sc.output.every > 0.0 && !(sc.end_time / sc.output.every < kMaxCadenceCount))
        fail_together(
            solver.comm,
            sc.output.every_origin.error(fmt::format(
                "output.every = {:g} s is too fine to count up to t = {:g} s (more than 2^53 "
                "output times); outputs come at most once per step, so a cadence below the time "
                "step ({:.3g} s) gives the same files as the step itself",
                sc.output.every, sc.end_time, plan.first_dt)));
    if (sc.checkpoint.every && !(sc.end_time / *sc.checkpoint.every < kMaxCadenceCount))
        fail_together(
            solver.comm,
            sc.checkpoint.every_origin.error(fmt::format(
                "checkpoint.every = {:g} s is too fine to count up to t = {:g} s (more than 2^53 "
                "checkpoint times); checkpoint.steps: 1 writes one after every step",
                *sc.checkpoint.every, sc.end_time)));
    if (plan.output_files > kMaxOutputFiles)
        plan.over_limits.push_back(sc.output.every_origin.warning(fmt::format(
            "the run would write about {:.3g} VTK files, more than {:.0e} ({}one at the end of "
            "each of its {} stage(s)); raise output.every{}",
            plan.output_files, kMaxOutputFiles,
            sc.output.every > 0.0
                ? fmt::format("one every {:g} s to t = {:g} s, ", sc.output.every, sc.end_time)
                : std::string(),
            std::max<std::size_t>(sc.stages.size(), 1),
            sc.stages.size() > 1000 ? ", join stages, or set output.vtk: false" : "")));
    return out;
}

// -------------------------------------------------------------- the run --

namespace {

// The smallest k >= from with k * every > t: the next output or checkpoint
// after time t, computed (floor(t / every) + 1, mended by one where the
// division rounds) instead of counted up to one by one, which took for
// ever for a cadence far below the time step. prepare_run keeps t / every
// below 2^53, where doubles still count every integer.
long next_multiple(double t, double every, long from) {
    double k = std::max(std::floor(t / every) + 1.0, static_cast<double>(from));
    if (!(k < kMaxCadenceCount))
        throw Error(fmt::format("a cadence of {:g} s at t = {:.6g} s: more than 2^53 of them "
                                "(output.every or checkpoint.every is too fine)",
                                every, t));
    while (k * every <= t)
        k += 1.0;
    while (k - 1.0 >= static_cast<double>(from) && (k - 1.0) * every > t)
        k -= 1.0;
    return static_cast<long>(k);
}

// Removes a file, or a folder of pieces, of a previous run.
void remove_own(const fs::path &p, const char *why) {
    std::error_code ec;
    if (fs::remove_all(p, ec) == static_cast<std::uintmax_t>(-1) || ec)
        throw Error(fmt::format("{}: cannot remove {}: {}", p.string(), why, ec.message()));
}

// A folder every rank may create at once.
void make_folder(const fs::path &dir) {
    std::error_code ec;
    fs::create_directories(dir, ec);
    if (ec && !fs::is_directory(dir))
        throw Error(fmt::format("{}: cannot create the folder: {}", dir.string(), ec.message()));
}

// Every rank's text, in rank order, on rank 0 (collective; the others get
// their own).
std::string gather_text(const Comm &comm, const std::string &mine) {
    if (!comm.distributed()) return mine;
    const auto *p = reinterpret_cast<const std::byte *>(mine.data());
    std::string all;
    for (const auto &r : comm.gather(std::vector<std::byte>(p, p + mine.size())))
        all.append(reinterpret_cast<const char *>(r.data()), r.size());
    return comm.rank() == 0 ? all : mine;
}

std::string fmt_time(double s) {
    if (!std::isfinite(s)) return "?";
    const long t = static_cast<long>(s + 0.5);
    return fmt::format("{}:{:02d}:{:02d}", t / 3600, (t / 60) % 60, t % 60);
}

// What names a run in its files: its id (Checkpoint::run_id) and the
// digest of its scenario's text as it was read, both kept by its restarts.
struct RunIdentity {
    std::string run_id, scenario_sha256;
};

// Everything a run writes, every write checked (output_file.hpp). The VTK
// file of an output time is complete before its CSV rows are written, so
// no row stands for a file that is not there. On several ranks each writes
// its piece of every VTK output; rank 0 writes the rest, and every write is
// agreed on (together()), so that a failure on any rank stops all of them
// at the same point.
class RunOutput {
  public:
    // With `resume`, continues the output of an interrupted run as it
    // stood at its checkpoint. Collective.
    RunOutput(const fs::path &dir, const Scenario &sc, const Simulation &sim, const RunIdentity &id,
              std::vector<std::int64_t> probe_ids, const OutputProgress *resume = nullptr)
        : dir_(dir), sc_(sc), sim_(sim), id_(id), comm_(sim.comm()), root_(comm_.rank() == 0),
          probe_ids_(std::move(probe_ids)) {
        // State variables to write: those named in output.state, else every
        // one its plugin flags for output.
        fields_ = sc.output.state_fields;
        if (sc.output.all_flagged_state)
            for (const auto &m : sc.materials)
                for (const auto &v : m.spec.state.vars)
                    if (v.output() &&
                        std::find(fields_.begin(), fields_.end(), v.name) == fields_.end())
                        fields_.push_back(v.name);
        together(comm_, [&] {
            if (resume)
                resume_from(*resume);
            else if (root_)
                start();
        });
    }

    int outputs() const { return outputs_; }

    // Where the output stands, every row handed to the OS (for a
    // checkpoint). Rank 0's files only: the others' byte counts are 0.
    OutputProgress progress() {
        OutputProgress o;
        if (diag_.is_open()) {
            diag_.flush();
            o.diagnostics_bytes = diag_.bytes();
        }
        if (prob_.is_open()) {
            prob_.flush();
            o.probes_bytes = prob_.bytes();
        }
        if (stages_.is_open()) {
            stages_.flush();
            o.stages_bytes = stages_.bytes();
        }
        o.next_output = outputs_;
        o.last_written_step = last_written_step_;
        o.stage_first_step = stage_first_step_;
        for (const auto &f : pvd_)
            o.frames.push_back(f.first);
        o.probe_particles = probe_ids_;
        return o;
    }

    // Where the last output went, for messages.
    std::string last_written() const {
        return sc_.output.vtk
                   ? fmt::format("{} and the last row of diagnostics.csv", pvd_.back().second)
                   : "the last row of diagnostics.csv";
    }
    // Whether the current state (this step) has been written.
    bool written_now() const { return last_written_step_ == sim_.steps(); }

    // The end of a stage, after its last output: a row of stages.csv
    // (scenarios with stages only).
    void stage_row(StageEnd why, bool met) {
        together(comm_, [&] {
            if (!stages_.is_open()) return;
            const StageSpec &st = sim_.stages()[sim_.stage()];
            const char *end = why == StageEnd::quiescent ? "quiescent"
                              : st.until && !met         ? "duration_not_quiescent"
                                                         : "duration";
            stages_ << fmt::format("{},{},{},{:.17g},{},{:.17g},{},{:.17g},{}\n", sim_.stage(),
                                   csv_field(st.name), stage_first_step_, sim_.stage_start(),
                                   sim_.steps(), sim_.time(), end, sim_.last_kinetic_energy_ratio(),
                                   outputs_ - 1);
            stages_.flush();
        });
        stage_first_step_ = sim_.steps() + 1;
    }

    // An output time: the VTK file and the collection, then the rows
    // (collective).
    void write() {
        if (sc_.output.vtk) {
            const std::string name = particles(fmt::format("particles_{:05d}", outputs_));
            pvd_.emplace_back(sim_.time(), name);
            // A valid collection after every frame, so that a run stopped
            // early leaves one: written whole at the first, then grown.
            together(comm_, [&] {
                if (!root_) return;
                if (collection_.is_open())
                    collection_.append(pvd_.back().first, pvd_.back().second);
                else
                    collection_.start(dir_ / "particles.pvd", pvd_);
            });
        }
        rows();
        ++outputs_;
        last_written_step_ = sim_.steps();
    }

    // The state when a step failed: failure_step<N>.vtu (.pvtu and its
    // pieces on several ranks) and a last row of each CSV. Returns where
    // it went (or why it could not be written) for the error message.
    // `all_ranks`: every rank is here (an agreed failure); otherwise this
    // rank writes its piece alone (a crash).
    // `state`: what the particles are in (default: part way through the
    // next step).
    std::string write_failure(bool all_ranks = true, const std::string &state = {}) noexcept {
        try {
            const std::string stem = fmt::format("failure_step{}", sim_.steps() + 1);
            const std::string how =
                state.empty()
                    ? fmt::format("particles may be part way through step {}", sim_.steps() + 1)
                    : state;
            fs::path file;
            if (all_ranks || !comm_.distributed()) {
                file = dir_ / particles(stem);
                rows();
            } else {
                file = dir_ / stem / piece(comm_.rank());
                make_folder(file.parent_path());
                write_vtu(file, sim_, fields_);
                return fmt::format("\nthe state of rank {} when it stopped is in {} ({})",
                                   comm_.rank(), file.string(), how);
            }
            return fmt::format(
                "\nthe state when the run stopped is in {} and the last row of diagnostics.csv "
                "({})",
                file.string(), how);
        } catch (const std::exception &e) {
            return fmt::format("\nthe state when the run stopped could not be written: {}",
                               e.what());
        }
    }

  private:
    // The piece of rank r, in the folder of its output time.
    static std::string piece(int r) { return fmt::format("rank_{:04d}.vtu", r); }

    // The particles now as `stem`.vtu; on several ranks as a piece per rank
    // in the folder `stem` and `stem`.pvtu naming them (collective).
    // Returns the file name, relative to the run's folder.
    std::string particles(const std::string &stem) {
        if (!comm_.distributed()) {
            write_vtu(dir_ / (stem + ".vtu"), sim_, fields_);
            return stem + ".vtu";
        }
        together(comm_, [&] {
            make_folder(dir_ / stem);
            write_vtu(dir_ / stem / piece(comm_.rank()), sim_, fields_);
        });
        together(comm_, [&] {
            if (!root_) return;
            std::vector<std::string> pieces;
            for (int r = 0; r < comm_.size(); ++r)
                pieces.push_back(stem + "/" + piece(r));
            write_pvtu(dir_ / (stem + ".pvtu"), sim_, fields_, pieces);
        });
        return stem + ".pvtu";
    }

    // A new run's files (rank 0): first what made this run, before any
    // result exists, then the CSV headers.
    void start() {
        Provenance prov;
        prov.command = "run";
        prov.input_file = sc_.file;
        for (const auto &m : sc_.materials)
            prov.materials.push_back({m.name, &m.spec});
        prov.input_sha256 = id_.scenario_sha256;
        prov.run_id = id_.run_id;
        write_file_atomically(dir_ / "provenance.json", provenance_json(prov));
        diag_ = OutputFile(dir_ / "diagnostics.csv");
        diag_ << "step,time,dt,mass,momentum_x,momentum_y,momentum_z,kinetic_energy,stress_work,"
                 "angular_momentum_x,angular_momentum_y,angular_momentum_z,particles,removed,"
                 "cut_steps,held_at_faces,stage\n";
        diag_.flush();
        if (!sc_.stages.empty()) {
            stages_ = OutputFile(dir_ / "stages.csv");
            stages_ << "stage,name,first_step,start_time,last_step,end_time,end,"
                       "kinetic_energy_ratio,last_output\n";
            stages_.flush();
        }
        if (!sc_.output.probes.empty()) {
            prob_ = OutputFile(dir_ / "probes.csv");
            std::string h = "time";
            const char *axes = "xyz";
            for (const Probe &p : sc_.output.probes) {
                const bool particle = p.kind == Probe::Kind::particle;
                auto column = [&](const std::string &what) {
                    h += ',' + csv_field(p.name + '.' + what);
                };
                for (int d = 0; d < sc_.dim; ++d)
                    column(std::string(1, axes[d]));
                if (particle)
                    for (int d = 0; d < sc_.dim; ++d)
                        column(std::string("u") + axes[d]);
                for (int d = 0; d < sc_.dim; ++d)
                    column(std::string("v") + axes[d]);
                if (particle)
                    for (const char *c : {"xx", "yy", "zz", "xy", "yz", "xz"})
                        column(std::string("sig_") + c);
            }
            prob_ << h << "\n";
            prob_.flush();
        }
    }

    // The files as they stood at the checkpoint: the CSV files cut back to
    // its length, the VTK files written after it removed, the collection
    // rewritten (rank 0; the others only take up the count).
    void resume_from(const OutputProgress &o) {
        outputs_ = static_cast<int>(o.next_output);
        last_written_step_ = o.last_written_step;
        stage_first_step_ = o.stage_first_step;
        // The frames so far as they were written: .pvtu by several ranks,
        // .vtu by one (the checkpoint may be of another number of ranks).
        for (std::size_t k = 0; k < o.frames.size(); ++k) {
            const std::string stem = fmt::format("particles_{:05d}", k);
            std::error_code ec;
            pvd_.emplace_back(o.frames[k], fs::exists(dir_ / (stem + ".pvtu"), ec) ? stem + ".pvtu"
                                                                                   : stem + ".vtu");
        }
        if (!root_) return;
        diag_ = OutputFile::resume(dir_ / "diagnostics.csv", o.diagnostics_bytes);
        if (!sc_.output.probes.empty())
            prob_ = OutputFile::resume(dir_ / "probes.csv", o.probes_bytes);
        if (!sc_.stages.empty()) stages_ = OutputFile::resume(dir_ / "stages.csv", o.stages_bytes);
        std::error_code ec;
        std::vector<fs::path> after;
        for (const auto &e : fs::directory_iterator(dir_, ec)) {
            const std::string name = e.path().filename().string();
            int k = -1;
            char tail[8] = {};
            const bool later = std::sscanf(name.c_str(), "particles_%d%7s", &k, tail) >= 1 &&
                               k >= outputs_ && is_own_file(e.path());
            const bool stale = name.rfind("failure_", 0) == 0 || name == "final_particles.csv" ||
                               name == "failed_call.yaml";
            if (later || stale) after.push_back(e.path());
        }
        if (ec)
            throw Error(fmt::format("{}: cannot list the folder: {}", dir_.string(), ec.message()));
        for (const fs::path &p : after)
            remove_own(p, "a file written after the checkpoint");
        if (sc_.output.vtk) collection_.start(dir_ / "particles.pvd", pvd_);
    }

    // A row of diagnostics.csv and of probes.csv (collective: the sums are
    // over the ranks; rank 0 writes).
    void rows() {
        const Diagnostics dg = sim_.diagnostics();
        // Each probe's values: a particle probe's from the rank that holds
        // the particle (the others add zeros), a group probe's sums from
        // every rank; then one sum over the ranks.
        const int D = sc_.dim;
        const std::size_t Dz = static_cast<std::size_t>(D);
        const std::size_t P = sc_.output.probes.size();
        std::vector<double> val, found(P, 0.0);
        std::vector<std::size_t> at(P);
        for (std::size_t i = 0; i < P; ++i) {
            const Probe &probe = sc_.output.probes[i];
            at[i] = val.size();
            const bool particle = probe.kind == Probe::Kind::particle;
            val.resize(val.size() + (particle ? 3 * Dz + 6 : 1 + 2 * Dz), 0.0);
            double *v = &val[at[i]];
            for (const auto &s : sim_.sets())
                for (std::size_t k = 0; k < s.n; ++k) {
                    if (particle && s.id[k] == probe_ids_[i]) {
                        found[i] = 1.0;
                        for (std::size_t d = 0; d < Dz; ++d) {
                            v[d] = s.x[d][k];
                            v[Dz + d] = s.x[d][k] - s.x0[d][k];
                            v[2 * Dz + d] = s.v[d][k];
                        }
                        for (std::size_t c = 0; c < 6; ++c)
                            v[3 * Dz + c] = s.stress[6 * k + c];
                    } else if (!particle && static_cast<std::size_t>(s.group[k]) == probe.group) {
                        v[0] += s.mass[k];
                        for (std::size_t d = 0; d < Dz; ++d) {
                            v[1 + d] += s.mass[k] * s.x[d][k];
                            v[1 + Dz + d] += s.mass[k] * s.v[d][k];
                        }
                    }
                }
        }
        if (comm_.distributed() && P > 0) {
            comm_.sum(val.data(), val.size());
            comm_.sum(found.data(), found.size());
        }
        together(comm_, [&] {
            if (!root_) return;
            diag_ << fmt::format(
                "{},{:.17g},{:.17g},{:.17g},{:.17g},{:.17g},{:.17g},{:.17g},{:.17g},"
                "{:.17g},{:.17g},{:.17g},{},{},{},{},{}\n",
                dg.step, dg.time, dg.dt, dg.mass, dg.momentum[0], dg.momentum[1], dg.momentum[2],
                dg.kinetic_energy, dg.stress_work, dg.angular_momentum[0], dg.angular_momentum[1],
                dg.angular_momentum[2], dg.particles, dg.removed, dg.cut_steps, dg.held_at_faces,
                sim_.stage());
            diag_.flush();
            if (!prob_.is_open()) return;
            std::string row = fmt::format("{:.17g}", sim_.time());
            for (std::size_t i = 0; i < P; ++i) {
                const double *v = &val[at[i]];
                if (sc_.output.probes[i].kind == Probe::Kind::particle) {
                    // NaN once removed (it left the grid, or its group was
                    // removed).
                    for (int c = 0; c < 3 * D + 6; ++c)
                        row += found[i] > 0.0 ? fmt::format(",{:.17g}", v[c]) : ",nan";
                } else {
                    const double m = v[0];
                    for (int c = 1; c < 1 + 2 * D; ++c)
                        row += fmt::format(",{:.17g}", m > 0 ? v[c] / m : NAN);
                }
            }
            prob_ << row << "\n";
            prob_.flush();
        });
    }

    fs::path dir_;
    const Scenario &sc_;
    const Simulation &sim_;
    RunIdentity id_;
    const Comm &comm_;
    bool root_ = true; // rank 0 writes all but the pieces
    std::vector<std::int64_t> probe_ids_;
    std::vector<std::string> fields_;
    OutputFile diag_, prob_, stages_;
    std::vector<std::pair<double, std::string>> pvd_;
    PvdFile collection_; // rank 0's particles.pvd
    int outputs_ = 0;
    long last_written_step_ = -1;
    long stage_first_step_ = 1;
};

// When a plugin failed at one particle, the driver case that replays that
// call (`talus point`), for the message.
std::string write_replay_case(const Simulation &sim, const fs::path &dir) noexcept {
    if (!sim.failed_call()) return "";
    try {
        const fs::path file = dir / "failed_call.yaml";
        write_file_atomically(file, replay_case_yaml(*sim.failed_call(), sim.scenario()));
        return fmt::format("\nthe failed plugin call is replayed by: talus point {}",
                           file.string());
    } catch (const std::exception &e) {
        return fmt::format("\nthe failed plugin call could not be written for replay: {}",
                           e.what());
    }
}

// The crash handler's last action (crash_report.hpp): the state at the
// crash, best effort (the heap may be what the plugin broke).
void write_state_after_crash(void *context) {
    auto *out = static_cast<RunOutput *>(context);
    // One write: the lines of several ranks do not interleave.
    const std::string where =
        out->write_failure(/*all_ranks=*/false).substr(1) + " (best effort after a crash)\n";
    ::write(STDERR_FILENO, where.data(), where.size());
}

struct ClearLastAction {
    ~ClearLastAction() { crash::set_last_action(nullptr, nullptr); }
};

} // namespace

namespace {

// Where a state variable of that name sits in each material's state vector
// (-1: the material lacks it). Throws when no material has it as a scalar.
std::vector<long> final_field_offsets(const Scenario &sc, const std::string &field) {
    std::vector<long> where(sc.materials.size(), -1);
    std::vector<std::string> known(std::begin(kFinalFieldBuiltins), std::end(kFinalFieldBuiltins));
    bool found = false;
    for (std::size_t m = 0; m < sc.materials.size(); ++m)
        for (const auto &v : sc.materials[m].spec.state.vars) {
            if (std::find(known.begin(), known.end(), v.name) == known.end())
                known.push_back(v.name);
            if (v.name != field) continue;
            if (v.size != 1)
                throw Error(fmt::format("--plot-field {}: a state variable of {} values; only "
                                        "scalar ones can be drawn",
                                        field, v.size));
            where[m] = static_cast<long>(v.offset);
            found = true;
        }
    if (!found) {
        const std::string guess = yaml::closest_match(field, known);
        std::string list;
        for (const std::string &k : known)
            list += (list.empty() ? "" : ", ") + k;
        throw Error(fmt::format("--plot-field {}: no such field{}; this scenario has: {}", field,
                                guess.empty() ? "" : fmt::format(" (did you mean '{}'?)", guess),
                                list));
    }
    return where;
}

bool is_builtin_field(const std::string &field) {
    for (const char *b : kFinalFieldBuiltins)
        if (field == b) return true;
    return false;
}

// final_particles.csv: one row per particle; NaN where a particle's
// material lacks the state variable. The field is resolved once, not per
// particle.
void write_final_particles(const fs::path &file, const Simulation &sim, const std::string &field,
                           const std::vector<long> &offsets) {
    enum class Kind { displacement, speed, p, q, J, state };
    const Kind kind = field == "displacement" ? Kind::displacement
                      : field == "speed"      ? Kind::speed
                      : field == "p"          ? Kind::p
                      : field == "q"          ? Kind::q
                      : field == "J"          ? Kind::J
                                              : Kind::state;
    const int D = sim.scenario().dim;
    std::string text; // this rank's rows
    auto out = std::back_inserter(text);
    for (const ParticleSet &s : sim.sets())
        for (std::size_t p = 0; p < s.n; ++p) {
            double value = std::numeric_limits<double>::quiet_NaN();
            const auto stress = [&] { return Eigen::Map<const sdk::Vec6>(&s.stress[6 * p]); };
            const auto norm = [&](auto component) {
                double sum = 0.0;
                for (std::size_t d = 0; d < static_cast<std::size_t>(D); ++d)
                    sum += component(d) * component(d);
                return std::sqrt(sum);
            };
            switch (kind) {
            case Kind::displacement:
                value = norm([&](std::size_t d) { return s.x[d][p] - s.x0[d][p]; });
                break;
            case Kind::speed: value = norm([&](std::size_t d) { return s.v[d][p]; }); break;
            case Kind::p: value = sdk::mean_pressure(stress()); break;
            case Kind::q: value = sdk::von_mises(stress()); break;
            case Kind::J: value = s.J[p]; break;
            case Kind::state:
                if (offsets[s.material] >= 0)
                    value =
                        s.state[s.state_size * p + static_cast<std::size_t>(offsets[s.material])];
                break;
            }
            fmt::format_to(out, "{},{}", s.id[p], s.group[p]);
            for (std::size_t d = 0; d < static_cast<std::size_t>(D); ++d)
                fmt::format_to(out, ",{:.9g}", s.x[d][p]);
            fmt::format_to(out, ",{:.9g}\n", value);
        }
    // Rank 0 writes every rank's rows, in rank order.
    const Comm &comm = sim.comm();
    std::string all = D == 3 ? "id,group,x,y,z," : "id,group,x,y,";
    all += field;
    all += '\n';
    all += gather_text(comm, text);
    together(comm, [&] {
        if (comm.rank() == 0) write_file_atomically(file, all);
    });
}

} // namespace

namespace {

// The scenario's text, for the checkpoints; empty if it cannot be read.
std::string scenario_text_of(const Scenario &sc) {
    try {
        return yaml::read_text_file(sc.file);
    } catch (const Error &) {
        return {};
    }
}

// Writes checkpoints/checkpoint_<step>.h5 and keeps the newest `keep`.
class Checkpoints {
  public:
    // `spared_step`: the step of the checkpoint a restart continues from,
    // kept however many come after it, so that the command the user gave
    // can be given again; -1 for none.
    Checkpoints(const fs::path &dir, const Scenario &sc, std::string text, const RunIdentity &id,
                long spared_step)
        : dir_(dir / "checkpoints"), sc_(sc), text_(std::move(text)), id_(id),
          plugins_(plugin_identities(sc)), spared_step_(spared_step) {}

    bool possible() const { return !text_.empty(); }

    // Collective: on several ranks each writes its own file, rank 0 its
    // own last (rank_checkpoint_file()).
    fs::path write(const Simulation &sim, RunOutput &out, long next_due, long particle_steps) {
        const Comm &comm = sim.comm();
        Checkpoint c;
        together(comm, [&] {
            if (!possible())
                throw Error(fmt::format("{}: the scenario's text could not be read, so no "
                                        "checkpoint can be written",
                                        sc_.file));
            make_folder(dir_);
            c.output = out.progress();
        });
        c.scenario_path = fs::absolute(sc_.file).string();
        c.scenario_text = text_;
        c.scenario_sha256 = id_.scenario_sha256;
        c.run_id = id_.run_id;
        c.plugins = plugins_;
        c.output.next_due = next_due;
        c.output.particle_steps = particle_steps;
        try {
            c.state = sim.snapshot();
        } catch (const std::bad_alloc &) {
            // (particle_count() is collective: not here, on one rank.)
            throw Error(fmt::format("{}: out of memory while copying the particles for a "
                                    "checkpoint (a copy of every particle column)",
                                    dir_.string()));
        }
        const fs::path file = dir_ / fmt::format("checkpoint_{:010d}.h5", sim.steps());
        together(comm, [&] {
            if (comm.rank() != 0) write_checkpoint(rank_checkpoint_file(file, comm.rank()), c);
        });
        together(comm, [&] {
            if (comm.rank() != 0) return;
            write_checkpoint(file, c);
            prune();
        });
        ++written_;
        return file;
    }
    int written() const { return written_; }

  private:
    // The newest `keep` complete checkpoints stay (rank 0's file there),
    // with their ranks' files, and the one this restart started from; older
    // ones go, rank 0's file first, so that an interrupted removal never
    // leaves one that looks complete.
    void prune() {
        std::map<long, std::vector<fs::path>> by_step; // rank 0's file first in each
        std::vector<long> complete;
        std::error_code ec;
        for (const auto &e : fs::directory_iterator(dir_, ec)) {
            const std::string name = e.path().filename().string();
            long step = -1;
            char rest[16] = {};
            if (e.path().extension() != ".h5" ||
                std::sscanf(name.c_str(), "checkpoint_%ld%15s", &step, rest) < 1)
                continue;
            std::vector<fs::path> &files = by_step[step];
            if (std::string(rest) == ".h5") {
                files.insert(files.begin(), e.path());
                complete.push_back(step);
            } else {
                files.push_back(e.path());
            }
        }
        if (ec)
            throw Error(
                fmt::format("{}: cannot list the checkpoints: {}", dir_.string(), ec.message()));
        std::sort(complete.begin(), complete.end());
        const std::size_t keep = static_cast<std::size_t>(sc_.checkpoint.keep);
        if (complete.size() <= keep) return;
        const long oldest_kept = complete[complete.size() - keep];
        for (const auto &[step, files] : by_step) {
            if (step >= oldest_kept) break;
            if (step == spared_step_) continue;
            for (const fs::path &f : files)
                if (!fs::remove(f, ec) && ec)
                    throw Error(fmt::format("{}: cannot remove an old checkpoint: {}", f.string(),
                                            ec.message()));
        }
    }
    fs::path dir_;
    const Scenario &sc_;
    std::string text_;
    RunIdentity id_;
    std::vector<PluginIdentity> plugins_;
    long spared_step_ = -1;
    int written_ = 0;
};

// A step (or a stage's start) failed: the state then goes to the output
// and, for a plugin's failure, the call to replay; the message says where.
// On several ranks an agreed failure is written by all of them (the failed
// call by the rank it failed on) and rank 0's message names every file;
// any other failure is one rank's alone and goes up as it is.
[[noreturn]] void failed(const Error &e, RunOutput &out, const Simulation &sim, const fs::path &dir,
                         const std::string &state = {}) {
    const Comm &comm = sim.comm();
    if (!comm.distributed())
        throw Error(e.what() + out.write_failure(true, state) + write_replay_case(sim, dir));
    if (!dynamic_cast<const AgreedError *>(&e)) throw;
    const std::string where = out.write_failure(true, state);
    throw AgreedError(e.what() + where + gather_text(comm, write_replay_case(sim, dir)));
}

// `said`: where a verbose run notes each output (null: nowhere).
void write_or_stop(RunOutput &out, const Simulation &sim, std::ostream *said) {
    try {
        out.write();
        if (said)
            *said << fmt::format("talus: output {} at t = {:.6g} s (step {})\n", out.outputs() - 1,
                                 sim.time(), sim.steps());
    } catch (const Error &e) {
        const std::string m = fmt::format("{}\nthe run stopped at step {} (t = {:.6g} s)", e.what(),
                                          sim.steps(), sim.time());
        if (dynamic_cast<const AgreedError *>(&e)) throw AgreedError(m);
        throw Error(m);
    }
}

// A checkpoint written, or the run stopped with the state now written
// (a checkpoint that cannot be written, the disk full, is no reason to
// lose the state it was to keep).
fs::path checkpoint_or_stop(Checkpoints &checkpoints, const Simulation &sim, RunOutput &out,
                            long next_due, long particle_steps) {
    try {
        return checkpoints.write(sim, out, next_due, particle_steps);
    } catch (const Error &e) {
        const bool agreed = dynamic_cast<const AgreedError *>(&e) != nullptr;
        if (sim.comm().distributed() && !agreed) throw;
        const std::string m =
            fmt::format("{}\nthe run stopped at step {} (t = {:.6g} s): its checkpoint could not "
                        "be written{}",
                        e.what(), sim.steps(), sim.time(),
                        out.write_failure(
                            true, fmt::format("particles as at the end of step {}", sim.steps())));
        if (agreed) throw AgreedError(m);
        throw Error(m);
    }
}

// The run's folder taken (on every rank, agreed): there to continue in, a
// folder, and locked by rank 0 against a second run (run_folder.hpp).
void take_folder(std::optional<FolderLock> &lock, const fs::path &dir, const RunOptions &opt,
                 const Comm &comm) {
    together(comm, [&] {
        std::error_code ec;
        if (opt.restart && !fs::is_directory(dir, ec))
            throw Error(fmt::format("{}: no such folder: the checkpoint's run output is not there",
                                    dir.string()));
        if (fs::exists(dir, ec) && !fs::is_directory(dir, ec))
            throw Error(fmt::format("{}: exists and is not a directory", dir.string()));
        if (comm.rank() == 0)
            lock.emplace(dir, opt.restart ? FolderLock::For::restart : FolderLock::For::new_run);
    });
}

// The run's name and its scenario's digest: a new run's (rank 0's name on
// every rank), or those of the run a checkpoint continues.
RunIdentity run_identity(const RunOptions &opt, const Scenario &sc, const std::string &text,
                         const Comm &comm) {
    RunIdentity id;
    if (opt.restart)
        id = {opt.restart->run_id, opt.restart->scenario_sha256};
    else
        id.scenario_sha256 = text.empty() ? sha256_file(sc.file) : sha256_bytes(text);
    // A checkpoint of a Talus that named no runs goes on under a new name.
    if (id.run_id.empty()) {
        std::string mine = comm.rank() == 0 ? new_run_id() : std::string(32, ' ');
        const auto *p = reinterpret_cast<const std::byte *>(mine.data());
        const std::vector<std::byte> all =
            comm.broadcast(std::vector<std::byte>(p, p + mine.size()), 0);
        id.run_id.assign(reinterpret_cast<const char *>(all.data()), all.size());
    }
    return id;
}

// What a run refuses before any work (on every rank, agreed): a misspelt
// --plot-field, a checkpoint of other binaries (unless --force-restart),
// another run's folder to continue in, a previous run's files (unless
// --force).
// Returns the final field's state offsets per material.
std::vector<long> refuse_before_work(const Scenario &sc, const RunOptions &opt, const fs::path &dir,
                                     std::ostream &log) {
    std::vector<long> final_offsets;
    // A misspelt field is refused before any work, not after the run.
    if (!opt.final_field.empty() && !is_builtin_field(opt.final_field))
        final_offsets = final_field_offsets(sc, opt.final_field);
    else
        final_offsets.assign(sc.materials.size(), -1);
    // Refuse before any work: a previous run's files are never
    // overwritten silently.
    std::error_code ec;
    if (opt.restart) {
        const std::vector<std::string> diff =
            identity_differences(*opt.restart, plugin_identities(sc));
        if (!diff.empty()) {
            std::string all;
            for (const std::string &d : diff)
                all += "\n  " + d;
            if (!opt.force_restart)
                throw Error(fmt::format(
                    "the checkpoint was written by other binaries than this run would use:{}\n"
                    "the run was not continued: a result made by two builds is not one "
                    "result; pass --force-restart to continue anyway",
                    all));
            log << fmt::format("talus: warning: continuing with other binaries than the "
                               "checkpoint's (--force-restart):{}\n",
                               all);
        }
        refuse_foreign_folder(dir, *opt.restart);
    } else if (fs::exists(dir, ec)) {
        // A new run removes the previous run's checkpoints: never through
        // a link (checkpoints/ on a scratch disk), into a folder that may
        // hold more than this run's.
        const fs::path ck = dir / "checkpoints";
        if (fs::is_symlink(ck, ec) && fs::is_directory(ck, ec))
            for (const auto &e : fs::directory_iterator(ck, ec))
                if (e.path().extension() == ".h5")
                    throw Error(fmt::format(
                        "{}: a symbolic link (to {}) to a folder that holds checkpoints ({}, "
                        "...): a new run would remove them there; empty that folder, or point "
                        "the link at an empty one",
                        ck.string(), fs::read_symlink(ck, ec).string(),
                        e.path().filename().string()));
        std::vector<fs::path> previous;
        for (const auto &e : fs::directory_iterator(dir, ec))
            if (is_own_file(e.path())) previous.push_back(e.path());
        if (ec)
            throw Error(fmt::format("{}: cannot list the folder: {}", dir.string(), ec.message()));
        std::sort(previous.begin(), previous.end());
        if (!previous.empty() && !opt.force)
            throw Error(fmt::format(
                "{}: holds the output of a previous run ({} and {} more file(s)); "
                "pass --force to overwrite it, or choose another --output-dir",
                dir.string(), previous.front().filename().string(), previous.size() - 1));
    }
    return final_offsets;
}

// The previous run's files and checkpoints removed, the folder made (rank 0).
void clear_previous_output(const fs::path &dir, const RunOptions &opt) {
    std::error_code ec;
    if (!opt.restart && fs::exists(dir / "checkpoints", ec))
        for (const auto &e : fs::directory_iterator(dir / "checkpoints", ec))
            if (e.path().extension() == ".h5" && !fs::remove(e.path(), ec) && ec)
                throw Error(fmt::format("{}: cannot remove the previous run's checkpoint: {}",
                                        e.path().string(), ec.message()));
    if (!opt.restart && fs::exists(dir, ec)) {
        std::vector<fs::path> old;
        for (const auto &e : fs::directory_iterator(dir, ec))
            if (is_own_file(e.path())) old.push_back(e.path());
        for (const fs::path &p : old)
            remove_own(p, "the previous run's file");
    }
    make_folder(dir);
}

// A stage with until: that did not come to rest: the run stops (agreed on
// every rank) or, with until.otherwise: continue, warns and goes on.
void not_at_rest(const StageSpec &stage, const Simulation &sim, const RunOutput &out,
                 const Comm &comm, std::ostream &log) {
    const std::string what = fmt::format(
        "stage '{}' did not come to rest within its duration of {:g} s: the kinetic "
        "energy ratio is {:.3g} at t = {:.6g} s, the limit {:.3g}{}; the state at the "
        "stage's end is in {}",
        stage.name, stage.duration, sim.last_kinetic_energy_ratio(), sim.time(),
        stage.until->kinetic_energy_ratio,
        sim.quiet_since() ? fmt::format(" (below it since t = {:.6g} s, not yet for the hold time)",
                                        *sim.quiet_since())
                          : std::string(),
        out.last_written());
    if (stage.until->stop_if_not_met)
        fail_together(comm,
                      stage.until->origin.error(
                          what + "; lengthen the duration or damp more, or set until.otherwise: "
                                 "continue to go on regardless"));
    log << stage.until->origin.warning(what + "; going on (until.otherwise: continue)") << '\n';
}

// After a SIGTERM or SIGINT (on any rank): a checkpoint, and the command
// that continues the run, in the Interrupted the run ends with.
void stop_if_signalled(const Comm &comm, Checkpoints &checkpoints, Simulation &sim, RunOutput &out,
                       long next_k, long particle_steps) {
    int sig = stop_signal();
    // A launcher signals every rank, not at the same step: all stop at the
    // first step's end where any has been.
    if (comm.distributed()) sig = static_cast<int>(comm.max(static_cast<double>(sig)));
    if (!sig) return;
    stop_signal_seen();

    const char *name = sig == SIGTERM ? "SIGTERM" : sig == SIGINT ? "SIGINT" : "a signal";
    if (!checkpoints.possible()) // the same on every rank
        throw Interrupted(fmt::format("talus: stopped by {} at step {} (t = {:.6g} s); no "
                                      "checkpoint could be written: {}",
                                      name, sim.steps(), sim.time(),
                                      "the scenario's text could not be read"),
                          sig);
    const fs::path file = checkpoint_or_stop(checkpoints, sim, out, next_k, particle_steps);
    throw Interrupted(
        fmt::format("talus: stopped by {} at step {} (t = {:.6g} s); the run continues with: "
                    "{}talus run --restart {}{}",
                    name, sim.steps(), sim.time(),
                    comm.distributed() ? fmt::format("mpirun -np {} ", comm.size()) : std::string(),
                    file.string(), comm.distributed() ? " (or on any other number of ranks)" : ""),
        sig);
}

// One progress line: a live one on a terminal, a plain one in a log.
void print_progress(const RunOptions &opt, const Simulation &sim, double end, double elapsed,
                    double rate, double eta) {
    std::fprintf(stderr,
                 "%sstep %ld  t = %.4g / %.4g s  dt = %.3g s  elapsed %s  ETA %s  "
                 "%.3g particle-steps/s%s",
                 opt.progress_tty ? "\r" : "talus: progress: ", sim.steps(), sim.time(), end,
                 sim.last_dt(), fmt_time(elapsed).c_str(), fmt_time(eta).c_str(), rate,
                 opt.progress_tty ? "   " : "\n");
    std::fflush(stderr);
}

RunSummary summary(const Simulation &sim, const Comm &comm, double seconds, long particle_steps,
                   int outputs, int checkpoints, const fs::path &dir) {
    RunSummary rs;
    rs.steps = sim.steps();
    rs.time = sim.time();
    rs.seconds = seconds;
    rs.particles = sim.particle_count();
    rs.ranks = comm.size();
    rs.particle_steps_per_second = static_cast<double>(particle_steps) / std::max(seconds, 1e-9);
    rs.outputs = outputs;
    rs.checkpoints = checkpoints;
    rs.output_dir = dir;
    return rs;
}

// What the run will do, or where it continues from, before its first step.
void log_start(const RunOptions &opt, const Simulation &sim, const Comm &comm,
               std::size_t particles, const RunPlan &plan, double end, std::ostream &log) {
    if (!opt.progress) return;
    const std::string spread =
        comm.distributed()
            ? fmt::format(" on {} ranks of {} thread(s)", comm.size(), Simulation::max_threads())
            : std::string();
    if (opt.restart)
        log << fmt::format("talus: continuing from step {} (t = {:.6g} s{}), {} particles{}\n",
                           sim.steps(), sim.time(),
                           sim.stages().size() > 1 || !sim.stages()[0].name.empty()
                               ? fmt::format(", stage '{}'", sim.stages()[sim.stage()].name)
                               : std::string(),
                           particles, spread);
    else
        log << fmt::format("talus: {} particles{}; about {:.3g} steps of {:.3g} s to t = {:g} s "
                           "(estimated from the initial state)\n",
                           particles, spread, plan.steps, plan.first_dt, end);
}

// The end of a stage of a scenario in stages, and why it ended.
void log_stage_end(const RunOptions &opt, const StageSpec &stage, const Simulation &sim, bool met,
                   std::ostream &log) {
    if (opt.progress && opt.progress_tty) std::fprintf(stderr, "\n");
    log << fmt::format(
        "talus: stage '{}' ended at t = {:.6g} s (step {}): {}\n", stage.name, sim.time(),
        sim.steps(),
        met ? fmt::format("at rest (kinetic energy ratio {:.3g})", sim.last_kinetic_energy_ratio())
            : "its duration");
}

// The Simulation from the scenario, or from the checkpoint a restart
// continues; the plan's notes logged, and a run over the limits refused
// unless allowed.
Prepared prepare_or_restore(Scenario &sc, const RunOptions &opt, std::ostream &log) {
    Prepared prep;
    if (opt.restart) {
        prep.sim = std::make_unique<Simulation>(sc, opt.solver, opt.restart->state);
        prep.probe_particles = opt.restart->output.probe_particles;
    } else {
        prep = prepare_run(sc, opt.solver);
    }
    // A note of the plan is said unless quiet; a warning always.
    for (const std::string &n : prep.plan.notes)
        if (opt.verbosity != Verbosity::quiet ||
            n.substr(0, n.find('\n')).find("warning:") != std::string::npos)
            log << n << '\n';
    if (!prep.plan.over_limits.empty()) {
        std::string all;
        for (const std::string &w : prep.plan.over_limits)
            all += (all.empty() ? "" : "\n") + w;
        if (!opt.allow_large)
            fail_together(opt.solver.comm,
                          all + "\nthe run was not started; pass --allow-large to run it anyway");
        log << all << '\n';
    }
    return prep;
}

} // namespace

RunSummary run_scenario(Scenario &sc, const RunOptions &opt, std::ostream &log) {
    // On several ranks every rank runs this function; rank 0 writes the
    // files all ranks share and the log (the others get a silent one), and
    // every failure is agreed on (together(), fail_together()) so that all
    // ranks stop at the same point.
    const Comm &comm = opt.solver.comm;
    const bool root = comm.rank() == 0;
    // Notes go where warnings go, unless quiet; a verbose run's details
    // (each output and checkpoint) only when verbose.
    std::ostream nowhere(nullptr);
    std::ostream &notes = opt.verbosity == Verbosity::quiet ? nowhere : log;
    std::ostream *said = opt.verbosity == Verbosity::verbose ? &log : nullptr;
    const fs::path dir = opt.output_dir.empty() ? default_output_dir(sc.file) : opt.output_dir;
    std::optional<FolderLock> lock;
    take_folder(lock, dir, opt, comm);
    if (lock && !lock->warning().empty()) log << lock->warning() << '\n';
    std::vector<long> final_offsets;
    together(comm, [&] { final_offsets = refuse_before_work(sc, opt, dir, log); });
    Prepared prep = prepare_or_restore(sc, opt, log);
    Simulation &sim = *prep.sim;

    // Now the old files go: a run refused above leaves them as they were.
    together(comm, [&] {
        if (root) clear_previous_output(dir, opt);
    });

    const std::string text = opt.restart                 ? opt.restart->scenario_text
                             : opt.scenario_text.empty() ? scenario_text_of(sc)
                                                         : opt.scenario_text;
    const RunIdentity id = run_identity(opt, sc, text, comm);
    RunOutput out(dir, sc, sim, id, prep.probe_particles,
                  opt.restart ? &opt.restart->output : nullptr);
    std::optional<Checkpoints> made;
    together(comm, [&] {
        made.emplace(dir, sc, text, id, opt.restart ? opt.restart->state.step : -1L);
        if (!made->possible() && (sc.checkpoint.every || sc.checkpoint.steps || sc.checkpoint.wall))
            throw Error(fmt::format("{}: cannot read the scenario's text, which every checkpoint "
                                    "stores",
                                    sc.file));
    });
    Checkpoints &checkpoints = *made;
    const StopSignals stop_signals(comm.rank() == 0 && opt.progress);
    crash::set_last_action(write_state_after_crash, &out);
    const ClearLastAction clear_on_exit;

    const auto start = std::chrono::steady_clock::now();
    auto elapsed = [&] {
        return std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    };
    double last_progress = -1.0;
    long particle_steps = opt.restart ? opt.restart->output.particle_steps : 0;
    std::size_t warnings_shown = 0;
    if (!opt.restart) write_or_stop(out, sim, nullptr);
    const double end = sc.end_time;
    const std::size_t particles = sim.particle_count(); // collective: on every rank
    log_start(opt, sim, comm, particles, prep.plan, end, log);
    if (said) {
        for (const PluginIdentity &p : plugin_identities(sc))
            *said << describe(p) << '\n';
        if (!opt.restart) *said << "talus: output 0 at t = 0 s (step 0)\n";
    }
    // The rate is of this process's steps.
    const long particle_steps_before = particle_steps;
    const double time_before = sim.time();
    const long steps_before = sim.steps();
    const int outputs_before = out.outputs();
    const double every = sc.output.every > 0.0 ? sc.output.every : end;
    // Output k is due at k * every; it is written after the first step that
    // reaches that time (the file and the CSV rows carry the actual time),
    // and the end of every stage is written too. Steps are never shortened
    // for an output, so the trajectory does not depend on the cadence; only
    // the last step of a stage is cut to end on its duration.
    long next_k = opt.restart ? opt.restart->output.next_due : 1;
    auto due = [&] { return static_cast<double>(next_k) * every; };
    // Checkpoints: by steps, simulated time or wall-clock time, whichever
    // comes first; none of them changes the trajectory.
    const CheckpointSpec &ck = sc.checkpoint;
    long next_ck = ck.every ? next_multiple(sim.time(), *ck.every, 1) : 0;
    double last_ck_wall = 0.0;
    auto checkpoint_due = [&] {
        bool now = ck.steps && sim.steps() % *ck.steps == 0;
        if (ck.every && sim.time() >= static_cast<double>(next_ck) * *ck.every) {
            now = true;
            next_ck = next_multiple(sim.time(), *ck.every, next_ck);
        }
        if (ck.wall) {
            // Each rank's clock differs: rank 0's decides.
            double wall = root && elapsed() - last_ck_wall >= *ck.wall ? 1.0 : 0.0;
            if (comm.distributed()) wall = comm.max(wall);
            if (wall > 0.0) now = true;
        }
        return now;
    };
    GovernedSteps steps(opt.adapt_threads, comm);
    ClampWatch clamps(sc);
    for (;;) {
        const StageSpec &stage = sim.stages()[sim.stage()];
        StageEnd why = StageEnd::running;
        while ((why = sim.stage_end_reached()) == StageEnd::running) {
            try {
                steps.step(sim, sim.stage_end() - sim.time());
            } catch (const Error &e) {
                failed(e, out, sim, dir);
            }
            particle_steps += static_cast<long>(sim.particle_count());
            for (; warnings_shown < sim.warnings().size(); ++warnings_shown)
                log << "talus: warning: " << sim.warnings()[warnings_shown] << '\n';
            // Times within a millionth of a step of a target count as
            // reaching it.
            if (sim.time() >= due() - 1e-9 * sim.last_dt()) {
                write_or_stop(out, sim, said);
                clamps.look(sim, log);
                // One file per output time reached, even if a long step
                // passed several of them.
                next_k = next_multiple(sim.time() + 1e-9 * sim.last_dt(), every, next_k);
            }
            stop_if_signalled(comm, checkpoints, sim, out, next_k, particle_steps);
            if (checkpoint_due()) {
                const fs::path file =
                    checkpoint_or_stop(checkpoints, sim, out, next_k, particle_steps);
                last_ck_wall = elapsed();
                if (said)
                    *said << fmt::format("talus: checkpoint {} at t = {:.6g} s (step {})\n",
                                         file.string(), sim.time(), sim.steps());
            }
            const double interval = opt.progress_tty ? 0.5 : opt.progress_interval;
            if (opt.progress && elapsed() - last_progress > interval) {
                last_progress = elapsed();
                const double rate = static_cast<double>(particle_steps - particle_steps_before) /
                                    std::max(last_progress, 1e-9);
                // The end as it now stands: a stage that came to rest
                // early (until) moved every later stage, and the end, back.
                double projected = sim.stage_end();
                for (std::size_t k = sim.stage() + 1; k < sim.stages().size(); ++k)
                    projected += sim.stages()[k].duration;
                const double eta = last_progress * (projected - sim.time()) /
                                   std::max(sim.time() - time_before, 1e-300);
                print_progress(opt, sim, projected, last_progress, rate, eta);
            }
        }
        // The end of every stage is in the output.
        if (!out.written_now()) write_or_stop(out, sim, said);
        const bool met = why == StageEnd::quiescent;
        out.stage_row(why, met);
        if (!sc.stages.empty()) log_stage_end(opt, stage, sim, met, notes);
        if (stage.until && !met) not_at_rest(stage, sim, out, comm, log);
        if (sim.stage() + 1 == sim.stages().size()) break;
        try {
            sim.begin_next_stage();
        } catch (const Error &e) {
            failed(e, out, sim, dir,
                   fmt::format("particles as at the end of step {}, with the changes of stage "
                               "'{}' to its groups and materials possibly part made",
                               sim.steps(), sim.stages()[sim.stage()].name));
        }
        notes << fmt::format("talus: stage '{}' begins at t = {:.6g} s\n",
                             sim.stages()[sim.stage()].name, sim.time());
    }
    if (opt.progress && opt.progress_tty) std::fprintf(stderr, "\n");
    if (opt.progress) steps.report(log);
    if (const Diagnostics dg = sim.diagnostics(); dg.removed > 0) // collective
        notes << fmt::format("talus: note: {} particle(s) left the grid and were removed; {} "
                             "remain\n",
                             dg.removed, dg.particles);
    if (!opt.final_field.empty())
        write_final_particles(dir / "final_particles.csv", sim, opt.final_field, final_offsets);
    RunSummary rs = summary(sim, comm, elapsed(), particle_steps - particle_steps_before,
                            out.outputs(), checkpoints.written(), dir);
    rs.restarted = opt.restart != nullptr;
    rs.first_step = steps_before;
    rs.outputs_before = outputs_before;
    return rs;
}

} // namespace talus
