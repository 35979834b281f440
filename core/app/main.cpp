// The `talus` command: run and validate a scenario, the material-point
// driver, the plugin tools; one file of commands/ each. Every user error
// ends in one message on stderr and exit status 1; command-line misuse
// exits with status 2 (CLI11's convention is kept: 105 and up are its own
// parse errors, mapped to 2 here).
#include "cli.hpp"
#include "commands/commands.hpp"

#include <talus/driver/run.hpp>
#include <talus/error.hpp>
#include <talus/input/yaml_input.hpp>
#include <talus/material/crash_report.hpp>
#include <talus/mpm/comm.hpp>

#include <CLI/CLI.hpp>
#include <fmt/format.h>

#include <csignal>
#include <filesystem>
#include <iostream>
#include <memory>
#include <optional>
#include <vector>

namespace {

// A message that does not yet say it is an error (a located input error
// does: "file:line:col: error: ...") gets the prefix every other error and
// warning of the command has, so that a script or a reader finds each by
// "error:".
std::string as_error(const std::string &message) {
    const std::string first = message.substr(0, message.find('\n'));
    if (first.rfind("error:", 0) == 0 || first.find(": error:") != std::string::npos)
        return message;
    return "talus: error: " + message;
}

// The exception being handled, as one message on stderr; the exit status.
int report_current() {
    try {
        throw;
    } catch (const talus::Error &e) {
        std::cerr << as_error(e.what()) << '\n';
    } catch (const std::filesystem::filesystem_error &e) {
        // Permissions, a missing folder, a full disk: the user's to fix.
        std::cerr << fmt::format("talus: error: {}\n", e.what());
    } catch (const std::bad_alloc &) {
        std::cerr << "talus: error: out of memory (an allocation failed; the machine's memory, "
                     "ulimit -v or a job's limit)\n";
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
    // The options of `talus` itself may also follow the command's
    // (`talus run x.yaml --quiet`).
    app.fallthrough();
    std::vector<std::string> plugin_path;
    app.add_option("--plugin-path", plugin_path,
                   "Directory searched for plugins before TALUS_PLUGIN_PATH (repeatable)")
        ->type_name("DIR");
    bool quiet = false, verbose = false;
    auto *quiet_flag =
        app.add_flag("-q,--quiet", quiet,
                     "Say errors and warnings only (run, validate, point): no plan, progress, "
                     "notes or summary");
    app.add_flag("-v,--verbose", verbose,
                 "Say more (run, validate, point): the plugins loaded, every output and "
                 "checkpoint written, every message of a plugin")
        ->excludes(quiet_flag);
    std::vector<std::unique_ptr<talus::cli::Command>> commands;
    commands.push_back(talus::cli::run_command(app));
    commands.push_back(talus::cli::validate_command(app));
    commands.push_back(talus::cli::point_command(app));
    auto *plugin = app.add_subcommand("plugin", "Inspect and check material plugins");
    plugin->require_subcommand(1);
    commands.push_back(talus::cli::plugin_info_command(*plugin));
    commands.push_back(talus::cli::plugin_new_command(*plugin));
    commands.push_back(talus::cli::plugin_list_command(*plugin));
    commands.push_back(talus::cli::plugin_check_command(*plugin));

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

    std::optional<talus::MpiSession> mpi;
    talus::Comm comm = talus::Comm::serial();
    try {
        std::vector<std::filesystem::path> dirs(plugin_path.begin(), plugin_path.end());
        talus::PluginRegistry registry(dirs);
        talus::cli::Context ctx{registry, argc, argv, mpi, comm};
        ctx.verbosity = quiet     ? talus::Verbosity::quiet
                        : verbose ? talus::Verbosity::verbose
                                  : talus::Verbosity::normal;
        if (verbose) talus::set_plugin_log_policy(SIZE_MAX, true);
        if (quiet) talus::set_plugin_log_policy(talus::kPluginLogShown, false);
        for (const auto &c : commands) {
            if (!c->parsed()) continue;
            // A plugin that crashes inside this process is named (run,
            // validate and point call plugins in-process; `plugin check`
            // isolates them).
            if (c->calls_plugins()) talus::crash::install_handlers();
            // A file-size limit (ulimit -f) then fails the write with EFBIG,
            // reported with the file, instead of killing the process
            // unexplained.
            std::signal(SIGXFSZ, SIG_IGN);
            // How many of a plugin's log messages were not shown, once the
            // command is done (or failed).
            auto notes = [&] {
                // (Said under --quiet too: it counts warnings the run was
                // told would be counted.)
                if (comm.rank() != 0) return;
                for (const auto &lib : registry.libraries())
                    if (const std::string n = lib->log_note(); !n.empty()) std::cerr << n << '\n';
            };
            int status = 0;
            try {
                status = c->run(ctx);
            } catch (...) {
                notes();
                throw;
            }
            notes();
            return status;
        }
    } catch (const talus::Interrupted &e) {
        // On several ranks, every rank stops together: rank 0 tells.
        if (comm.rank() == 0) std::cerr << e.what() << '\n';
        return 128 + e.signal();
    } catch (const talus::AgreedError &e) {
        if (comm.rank() == 0) std::cerr << as_error(e.what()) << '\n';
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
