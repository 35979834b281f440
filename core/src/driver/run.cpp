#include <talus/driver/run.hpp>

#include <talus/driver/point_driver.hpp>
#include <talus/input/yaml_input.hpp>
#include <talus/io/checkpoint.hpp>
#include <talus/io/output_file.hpp>
#include <talus/io/provenance.hpp>
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

// The particle nearest each probe point at t = 0 (-1 for other probes). A
// point farther than a cell from every particle is a mistake in the point.
std::vector<std::int64_t> probe_particles(const Scenario &sc, const Simulation &sim) {
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
                    if (d2 < best) {
                        best = d2;
                        id = s.id[k];
                    }
                }
            if (std::sqrt(best) > sc.cell)
                throw Error(p.origin.error(fmt::format(
                    "probe '{}': no particle within a cell ({:g} m) of its point; the nearest "
                    "is {:.4g} m away (a probe follows the particle nearest its point at t = 0)",
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
    plan.estimate = check_memory(sc, plan.memory_total, plan.memory_available);
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
    out.sim = std::make_unique<Simulation>(sc, solver);
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
    plan.steps = std::ceil(sc.end_time / plan.first_dt);
    if (sc.output.vtk) {
        // One file per output time, at most one per step, plus the start.
        const double due = sc.output.every > 0.0 ? std::ceil(sc.end_time / sc.output.every) : 1.0;
        plan.output_files = std::min(due, plan.steps) + 1.0;
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
        throw Error(sc.output.every_origin.error(fmt::format(
            "output.every = {:g} s is too fine to count up to t = {:g} s (more than 2^53 "
            "output times); outputs come at most once per step, so a cadence below the time "
            "step ({:.3g} s) gives the same files as the step itself",
            sc.output.every, sc.end_time, plan.first_dt)));
    if (sc.checkpoint.every && !(sc.end_time / *sc.checkpoint.every < kMaxCadenceCount))
        throw Error(sc.checkpoint.every_origin.error(fmt::format(
            "checkpoint.every = {:g} s is too fine to count up to t = {:g} s (more than 2^53 "
            "checkpoint times); checkpoint.steps: 1 writes one after every step",
            *sc.checkpoint.every, sc.end_time)));
    if (plan.output_files > kMaxOutputFiles)
        plan.over_limits.push_back(sc.output.every_origin.warning(fmt::format(
            "the cadence asks for about {:.3g} VTK files, more than {:.0e}; raise output.every",
            plan.output_files, kMaxOutputFiles)));
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

bool is_own_file(const fs::path &p) {
    const std::string name = p.filename().string();
    for (const char *f : {"diagnostics.csv", "probes.csv", "particles.pvd", "failed_call.yaml",
                          "final_particles.csv", "provenance.json", "stages.csv"})
        if (name == f) return true;
    return (name.rfind("particles_", 0) == 0 || name.rfind("failure_", 0) == 0) &&
           p.extension() == ".vtu";
}

std::string fmt_time(double s) {
    if (!std::isfinite(s)) return "?";
    const long t = static_cast<long>(s + 0.5);
    return fmt::format("{}:{:02d}:{:02d}", t / 3600, (t / 60) % 60, t % 60);
}

// Everything a run writes, every write checked (output_file.hpp). The VTK
// file of an output time is complete before its CSV rows are written, so
// no row stands for a file that is not there.
class RunOutput {
  public:
    // With `resume`, continues the output of an interrupted run as it
    // stood at its checkpoint.
    RunOutput(const fs::path &dir, const Scenario &sc, const Simulation &sim,
              std::vector<std::int64_t> probe_ids, const OutputProgress *resume = nullptr)
        : dir_(dir), sc_(sc), sim_(sim), probe_ids_(std::move(probe_ids)) {
        // State variables to write: those named in output.state, else every
        // one its plugin flags for output.
        fields_ = sc.output.state_fields;
        if (sc.output.all_flagged_state)
            for (const auto &m : sc.materials)
                for (const auto &v : m.spec.state.vars)
                    if (v.output() &&
                        std::find(fields_.begin(), fields_.end(), v.name) == fields_.end())
                        fields_.push_back(v.name);
        if (resume) {
            resume_from(*resume);
            return;
        }
        // First: what made this run, before any result exists.
        Provenance prov{"run", sc.file, {}};
        for (const auto &m : sc.materials)
            prov.materials.push_back({m.name, &m.spec});
        write_file_atomically(dir / "provenance.json", provenance_json(prov));
        diag_ = OutputFile(dir / "diagnostics.csv");
        diag_ << "step,time,dt,mass,momentum_x,momentum_y,momentum_z,kinetic_energy,stress_work,"
                 "angular_momentum_x,angular_momentum_y,angular_momentum_z,particles,removed,"
                 "cut_steps,held_at_faces,stage\n";
        diag_.flush();
        if (!sc.stages.empty()) {
            stages_ = OutputFile(dir / "stages.csv");
            stages_ << "stage,name,first_step,start_time,last_step,end_time,end,"
                       "kinetic_energy_ratio,last_output\n";
            stages_.flush();
        }
        if (!sc.output.probes.empty()) {
            prob_ = OutputFile(dir / "probes.csv");
            std::string h = "time";
            const char *axes = "xyz";
            for (const Probe &p : sc.output.probes) {
                const std::string &nm = p.name;
                const bool particle = p.kind == Probe::Kind::particle;
                for (int d = 0; d < sc.dim; ++d)
                    h += fmt::format(",{}.{}", nm, axes[d]);
                if (particle)
                    for (int d = 0; d < sc.dim; ++d)
                        h += fmt::format(",{}.u{}", nm, axes[d]);
                for (int d = 0; d < sc.dim; ++d)
                    h += fmt::format(",{}.v{}", nm, axes[d]);
                if (particle)
                    for (const char *c : {"xx", "yy", "zz", "xy", "yz", "xz"})
                        h += fmt::format(",{}.sig_{}", nm, c);
            }
            prob_ << h << "\n";
            prob_.flush();
        }
    }

    int outputs() const { return outputs_; }

    // Where the output stands, every row handed to the OS (for a
    // checkpoint).
    OutputProgress progress() {
        OutputProgress o;
        diag_.flush();
        o.diagnostics_bytes = diag_.bytes();
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
        if (!stages_.is_open()) return;
        const StageSpec &st = sim_.stages()[sim_.stage()];
        const char *end = why == StageEnd::quiescent ? "quiescent"
                          : st.until && !met         ? "duration_not_quiescent"
                                                     : "duration";
        stages_ << fmt::format("{},{},{},{:.17g},{},{:.17g},{},{:.17g},{}\n", sim_.stage(), st.name,
                               stage_first_step_, sim_.stage_start(), sim_.steps(), sim_.time(),
                               end, sim_.last_kinetic_energy_ratio(), outputs_ - 1);
        stages_.flush();
        stage_first_step_ = sim_.steps() + 1;
    }

    // An output time: the VTK file and the collection, then the rows.
    void write() {
        if (sc_.output.vtk) {
            const std::string name = fmt::format("particles_{:05d}.vtu", outputs_);
            write_vtu(dir_ / name, sim_, fields_);
            pvd_.emplace_back(sim_.time(), name);
            // Rewritten after every frame so that a run stopped early still
            // leaves a valid collection.
            write_pvd(dir_ / "particles.pvd", pvd_);
        }
        rows();
        ++outputs_;
        last_written_step_ = sim_.steps();
    }

    // The state when a step failed: failure_step<N>.vtu and a last row of
    // each CSV. Returns where it went (or why it could not be written) for
    // the error message.
    std::string write_failure() noexcept {
        try {
            const fs::path file = dir_ / fmt::format("failure_step{}.vtu", sim_.steps() + 1);
            write_vtu(file, sim_, fields_);
            rows();
            return fmt::format(
                "\nthe state when the run stopped is in {} and the last row of diagnostics.csv "
                "(particles may be part way through step {})",
                file.string(), sim_.steps() + 1);
        } catch (const std::exception &e) {
            return fmt::format("\nthe state when the run stopped could not be written: {}",
                               e.what());
        }
    }

  private:
    // The files as they stood at the checkpoint: the CSV files cut back to
    // its length, the VTK files written after it removed, the collection
    // rewritten.
    void resume_from(const OutputProgress &o) {
        diag_ = OutputFile::resume(dir_ / "diagnostics.csv", o.diagnostics_bytes);
        if (!sc_.output.probes.empty())
            prob_ = OutputFile::resume(dir_ / "probes.csv", o.probes_bytes);
        if (!sc_.stages.empty()) stages_ = OutputFile::resume(dir_ / "stages.csv", o.stages_bytes);
        outputs_ = static_cast<int>(o.next_output);
        last_written_step_ = o.last_written_step;
        stage_first_step_ = o.stage_first_step;
        for (std::size_t k = 0; k < o.frames.size(); ++k)
            pvd_.emplace_back(o.frames[k], fmt::format("particles_{:05d}.vtu", k));
        std::error_code ec;
        for (const auto &e : fs::directory_iterator(dir_, ec)) {
            const std::string name = e.path().filename().string();
            int k = -1;
            const bool later = std::sscanf(name.c_str(), "particles_%d.vtu", &k) == 1 &&
                               k >= outputs_ && e.path().extension() == ".vtu";
            const bool stale = name.rfind("failure_", 0) == 0 || name == "final_particles.csv" ||
                               name == "failed_call.yaml";
            if ((later || stale) && !fs::remove(e.path(), ec) && ec)
                throw Error(fmt::format("{}: cannot remove a file written after the checkpoint: {}",
                                        e.path().string(), ec.message()));
        }
        if (sc_.output.vtk) write_pvd(dir_ / "particles.pvd", pvd_);
    }

    void rows() {
        const Diagnostics dg = sim_.diagnostics();
        diag_ << fmt::format("{},{:.17g},{:.17g},{:.17g},{:.17g},{:.17g},{:.17g},{:.17g},{:.17g},"
                             "{:.17g},{:.17g},{:.17g},{},{},{},{},{}\n",
                             dg.step, dg.time, dg.dt, dg.mass, dg.momentum[0], dg.momentum[1],
                             dg.momentum[2], dg.kinetic_energy, dg.stress_work,
                             dg.angular_momentum[0], dg.angular_momentum[1], dg.angular_momentum[2],
                             dg.particles, dg.removed, dg.cut_steps, dg.held_at_faces,
                             sim_.stage());
        diag_.flush();
        if (!prob_.is_open()) return;
        std::string row = fmt::format("{:.17g}", sim_.time());
        const int D = sc_.dim;
        for (std::size_t i = 0; i < sc_.output.probes.size(); ++i) {
            const Probe &probe = sc_.output.probes[i];
            if (probe.kind == Probe::Kind::particle) {
                bool found = false;
                for (const auto &s : sim_.sets())
                    for (std::size_t k = 0; k < s.n && !found; ++k)
                        if (s.id[k] == probe_ids_[i]) {
                            found = true;
                            for (int d = 0; d < D; ++d)
                                row += fmt::format(",{:.17g}", s.x[static_cast<std::size_t>(d)][k]);
                            for (int d = 0; d < D; ++d)
                                row += fmt::format(",{:.17g}",
                                                   s.x[static_cast<std::size_t>(d)][k] -
                                                       s.x0[static_cast<std::size_t>(d)][k]);
                            for (int d = 0; d < D; ++d)
                                row += fmt::format(",{:.17g}", s.v[static_cast<std::size_t>(d)][k]);
                            for (std::size_t c = 0; c < 6; ++c)
                                row += fmt::format(",{:.17g}", s.stress[6 * k + c]);
                        }
                if (!found) // removed (it left the grid, or its group was removed)
                    for (int c = 0; c < 3 * D + 6; ++c)
                        row += ",nan";
            } else {
                double m = 0.0, x[3] = {0, 0, 0}, v[3] = {0, 0, 0};
                for (const auto &s : sim_.sets())
                    for (std::size_t k = 0; k < s.n; ++k)
                        if (static_cast<std::size_t>(s.group[k]) == probe.group) {
                            m += s.mass[k];
                            for (int d = 0; d < D; ++d) {
                                x[d] += s.mass[k] * s.x[static_cast<std::size_t>(d)][k];
                                v[d] += s.mass[k] * s.v[static_cast<std::size_t>(d)][k];
                            }
                        }
                for (int d = 0; d < D; ++d)
                    row += fmt::format(",{:.17g}", m > 0 ? x[d] / m : NAN);
                for (int d = 0; d < D; ++d)
                    row += fmt::format(",{:.17g}", m > 0 ? v[d] / m : NAN);
            }
        }
        prob_ << row << "\n";
        prob_.flush();
    }

    fs::path dir_;
    const Scenario &sc_;
    const Simulation &sim_;
    std::vector<std::int64_t> probe_ids_;
    std::vector<std::string> fields_;
    OutputFile diag_, prob_, stages_;
    std::vector<std::pair<double, std::string>> pvd_;
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
    const std::string where = out->write_failure();
    ::write(STDERR_FILENO, where.data() + 1, where.size() - 1);
    ::write(STDERR_FILENO, " (best effort after a crash)\n", 29);
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
    std::string text = D == 3 ? "id,group,x,y,z," : "id,group,x,y,";
    text += field;
    text += '\n';
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
    write_file_atomically(file, text);
}

} // namespace

namespace {

// SIGTERM and SIGINT (a scheduler's kill, Ctrl-C) only raise a flag: the
// run finishes its step, writes a checkpoint and stops. A second signal
// ends the process at once (SA_RESETHAND).
volatile std::sig_atomic_t g_stop_signal = 0;
extern "C" void on_stop_signal(int sig) { g_stop_signal = sig; }

class StopSignals {
  public:
    StopSignals() {
        g_stop_signal = 0;
        struct sigaction sa {};
        sa.sa_handler = on_stop_signal;
        sa.sa_flags = SA_RESETHAND;
        sigemptyset(&sa.sa_mask);
        ::sigaction(SIGTERM, &sa, &old_term_);
        ::sigaction(SIGINT, &sa, &old_int_);
    }
    ~StopSignals() {
        ::sigaction(SIGTERM, &old_term_, nullptr);
        ::sigaction(SIGINT, &old_int_, nullptr);
    }
    StopSignals(const StopSignals &) = delete;
    StopSignals &operator=(const StopSignals &) = delete;

  private:
    struct sigaction old_term_ {
    }, old_int_{};
};

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
    Checkpoints(const fs::path &dir, const Scenario &sc, std::string text)
        : dir_(dir / "checkpoints"), sc_(sc), text_(std::move(text)),
          sha_(fs::exists(sc.file) ? sha256_file(sc.file) : std::string()),
          plugins_(plugin_identities(sc)) {}

    bool possible() const { return !text_.empty(); }

    fs::path write(const Simulation &sim, RunOutput &out, long next_due, long particle_steps) {
        if (!possible())
            throw Error(fmt::format("{}: the scenario's text could not be read, so no checkpoint "
                                    "can be written",
                                    sc_.file));
        std::error_code ec;
        fs::create_directories(dir_, ec);
        if (ec)
            throw Error(fmt::format("{}: cannot create the checkpoint folder: {}", dir_.string(),
                                    ec.message()));
        Checkpoint c;
        c.scenario_path = fs::absolute(sc_.file).string();
        c.scenario_text = text_;
        c.scenario_sha256 = sha_;
        c.plugins = plugins_;
        c.output = out.progress();
        c.output.next_due = next_due;
        c.output.particle_steps = particle_steps;
        c.state = sim.snapshot();
        const fs::path file = dir_ / fmt::format("checkpoint_{:010d}.h5", sim.steps());
        write_checkpoint(file, c);
        ++written_;
        prune();
        return file;
    }
    int written() const { return written_; }

  private:
    // The newest `keep` stay (by step, in the name).
    void prune() {
        std::vector<fs::path> all;
        std::error_code ec;
        for (const auto &e : fs::directory_iterator(dir_, ec))
            if (e.path().filename().string().rfind("checkpoint_", 0) == 0 &&
                e.path().extension() == ".h5")
                all.push_back(e.path());
        std::sort(all.begin(), all.end());
        const std::size_t keep = static_cast<std::size_t>(sc_.checkpoint.keep);
        for (std::size_t k = 0; k + keep < all.size(); ++k)
            if (!fs::remove(all[k], ec) && ec)
                throw Error(fmt::format("{}: cannot remove an old checkpoint: {}", all[k].string(),
                                        ec.message()));
    }
    fs::path dir_;
    const Scenario &sc_;
    std::string text_, sha_;
    std::vector<PluginIdentity> plugins_;
    int written_ = 0;
};

void write_or_stop(RunOutput &out, const Simulation &sim) {
    try {
        out.write();
    } catch (const Error &e) {
        throw Error(fmt::format("{}\nthe run stopped at step {} (t = {:.6g} s)", e.what(),
                                sim.steps(), sim.time()));
    }
}

} // namespace

RunSummary run_scenario(Scenario &sc, const RunOptions &opt, std::ostream &log) {
    const fs::path dir = opt.output_dir.empty() ? default_output_dir(sc.file) : opt.output_dir;
    // A misspelt field is refused before any work, not after the run.
    std::vector<long> final_offsets;
    if (!opt.final_field.empty() && !is_builtin_field(opt.final_field))
        final_offsets = final_field_offsets(sc, opt.final_field);
    else
        final_offsets.assign(sc.materials.size(), -1);
    // Refuse before any work: a previous run's files are never overwritten
    // silently.
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
                    "the run was not continued: a result made by two builds is not one result; "
                    "pass --force-restart to continue anyway",
                    all));
            log << fmt::format("talus: warning: continuing with other binaries than the "
                               "checkpoint's (--force-restart):{}\n",
                               all);
        }
        if (!fs::is_directory(dir))
            throw Error(fmt::format("{}: no such folder: the checkpoint's run output is not there",
                                    dir.string()));
    } else if (fs::exists(dir, ec)) {
        if (!fs::is_directory(dir, ec))
            throw Error(fmt::format("{}: exists and is not a directory", dir.string()));
        std::vector<fs::path> previous;
        for (const auto &e : fs::directory_iterator(dir, ec))
            if (is_own_file(e.path())) previous.push_back(e.path());
        if (ec)
            throw Error(fmt::format("{}: cannot list the folder: {}", dir.string(), ec.message()));
        if (!previous.empty()) {
            if (!opt.force)
                throw Error(fmt::format(
                    "{}: holds the output of a previous run ({} and {} more file(s)); "
                    "pass --force to overwrite it, or choose another --output-dir",
                    dir.string(), previous.front().filename().string(), previous.size() - 1));
        }
    }
    Prepared prep;
    if (opt.restart) {
        prep.sim = std::make_unique<Simulation>(sc, opt.solver, opt.restart->state);
        prep.probe_particles = opt.restart->output.probe_particles;
    } else {
        prep = prepare_run(sc, opt.solver);
    }
    Simulation &sim = *prep.sim;
    for (const std::string &n : prep.plan.notes)
        log << n << '\n';
    if (!prep.plan.over_limits.empty()) {
        std::string all;
        for (const std::string &w : prep.plan.over_limits)
            all += (all.empty() ? "" : "\n") + w;
        if (!opt.allow_large)
            throw Error(all + "\nthe run was not started; pass --allow-large to run it anyway");
        log << all << '\n';
    }

    // Now the old files go: a run refused above leaves them as they were.
    if (!opt.restart && fs::exists(dir / "checkpoints", ec))
        for (const auto &e : fs::directory_iterator(dir / "checkpoints", ec))
            if (e.path().extension() == ".h5" && !fs::remove(e.path(), ec) && ec)
                throw Error(fmt::format("{}: cannot remove the previous run's checkpoint: {}",
                                        e.path().string(), ec.message()));
    if (!opt.restart && fs::exists(dir, ec))
        for (const auto &e : fs::directory_iterator(dir, ec))
            if (is_own_file(e.path()) && !fs::remove(e.path(), ec) && ec)
                throw Error(fmt::format("{}: cannot remove the previous run's file: {}",
                                        e.path().string(), ec.message()));
    fs::create_directories(dir, ec);
    if (ec)
        throw Error(
            fmt::format("{}: cannot create the output folder: {}", dir.string(), ec.message()));

    RunOutput out(dir, sc, sim, prep.probe_particles, opt.restart ? &opt.restart->output : nullptr);
    Checkpoints checkpoints(dir, sc,
                            opt.restart                 ? opt.restart->scenario_text
                            : opt.scenario_text.empty() ? scenario_text_of(sc)
                                                        : opt.scenario_text);
    if (!checkpoints.possible() &&
        (sc.checkpoint.every || sc.checkpoint.steps || sc.checkpoint.wall))
        throw Error(fmt::format("{}: cannot read the scenario's text, which every checkpoint "
                                "stores",
                                sc.file));
    const StopSignals stop_signals;
    crash::set_last_action(write_state_after_crash, &out);
    const ClearLastAction clear_on_exit;

    const auto start = std::chrono::steady_clock::now();
    auto elapsed = [&] {
        return std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    };
    double last_progress = -1.0;
    long particle_steps = opt.restart ? opt.restart->output.particle_steps : 0;
    std::size_t warnings_shown = 0;
    if (!opt.restart) out.write();
    const double end = sc.end_time;
    if (opt.progress && opt.restart)
        log << fmt::format("talus: continuing from step {} (t = {:.6g} s, stage '{}'), {} "
                           "particles\n",
                           sim.steps(), sim.time(), sim.stages()[sim.stage()].name,
                           sim.particle_count());
    else if (opt.progress)
        log << fmt::format("talus: {} particles; about {:.3g} steps of {:.3g} s to t = {:g} s "
                           "(estimated from the initial state)\n",
                           sim.particle_count(), prep.plan.steps, prep.plan.first_dt, end);
    // The rate is of this process's steps.
    const long particle_steps_before = particle_steps;
    const double time_before = sim.time();
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
        if (ck.wall && elapsed() - last_ck_wall >= *ck.wall) now = true;
        return now;
    };
    auto stop_if_signalled = [&] {
        if (!g_stop_signal) return;
        const int sig = g_stop_signal;
        const char *name = sig == SIGTERM ? "SIGTERM" : sig == SIGINT ? "SIGINT" : "a signal";
        if (!checkpoints.possible())
            throw Interrupted(fmt::format("talus: stopped by {} at step {} (t = {:.6g} s); no "
                                          "checkpoint could be written: {}",
                                          name, sim.steps(), sim.time(),
                                          "the scenario's text could not be read"),
                              sig);
        const fs::path file = checkpoints.write(sim, out, next_k, particle_steps);
        throw Interrupted(fmt::format("talus: stopped by {} at step {} (t = {:.6g} s); the run "
                                      "continues with: talus run --restart {}",
                                      name, sim.steps(), sim.time(), file.string()),
                          sig);
    };
    for (;;) {
        const StageSpec &stage = sim.stages()[sim.stage()];
        StageEnd why = StageEnd::running;
        while ((why = sim.stage_end_reached()) == StageEnd::running) {
            try {
                sim.step(sim.stage_end() - sim.time());
            } catch (const Error &e) {
                throw Error(e.what() + out.write_failure() + write_replay_case(sim, dir));
            }
            particle_steps += static_cast<long>(sim.particle_count());
            for (; warnings_shown < sim.warnings().size(); ++warnings_shown)
                log << "talus: warning: " << sim.warnings()[warnings_shown] << '\n';
            // Times within a millionth of a step of a target count as
            // reaching it.
            if (sim.time() >= due() - 1e-9 * sim.last_dt()) {
                write_or_stop(out, sim);
                // One file per output time reached, even if a long step
                // passed several of them.
                next_k = next_multiple(sim.time() + 1e-9 * sim.last_dt(), every, next_k);
            }
            stop_if_signalled();
            if (checkpoint_due()) {
                checkpoints.write(sim, out, next_k, particle_steps);
                last_ck_wall = elapsed();
            }
            const double interval = opt.progress_tty ? 0.5 : opt.progress_interval;
            if (opt.progress && elapsed() - last_progress > interval) {
                last_progress = elapsed();
                const double rate = static_cast<double>(particle_steps - particle_steps_before) /
                                    std::max(last_progress, 1e-9);
                const double eta =
                    last_progress * (end - sim.time()) / std::max(sim.time() - time_before, 1e-300);
                std::fprintf(stderr,
                             "%sstep %ld  t = %.4g / %.4g s  dt = %.3g s  elapsed %s  ETA %s  "
                             "%.3g particle-steps/s%s",
                             opt.progress_tty ? "\r" : "talus: progress: ", sim.steps(), sim.time(),
                             end, sim.last_dt(), fmt_time(last_progress).c_str(),
                             fmt_time(eta).c_str(), rate, opt.progress_tty ? "   " : "\n");
                std::fflush(stderr);
            }
        }
        // The end of every stage is in the output.
        if (!out.written_now()) write_or_stop(out, sim);
        const bool met = why == StageEnd::quiescent;
        out.stage_row(why, met);
        if (!sc.stages.empty()) {
            if (opt.progress && opt.progress_tty) std::fprintf(stderr, "\n");
            log << fmt::format("talus: stage '{}' ended at t = {:.6g} s (step {}): {}\n",
                               stage.name, sim.time(), sim.steps(),
                               met ? fmt::format("at rest (kinetic energy ratio {:.3g})",
                                                 sim.last_kinetic_energy_ratio())
                                   : "its duration");
        }
        if (stage.until && !met) {
            const std::string what = fmt::format(
                "stage '{}' did not come to rest within its duration of {:g} s: the kinetic "
                "energy ratio is {:.3g} at t = {:.6g} s, the limit {:.3g}{}; the state at the "
                "stage's end is in {}",
                stage.name, stage.duration, sim.last_kinetic_energy_ratio(), sim.time(),
                stage.until->kinetic_energy_ratio,
                sim.quiet_since()
                    ? fmt::format(" (below it since t = {:.6g} s, not yet for the hold time)",
                                  *sim.quiet_since())
                    : std::string(),
                out.last_written());
            if (stage.until->stop_if_not_met)
                throw Error(stage.until->origin.error(
                    what + "; lengthen the duration or damp more, or set until.otherwise: "
                           "continue to go on regardless"));
            log << stage.until->origin.warning(what + "; going on (until.otherwise: continue)")
                << '\n';
        }
        if (sim.stage() + 1 == sim.stages().size()) break;
        try {
            sim.begin_next_stage();
        } catch (const Error &e) {
            throw Error(e.what() + out.write_failure() + write_replay_case(sim, dir));
        }
        log << fmt::format("talus: stage '{}' begins at t = {:.6g} s\n",
                           sim.stages()[sim.stage()].name, sim.time());
    }
    if (opt.progress && opt.progress_tty) std::fprintf(stderr, "\n");
    if (!opt.final_field.empty())
        write_final_particles(dir / "final_particles.csv", sim, opt.final_field, final_offsets);
    RunSummary rs;
    rs.steps = sim.steps();
    rs.time = sim.time();
    rs.seconds = elapsed();
    rs.particles = sim.particle_count();
    rs.particle_steps_per_second =
        static_cast<double>(particle_steps - particle_steps_before) / std::max(rs.seconds, 1e-9);
    rs.outputs = out.outputs();
    rs.checkpoints = checkpoints.written();
    rs.output_dir = dir;
    return rs;
}

} // namespace talus
