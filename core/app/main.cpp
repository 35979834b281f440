// The `talus` command: point driver, plugin tools (and, with the solver, run
// and validate). Every user error ends in one message on stderr and exit
// status 1; command-line misuse exits with status 2 (CLI11's convention is
// kept: 105 and up are its own parse errors, mapped to 2 here).
#include <talus/driver/point_driver.hpp>
#include <talus/error.hpp>
#include <talus/input/scenario_yaml.hpp>
#include <talus/io/output_file.hpp>
#include <talus/io/provenance.hpp>
#include <talus/material/crash_report.hpp>
#include <talus/material/plugin_loader.hpp>
#include <talus/plugin_check/conformance.hpp>

#include "model_markdown.hpp"
#include "particle_plot.hpp"
#include "plugin_new.hpp"
#include "point_plot.hpp"
#include <talus/driver/run.hpp>
#include <talus/input/yaml_input.hpp>
#include <talus/mpm/comm.hpp>
#include <talus/mpm/scenario.hpp>

#include <CLI/CLI.hpp>
#include <fmt/format.h>

#include <csignal>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <optional>
#include <sstream>
#include <unistd.h>

namespace {

// A number above zero. (CLI11's PositiveNumber names its range "0.000000
// to" the largest double in all its 309 digits.)
const CLI::Validator kPositive(
    [](std::string &text) -> std::string {
        std::size_t used = 0;
        double v = 0.0;
        try {
            v = std::stod(text, &used);
        } catch (const std::out_of_range &) {
            return "out of range, got " + text;
        } catch (const std::exception &) {
            used = 0;
        }
        if (used == 0 || used != text.size()) return "expected a number, got '" + text + "'";
        return v > 0.0 ? std::string() : "must be greater than 0, got " + text;
    },
    "POSITIVE");

// A thread count: a whole number from 1 to kMaxThreads (CLI11's own message
// for 2.5 was "Could not convert: --threads = 2.5").
const CLI::Validator kThreadCount(
    [](std::string &text) -> std::string {
        std::size_t used = 0;
        long long n = 0;
        try {
            n = std::stoll(text, &used);
        } catch (const std::out_of_range &) {
            // Beyond a long long: far too many, or with a minus far too few.
            used = text.size();
            n = text.find('-') == std::string::npos ? talus::kMaxThreads + 1LL : 0;
        } catch (const std::exception &) {
            used = 0;
        }
        if (used == 0 || used != text.size())
            return "expected a whole number of threads, got '" + text + "'";
        if (n <= 0) return "must be greater than 0, got " + text;
        if (n > talus::kMaxThreads)
            return fmt::format("at most {} threads, got {} (this machine lets talus run on {} "
                               "processor(s))",
                               talus::kMaxThreads, text, talus::Simulation::processors());
        return std::string();
    },
    "COUNT");

using namespace talus;

std::string wrap(const std::string &text, std::size_t indent, std::size_t width = 78) {
    std::istringstream words(text);
    std::string word, line, out;
    const std::string pad(indent, ' ');
    while (words >> word) {
        if (!line.empty() && line.size() + 1 + word.size() > width - indent) {
            out += pad + line + '\n';
            line.clear();
        }
        line += (line.empty() ? "" : " ") + word;
    }
    if (!line.empty()) out += pad + line + '\n';
    return out;
}

void print_model(std::ostream &out, const Model &m) {
    out << fmt::format("model {} {}: {}\n", m.id(), m.version(), m.name());
    out << wrap(m.doc(), 2);
    out << fmt::format("  kinematics: {}; tangent: {}\n",
                       m.finite_strain() ? "finite strain (uses F, owns its objectivity)"
                                         : "strain increment (host rotates stress objectively)",
                       m.has_tangent() ? "consistent tangent provided" : "not provided");
    out << fmt::format("  qualified id: {}; set-up call: {}; threads: {}{}\n", m.qualified_id(),
                       m.has_init_state() ? "init_state" : "update with dt = 0",
                       m.reentrant() ? "reentrant"
                                     : "NOT reentrant (called from one thread at a time)",
                       m.wants_rotation() ? "; is given each increment's rotation" : "");
    out << "  parameters (YAML keys of the material, beside model and density):\n";
    if (m.params().empty()) out << "    none\n";
    for (const ParamInfo &p : m.params()) {
        out << fmt::format("    {:<20} [{}] {}, {}\n", p.key, p.unit, p.type_name(),
                           p.required() ? "required"
                                        : "default " + p.value_text(p.default_param()));
        if (p.type == TALUS_PARAM_STRING)
            out << fmt::format("      example: {}\n", p.value_text(p.typical_param()));
        else if (p.type == TALUS_PARAM_REAL_ARRAY)
            out << fmt::format("      {}, each {}; example: {}\n", p.count_text(), p.bounds_text(),
                               p.value_text(p.typical_param()));
        else
            out << fmt::format("      bounds: {}; example: {}\n", p.bounds_text(),
                               p.value_text(p.typical_param()));
        out << wrap(p.doc, 6);
    }
    out << "  state variables:\n";
    if (m.instance_state())
        out << "    set per material from its parameters (the instance's layout)\n";
    else if (m.state().empty())
        out << "    none\n";
    for (const StateInfo &s : m.state()) {
        std::string flags;
        if (s.output()) flags += ", written to output";
        if (s.user_initialisable()) flags += ", user-initialisable";
        out << fmt::format("    {:<20} [{}] {} component{}, initially {:g}{}\n", s.name, s.unit,
                           s.size, s.size == 1 ? "" : "s", s.initial_value, flags);
        out << wrap(s.doc, 6);
    }
}

void print_library(std::ostream &out, const PluginLibrary &lib) {
    out << fmt::format("library {} {} (material ABI {}.{})\n  {}\n  build: {}\n", lib.name(),
                       lib.version(), lib.abi_major(), lib.abi_minor(), lib.path().string(),
                       lib.build_text());
    for (const Model &m : lib.models()) {
        out << '\n';
        print_model(out, m);
    }
}

// A YAML file handed to the wrong command: say what it is and which command
// wants it. A scenario has groups: or grid:; a driver case has strain:, or
// material: without materials:; anything else is left to the command's own
// reader.
enum class YamlKind { other, scenario, point_case };
YamlKind yaml_kind(const std::string &file) {
    try {
        const YAML::Node n = YAML::LoadFile(file);
        if (!n.IsMap()) return YamlKind::other;
        if (n["groups"] || n["grid"]) return YamlKind::scenario;
        if (n["strain"] || (n["material"] && !n["materials"])) return YamlKind::point_case;
    } catch (const std::exception &) {
    }
    return YamlKind::other;
}

bool is_yaml_name(const std::string &s) {
    auto ends = [&](const char *e) {
        const std::string x = e;
        return s.size() > x.size() && s.compare(s.size() - x.size(), x.size(), x) == 0;
    };
    return ends(".yaml") || ends(".yml");
}

// The exception being handled, as one message on stderr; the exit status.
int report_current() {
    try {
        throw;
    } catch (const talus::Error &e) {
        std::cerr << e.what() << '\n';
    } catch (const std::filesystem::filesystem_error &e) {
        // Permissions, a missing folder, a full disk: the user's to fix.
        std::cerr << fmt::format("talus: error: {}\n", e.what());
    } catch (const std::exception &e) {
        std::cerr << "talus: internal error: " << e.what() << '\n';
    }
    return 1;
}

} // namespace

