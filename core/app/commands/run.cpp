// talus run: a scenario, or the continuation of a checkpoint's run, on one
// rank or on the ranks of a launcher (docs/mpi.md).
#include "commands.hpp"

#include "../particle_plot.hpp"

#include <talus/driver/run.hpp>
#include <talus/error.hpp>
#include <talus/input/scenario_yaml.hpp>
#include <talus/input/yaml_input.hpp>
#include <talus/io/checkpoint.hpp>
#include <talus/material/crash_report.hpp>

#include <fmt/format.h>

#include <filesystem>
#include <iostream>
#include <unistd.h>

namespace talus::cli {

namespace {

class Run final : public Command {
  public:
    explicit Run(CLI::App &parent)
        : Command(parent.add_subcommand("run", "Run an MPM scenario (YAML)")) {
        auto *scenario_option = app_->add_option("scenario", scenario_file_, "Scenario file (YAML)")
                                    ->type_name("SCENARIO.yaml");
        auto *restart_option =
            app_->add_option(
                    "--restart", restart_file_,
                    "Continue the run of this checkpoint (OUT/checkpoints/checkpoint_N.h5) "
                    "in its output folder OUT, with the scenario it stores")
                ->type_name("CHECKPOINT.h5")
                ->excludes(scenario_option);
        app_->add_flag("--force-restart", force_restart_,
                       "With --restart: continue even if Talus or a plugin differs from the "
                       "checkpoint's")
            ->needs(restart_option);
        app_->add_option(
                "--output-dir", output_dir_,
                "Where to write results (default: a folder named after the scenario, here)")
            ->type_name("DIR");
        app_->add_flag("--force", force_,
                       "Overwrite the files of a previous run in the output folder");
        app_->add_flag("--allow-large", allow_large_,
                       "Run even when the estimated step count (1e8) or VTK file count (1e5) is "
                       "exceeded");
        app_->add_option(
                "--progress-every", progress_every_,
                "Seconds between progress lines when stderr is not a terminal (default 10)")
            ->check(kPositive);
        app_->add_option("--threads", threads_,
                         "Number of threads, fixed (default: up to OpenMP's, all cores, each step "
                         "on as many as run fastest beside the machine's other load)")
            ->check(kThreadCount);
        auto *plot_option =
            app_->add_option(
                    "--plot", plot_,
                    "After the last step, draw the particles where they ended, coloured by "
                    "--plot-field, with matplotlib (also writes final_particles.csv in the "
                    "output folder)")
                ->type_name("FILE.png");
        app_->add_option("--plot-field", plot_field_,
                         "Field for --plot: a scalar state variable of the materials (e.g. "
                         "plastic_deviatoric_strain) or displacement, speed, p, q, J (default "
                         "displacement)")
            ->type_name("NAME")
            ->needs(plot_option);
    }
    bool calls_plugins() const override { return true; }
    int run(Context &ctx) override;

  private:
    // The scenario (the checkpoint's with --restart) and its text.
    Scenario read(Context &ctx, std::optional<Checkpoint> &checkpoint, std::string &text);
    // A picture that cannot be written is found out before the run.
    void check_plot_folder(const Scenario &sc) const;