int main(int argc, char **argv) {
    CLI::App app{"Talus: Material Point Method for large-deformation solid and soil mechanics"};
    app.require_subcommand(1);
    app.set_version_flag("--version",
                         std::string(talus::host_name()) + fmt::format(" (material ABI {}.{})",
                                                                       TALUS_ABI_VERSION_MAJOR,
                                                                       TALUS_ABI_VERSION_MINOR));
    std::vector<std::string> plugin_path;
    app.add_option("--plugin-path", plugin_path,
                   "Directory searched for plugins before TALUS_PLUGIN_PATH (repeatable)")
        ->type_name("DIR");

    // talus run / validate
    auto *run = app.add_subcommand("run", "Run an MPM scenario (YAML)");
    std::string scenario_file, output_dir;
    bool force = false;
    double progress_every = 10.0;
    int threads = 0;
    std::string restart_file;
    bool force_restart = false;
    auto *scenario_option = run->add_option("scenario", scenario_file, "Scenario file (YAML)")
                                ->type_name("SCENARIO.yaml");
    auto *restart_option =
        run->add_option("--restart", restart_file,
                        "Continue the run of this checkpoint (OUT/checkpoints/checkpoint_N.h5) "
                        "in its output folder OUT, with the scenario it stores")
            ->type_name("CHECKPOINT.h5")
            ->excludes(scenario_option);
    run->add_flag("--force-restart", force_restart,
                  "With --restart: continue even if Talus or a plugin differs from the "
                  "checkpoint's")
        ->needs(restart_option);
    run->add_option("--output-dir", output_dir,
                    "Where to write results (default: a folder named after the scenario, here)")
        ->type_name("DIR");
    run->add_flag("--force", force, "Overwrite the files of a previous run in the output folder");
    bool allow_large = false;
    run->add_flag("--allow-large", allow_large,
                  "Run even when the estimated step count (1e8) or VTK file count (1e5) is "
                  "exceeded");
    run->add_option("--progress-every", progress_every,
                    "Seconds between progress lines when stderr is not a terminal (default 10)")
        ->check(kPositive);
    run->add_option("--threads", threads,
                    "Number of threads, fixed (default: up to OpenMP's, all cores, each step on "
                    "as many as run fastest beside the machine's other load)")
        ->check(kThreadCount);
    std::string run_plot, run_plot_field = "displacement";
    auto *plot_option =
        run->add_option("--plot", run_plot,
                        "After the last step, draw the particles where they ended, coloured by "
                        "--plot-field, with matplotlib (also writes final_particles.csv in the "
                        "output folder)")
            ->type_name("FILE.png");
    auto *plot_field_option =
        run->add_option("--plot-field", run_plot_field,
                        "Field for --plot: a scalar state variable of the materials (e.g. "
                        "plastic_deviatoric_strain) or displacement, speed, p, q, J (default "
                        "displacement)")
            ->type_name("NAME");
    plot_field_option->needs(plot_option);
    auto *validate = app.add_subcommand("validate", "Check a scenario file without running it");
    std::string validate_file;
    validate->add_option("scenario", validate_file, "Scenario file (YAML)")
        ->required()
        ->type_name("SCENARIO.yaml");

    // talus point
    auto *point =
        app.add_subcommand("point", "Run a single material-point test (driver case YAML)");
    std::string case_file, csv_out;
    point->add_option("case", case_file, "Driver case file (YAML)")
        ->required()
        ->type_name("CASE.yaml");
    point->add_option("-o,--output", csv_out, "Write the CSV here instead of standard output")
        ->type_name("OUT.csv");
    std::string plot_png;
    point
        ->add_option("--plot", plot_png,
                     "Also draw the four panels of a soil test (q and volumetric strain against "
                     "axial strain, the q - p' path, the controlled quantities) with matplotlib")
        ->type_name("FILE.png");
    bool show_stages = false;
    point->add_flag("--print-stages", show_stages,
                    "Print each stage's six conditions (presets expanded) and stop");

    // talus plugin info|check|list
    auto *plugin = app.add_subcommand("plugin", "Inspect and check material plugins");
    plugin->require_subcommand(1);
    auto *info =
        plugin->add_subcommand("info", "Describe a plugin library, or the model with this id");
    std::string info_target, markdown_dir;
    bool markdown = false;
    info->add_option("target", info_target, "Library path or name, or a model id")
        ->required()
        ->type_name("LIB_OR_MODEL");
    info->add_flag("--markdown", markdown,
                   "Print each model's reference page in Markdown (docs/materials/)");
    info->add_option("--output-dir", markdown_dir,
                     "With --markdown: write one MODEL_ID.md per model into this folder")
        ->type_name("DIR");
    auto *new_plugin =
        plugin->add_subcommand("new", "Write a ready-to-build plugin project (CMake, source, "
                                      "driver case, tests)");
    std::string new_name, new_dir = ".";
    new_plugin->add_option("name", new_name, "Model id and project name (lower_snake_case)")
        ->required()
        ->type_name("NAME");
    new_plugin->add_option("--dir", new_dir, "Folder to create the project in (default: .)")
        ->type_name("DIR");
    auto *list = plugin->add_subcommand("list", "List every model found on the plugin search path");
    auto *check = plugin->add_subcommand("check", "Run the conformance suite on a plugin library");
    std::string check_target;
    std::vector<std::string> check_params;
    talus::CheckOptions check_opt;
    bool no_isolate = false;
    check->add_option("library", check_target, "Library path or name")
        ->required()
        ->type_name("LIB");
    check
        ->add_option("--param", check_params,
                     "Override a parameter's typical value for the checks (repeatable)")
        ->type_name("KEY=VALUE");
    check
        ->add_option("--strain-scale", check_opt.strain_scale,
                     "Strain increment of the loading paths (default 1e-4)")
        ->check(kPositive);
    check
        ->add_option("--density", check_opt.density,
                     "Density of the test point in kg/m^3 (default 2000)")
        ->check(kPositive);
    check->add_flag("--no-isolate", no_isolate,
                    "Run the checks in this process (for debugging a plugin under gdb)");

    // CLI11 would only say "a subcommand is required" for a mistyped one.
    if (argc > 1 && argv[1][0] != '-') {
        const std::string word = argv[1];
        std::vector<std::string> names;
        for (const CLI::App *sub : app.get_subcommands({}))
            names.push_back(sub->get_name());
        if (std::find(names.begin(), names.end(), word) == names.end()) {
            const std::string guess =
                talus::yaml::closest_match(word, std::span<const std::string>(names));
            std::string known;
            for (const auto &n : names)
                known += (known.empty() ? "" : ", ") + n;
            std::cerr << fmt::format(
                "talus: unknown command '{}'{}; commands: {} (see talus --help)\n", word,
                guess.empty() ? "" : fmt::format(" (did you mean '{}'?)", guess), known);
            return 2;
        }
    }
    try {
        app.parse(argc, argv);
    } catch (const CLI::ParseError &e) {
        const int code = app.exit(e);
        return code == 0 ? 0 : 2;
    }

    // `talus run` under a launcher: MPI for the command's lifetime, and the
    // ranks the run is spread over (serial otherwise).
    std::optional<talus::MpiSession> mpi;
    talus::Comm comm = talus::Comm::serial();

    try {
        std::vector<std::filesystem::path> dirs(plugin_path.begin(), plugin_path.end());
        talus::PluginRegistry registry(dirs);

        // A plugin that crashes inside this process is named (run, validate
        // and point call plugins in-process; `plugin check` isolates them).
        if (run->parsed() || validate->parsed() || point->parsed())
            talus::crash::install_handlers();
        // A file-size limit (ulimit -f) then fails the write with EFBIG,
        // reported with the file, instead of killing the process unexplained.
        std::signal(SIGXFSZ, SIG_IGN);
        auto wrong_file = [](const std::string &file, YamlKind want, const char *command) {
            const YamlKind k = yaml_kind(file);
            if (k == YamlKind::other || k == want) return;
            throw talus::Error(
                k == YamlKind::scenario
                    ? fmt::format("{}: this is a scenario (it has groups: and grid:), not what "
                                  "`talus {}` reads; run it with `talus run {}` or check it with "
                                  "`talus validate {}`",
                                  file, command, file, file)
                    : fmt::format("{}: this is a material-point driver case (it has material:, not "
                                  "materials: and "
                                  "groups:), not "
                                  "what `talus {}` reads; run it with `talus point {}`",
                                  file, command, file));
        };

        if (run->parsed()) {
            // Started by mpirun (or srun) on several ranks: the run is spread
            // over them (docs/mpi.md). Every rank reads the input; rank 0
            // writes what the ranks share and the log.
            if (talus::MpiSession::launched_ranks() > 1) mpi.emplace(&argc, &argv);
            comm = talus::Comm::world();
            if (comm.distributed()) talus::crash::set_rank(comm.rank(), comm.size());
            if (scenario_file.empty() && restart_file.empty())
                throw talus::Error("talus run: give a scenario (SCENARIO.yaml) or --restart "
                                   "CHECKPOINT.h5");
            // A restart reads the scenario the checkpoint stores, as its run
            // read it (the file may have changed since), under the file's
            // name, so that relative paths resolve as they did.
            std::optional<talus::Checkpoint> checkpoint;
            std::optional<talus::Scenario> read;
            std::string text;
            talus::together(comm, [&] {
                if (!restart_file.empty()) {
                    checkpoint = talus::read_checkpoint_for(restart_file, comm.rank(), comm.size());
                    scenario_file = checkpoint->scenario_path;
                    text = checkpoint->scenario_text;
                    if (output_dir.empty())
                        output_dir = std::filesystem::absolute(restart_file)
                                         .parent_path()
                                         .parent_path()
                                         .string();
                } else {
                    wrong_file(scenario_file, YamlKind::scenario, "run");
                    text = talus::yaml::read_text_file(scenario_file);
                }
                // One text is parsed and stored in the checkpoints.
                const talus::yaml::Node root = talus::yaml::load_string(text, scenario_file);
                read.emplace(talus::read_scenario(root, registry));
            });
            talus::Scenario &sc = *read;
            const bool rank0 = comm.rank() == 0;
            talus::RunOptions ro;
            ro.solver.comm = comm;
            ro.scenario_text = text;
            ro.restart = checkpoint ? &*checkpoint : nullptr;
            ro.force_restart = force_restart;
            ro.output_dir = output_dir;
            ro.force = force;
            ro.allow_large = allow_large;
            ro.progress = rank0;
            ro.progress_tty = rank0 && isatty(2) != 0;
            ro.progress_interval = progress_every;
            ro.solver.threads = threads;
            ro.solver.adapt_threads = threads == 0;
            if (!run_plot.empty()) {
                // A picture that cannot be written is found out now, not
                // after the run. Its folder must exist, or be the run's
                // output folder, which the run makes (as the default job,
                // ./dev run, draws into it on a fresh build).
                namespace fs = std::filesystem;
                const fs::path folder = fs::weakly_canonical(fs::absolute(run_plot).parent_path());
                const fs::path run_dir = fs::weakly_canonical(
                    fs::absolute(output_dir.empty() ? talus::default_output_dir(sc.file)
                                                    : fs::path(output_dir)));
                if (!fs::is_directory(folder) && folder != run_dir)
                    throw talus::Error(fmt::format(
                        "--plot {}: the folder {} does not exist (nor is it the run's output "
                        "folder, {}, which the run makes)",
                        run_plot, folder.string(), run_dir.string()));
                ro.final_field = run_plot_field;
            }
            std::ostream silent(nullptr); // the other ranks' log: rank 0 tells it
            const talus::RunSummary rs = talus::run_scenario(sc, ro, rank0 ? std::cerr : silent);
            if (!rank0) return 0;
            std::cerr << fmt::format(
                "talus: {} steps to t = {:.6g} s, {} particles, {:.1f} s wall, {:.3g} "
                "particle-steps/s; {} output(s){} in {}\n",
                rs.steps, rs.time, rs.particles, rs.seconds, rs.particle_steps_per_second,
                rs.outputs,
                rs.checkpoints > 0 ? fmt::format(" and {} checkpoint(s)", rs.checkpoints) : "",
                rs.output_dir.string());
            if (!run_plot.empty()) {
                talus::plot_final_particles(
                    rs.output_dir / "final_particles.csv", run_plot,
                    fmt::format("{}: {} at t = {:.4g} s",
                                std::filesystem::path(scenario_file).filename().string(),
                                run_plot_field, rs.time));
                std::cerr << fmt::format("talus: drew {}\n", run_plot);
            }
            return 0;
        }
        if (validate->parsed()) {
            wrong_file(validate_file, YamlKind::scenario, "validate");
            const talus::yaml::Node root = talus::yaml::load_file(validate_file);
            talus::Scenario sc = talus::read_scenario(root, registry);
            // Everything `run` decides before its first step, by the same code.
            const talus::Prepared prep = talus::prepare_run(sc, {});
            const talus::RunPlan &plan = prep.plan;
            for (const std::string &n : plan.notes)
                std::cerr << n << '\n';
            for (const std::string &w : plan.over_limits)
                std::cerr << w << " (`talus run` refuses this unless --allow-large)\n";
            std::cout << fmt::format(
                "{}: valid ({}D, {} material(s), {} group(s)): {} particles, {:.3g} grid nodes, "
                "about {:.3g} MB; about {:.3g} steps of {:.3g} s{}\n",
                validate_file, sc.dim, sc.materials.size(), sc.groups.size(), plan.particles,
                plan.estimate.nodes, plan.estimate.bytes / 1e6, plan.steps, plan.first_dt,
                plan.output_files > 0 ? fmt::format(", {:.3g} VTK files", plan.output_files)
                                      : std::string());
            return 0;
        }
        if (point->parsed()) {
            wrong_file(case_file, YamlKind::point_case, "point");
            const talus::yaml::Node root = talus::yaml::load_file(case_file);
            const talus::PointCase pc = talus::read_point_case(root, registry);
            if (show_stages) {
                talus::print_stages(std::cout, pc);
                return 0;
            }
            std::vector<talus::PointRow> rows;
            // What made the rows: beside the CSV file, or on stderr when the
            // CSV goes to stdout (which stays plain CSV).
            const talus::Provenance prov{"point", case_file, {{"material", &pc.material}}};
            auto write_provenance = [&](const std::string &csv_file) {
                if (csv_file.empty())
                    std::cerr << talus::provenance_comments(prov);
                else
                    talus::write_file_atomically(csv_file + ".provenance.json",
                                                 talus::provenance_json(prov));
            };
            auto csv_text = [&] {
                std::ostringstream csv;
                talus::write_point_csv(csv, *pc.instance, pc.axis, rows);
                return csv.str();
            };
            try {
                talus::run_point_case(pc, rows);
            } catch (const talus::Error &e) {
                // The rows up to the failure go beside the requested file,
                // under a name that cannot be mistaken for a result.
                if (csv_out.empty() || rows.empty()) throw;
                const std::string partial = csv_out + ".failed.csv";
                talus::write_file_atomically(partial, csv_text());
                write_provenance(partial);
                throw talus::Error(fmt::format("{}\n(the {} rows computed until then are in {}; "
                                               "{} was not written)",
                                               e.what(), rows.size(), partial, csv_out));
            }
            const std::string csv = csv_text();
            if (csv_out.empty())
                std::cout << csv;
            else
                talus::write_file_atomically(csv_out, csv);
            write_provenance(csv_out);
            if (!plot_png.empty()) {
                std::filesystem::path source = csv_out;
                std::filesystem::path tmp;
                if (csv_out.empty()) {
                    tmp = std::filesystem::path(plot_png).replace_extension(".plot-data.csv");
                    talus::write_file_atomically(tmp, csv);
                    source = tmp;
                }
                talus::plot_point_csv(
                    source, plot_png,
                    fmt::format("{} - {}", std::filesystem::path(case_file).filename().string(),
                                pc.instance->model().id()));
                if (!tmp.empty()) std::filesystem::remove(tmp);
            }
            if (pc.compare) {
                const std::string report = talus::compare_point_rows(pc, rows);
                if (!report.empty()) {
                    std::cerr << "talus point: " << report;
                    return 3;
                }
                std::cerr << fmt::format("talus point: compare: every value within tolerance of "
                                         "{}\n",
                                         pc.compare->file);
            }
            return 0;
        }
        if (info->parsed()) {
            // A path, or a bare word that names a library file on the search
            // path, is a library (whose load errors are reported); any other
            // word is a model id.
            std::filesystem::path library;
            if (talus::PluginRegistry::is_path(info_target)) {
                library = registry.locate(info_target);
            } else {
                try {
                    library = registry.locate(info_target);
                } catch (const talus::Error &) {
                }
            }
            if (markdown) {
                std::vector<const talus::Model *> models;
                if (!library.empty())
                    for (const talus::Model &m : registry.load(library.string()).models())
                        models.push_back(&m);
                else
                    models.push_back(&registry.find_model(info_target));
                for (const talus::Model *m : models) {
                    const std::string page = talus::model_markdown(*m);
                    if (markdown_dir.empty()) {
                        std::cout << page;
                    } else {
                        const auto file = std::filesystem::path(markdown_dir) / (m->id() + ".md");
                        talus::write_file_atomically(file, page);
                        std::cerr << fmt::format("talus: wrote {}\n", file.string());
                    }
                }
                return 0;
            }
            if (!markdown_dir.empty()) throw talus::Error("--output-dir goes with --markdown");
            if (!library.empty()) {
                print_library(std::cout, registry.load(library.string()));
                return 0;
            }
            const talus::Model &m = registry.find_model(info_target);
            std::cout << fmt::format("(from {} {}, {}; build: {})\n\n", m.library().name(),
                                     m.library().version(), m.library().path().string(),
                                     m.library().build_text());
            print_model(std::cout, m);
            return 0;
        }
        if (new_plugin->parsed()) {
            const std::filesystem::path dir = talus::write_plugin_project(new_name, new_dir);
            std::cout << fmt::format(
                "talus: wrote the plugin project {0}\n"
                "  cmake -S {0} -B {0}/build -DCMAKE_PREFIX_PATH=<where Talus is installed>\n"
                "  cmake --build {0}/build && ctest --test-dir {0}/build\n",
                dir.string());
            return 0;
        }
        if (list->parsed()) {
            registry.load_all();
            if (registry.libraries().empty()) {
                std::cout << "no plugins found; searched:\n";
                for (const auto &d : registry.search_dirs())
                    std::cout << "  " << d.string() << '\n';
                return 1;
            }
            for (const auto &lib : registry.libraries())
                for (const talus::Model &m : lib->models())
                    std::cout << fmt::format("{:<20} {:<8} {:<50} {}\n", m.id(), m.version(),
                                             m.name(), lib->path().string());
            return 0;
        }
        if (check->parsed()) {
            for (const std::string &kv : check_params) {
                const auto eq = kv.find('=');
                if (eq == std::string::npos || eq == 0)
                    throw talus::Error(fmt::format("--param {}: expected KEY=VALUE", kv));
                // Parsed by the parameter's type once the model is known.
                check_opt.params.emplace_back(kv.substr(0, eq), kv.substr(eq + 1));
            }
            check_opt.isolate = !no_isolate;
            if (is_yaml_name(check_target))
                throw talus::Error(fmt::format(
                    "{}: `talus plugin check` checks a plugin library (a .so file, or its name on "
                    "the plugin path), not a YAML file; {}",
                    check_target,
                    yaml_kind(check_target) == YamlKind::scenario
                        ? fmt::format("this is a scenario: `talus validate {}` checks it",
                                      check_target)
                        : fmt::format("a driver case runs with `talus point {}`", check_target)));
            // Resolve a name through the search path, but do not load it
            // here: the checks load it themselves (in a child process).
            const std::filesystem::path file = registry.locate(check_target);
            const talus::ConformanceReport rep = talus::check_plugin(file, check_opt);
            talus::print_report(std::cout, rep);
            return rep.passed() ? 0 : 1;
        }
    } catch (const talus::Interrupted &e) {
        // On several ranks, every rank stops together: rank 0 tells.
        if (comm.rank() == 0) std::cerr << e.what() << '\n';
        return 128 + e.signal();
    } catch (const talus::AgreedError &e) {
        if (comm.rank() == 0) std::cerr << e.what() << '\n';
        return 1;
    } catch (const std::exception &e) {
        if (!comm.distributed()) return report_current();
        // One rank's failure alone: the others may wait for it in an
        // exchange, so all end now.
        std::cerr << fmt::format("talus: rank {} of {}: ", comm.rank(), comm.size());
        report_current();
        talus::MpiSession::abort(1);
    }
    return 0;
}