    std::string scenario_file_, output_dir_, restart_file_;
    bool force_ = false, force_restart_ = false, allow_large_ = false;
    double progress_every_ = 10.0;
    int threads_ = 0;
    std::string plot_, plot_field_ = "displacement";
};

Scenario Run::read(Context &ctx, std::optional<Checkpoint> &checkpoint, std::string &text) {
    if (scenario_file_.empty() && restart_file_.empty())
        throw Error("`talus run` needs a scenario (SCENARIO.yaml) or --restart CHECKPOINT.h5");
    // A restart reads the scenario the checkpoint stores, as its run read it
    // (the file may have changed since), under the file's name, so that
    // relative paths resolve as they did.
    std::optional<Scenario> read;
    together(ctx.comm, [&] {
        if (!restart_file_.empty()) {
            checkpoint = read_checkpoint_for(restart_file_, ctx.comm.rank(), ctx.comm.size());
            scenario_file_ = checkpoint->scenario_path;
            text = checkpoint->scenario_text;
            if (output_dir_.empty())
                output_dir_ =
                    std::filesystem::absolute(restart_file_).parent_path().parent_path().string();
        } else {
            refuse_wrong_file(scenario_file_, YamlKind::scenario, "run");
            text = yaml::read_text_file(scenario_file_);
        }
        // One text is parsed and stored in the checkpoints.
        const yaml::Node root = yaml::load_string(text, scenario_file_);
        read.emplace(read_scenario(root, ctx.registry));
    });
    return std::move(*read);
}

void Run::check_plot_folder(const Scenario &sc) const {
    // Its folder must exist, or be the run's output folder, which the run
    // makes (as the default job, ./dev run, draws into it on a fresh build).
    namespace fs = std::filesystem;
    const fs::path folder = fs::weakly_canonical(fs::absolute(plot_).parent_path());
    const fs::path run_dir = fs::weakly_canonical(
        fs::absolute(output_dir_.empty() ? default_output_dir(sc.file) : fs::path(output_dir_)));
    if (!fs::is_directory(folder) && folder != run_dir)
        throw Error(fmt::format("--plot {}: the folder {} does not exist (nor is it the run's "
                                "output folder, {}, which the run makes)",
                                plot_, folder.string(), run_dir.string()));
}

int Run::run(Context &ctx) {
    // Started by mpirun (or srun) on several ranks: the run is spread over
    // them (docs/mpi.md). Every rank reads the input; rank 0 writes what the
    // ranks share and the log.
    if (MpiSession::launched_ranks() > 1) ctx.mpi.emplace(&ctx.argc, &ctx.argv);
    ctx.comm = Comm::world();
    if (ctx.comm.distributed()) crash::set_rank(ctx.comm.rank(), ctx.comm.size());
    std::optional<Checkpoint> checkpoint;
    std::string text;
    Scenario sc = read(ctx, checkpoint, text);
    const bool rank0 = ctx.comm.rank() == 0;
    RunOptions ro;
    ro.solver.comm = ctx.comm;
    ro.scenario_text = text;
    ro.restart = checkpoint ? &*checkpoint : nullptr;
    ro.force_restart = force_restart_;
    ro.output_dir = output_dir_;
    ro.force = force_;
    ro.allow_large = allow_large_;
    ro.verbosity = ctx.verbosity;
    ro.progress = rank0 && ctx.verbosity != Verbosity::quiet;
    ro.progress_tty = ro.progress && isatty(2) != 0;
    ro.progress_interval = progress_every_;
    ro.solver.threads = threads_;
    ro.adapt_threads = threads_ == 0;
    if (!plot_.empty()) {
        check_plot_folder(sc);
        ro.final_field = plot_field_;
    }
    std::ostream silent(nullptr); // the other ranks' log: rank 0 tells it
    const RunSummary rs = run_scenario(sc, ro, rank0 ? std::cerr : silent);
    if (!rank0) return 0;
    const bool say = ctx.verbosity != Verbosity::quiet;
    const std::string checkpoints =
        rs.checkpoints > 0 ? fmt::format(" and {} checkpoint(s)", rs.checkpoints) : "";
    // A restart's own part apart from the run's totals, each count with
    // the span it is of.
    if (say && rs.restarted)
        std::cerr << fmt::format(
            "talus: continued from step {} to step {} (t = {:.6g} s), {} particles, {:.1f} s wall, "
            "{:.3g} particle-steps/s; {} output(s){} written by this part, {} output(s) of the "
            "run in {}\n",
            rs.first_step, rs.steps, rs.time, rs.particles, rs.seconds,
            rs.particle_steps_per_second, rs.outputs - rs.outputs_before, checkpoints, rs.outputs,
            rs.output_dir.string());
    else if (say)
        std::cerr << fmt::format("talus: {} steps to t = {:.6g} s, {} particles, {:.1f} s wall, "
                                 "{:.3g} particle-steps/s; {} output(s){} in {}\n",
                                 rs.steps, rs.time, rs.particles, rs.seconds,
                                 rs.particle_steps_per_second, rs.outputs, checkpoints,
                                 rs.output_dir.string());
    if (!plot_.empty()) {
        plot_final_particles(rs.output_dir / "final_particles.csv", plot_,
                             fmt::format("{}: {} at t = {:.4g} s",
                                         std::filesystem::path(scenario_file_).filename().string(),
                                         plot_field_, rs.time));
        if (say) std::cerr << fmt::format("talus: drew {}\n", plot_);
    }
    return 0;
}

} // namespace

std::unique_ptr<Command> run_command(CLI::App &parent) { return std::make_unique<Run>(parent); }

} // namespace talus::cli
