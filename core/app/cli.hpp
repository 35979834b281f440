// What the commands of the `talus` command line share: the validators of
// their options, the context a command runs in, and the recognition of a
// YAML file handed to the wrong command. Each command is a file of
// commands/ (commands.hpp lists them); main.cpp parses and dispatches.
// They are compiled as one translation unit (UNITY_BUILD on the talus
// target, core/CMakeLists.txt), so the names in their anonymous namespaces
// must not repeat.
#pragma once

#include <talus/material/plugin_loader.hpp>
#include <talus/mpm/comm.hpp>
#include <talus/verbosity.hpp>

#include <CLI/CLI.hpp>

#include <optional>
#include <string>

namespace talus::cli {

// A number above zero. (CLI11's PositiveNumber names its range "0.000000
// to" the largest double in all its 309 digits.)
extern const CLI::Validator kPositive;
// A thread count: a whole number from 1 to kMaxThreads (CLI11's own message
// for 2.5 was "Could not convert: --threads = 2.5").
extern const CLI::Validator kThreadCount;

// A YAML file handed to the wrong command: say what it is and which command
// wants it. A scenario has groups: or grid:; a driver case has strain:, or
// material: without materials:; anything else is left to the command's own
// reader.
enum class YamlKind { other, scenario, point_case };
YamlKind yaml_kind(const std::string &file);
bool is_yaml_name(const std::string &s);
// Throws talus::Error naming the command that reads `file` if it is a YAML
// file of another kind than `want`.
void refuse_wrong_file(const std::string &file, YamlKind want, const char *command);

// What a command runs with. `mpi` and `comm`: `talus run` under a launcher
// starts MPI for the command's lifetime and spreads the run over the ranks
// (serial otherwise); main reports errors by rank.
struct Context {
    PluginRegistry &registry;
    int &argc;
    char **&argv;
    std::optional<MpiSession> &mpi;
    Comm &comm;
    Verbosity verbosity = Verbosity::normal; // --quiet, --verbose
};

// One command: its options are added to the command line when it is made;
// `run` is called when the command line named it, and returns the exit
// status (a failure throws).
class Command {
  public:
    explicit Command(CLI::App *app) : app_(app) {}
    virtual ~Command() = default;
    Command(const Command &) = delete;
    Command &operator=(const Command &) = delete;
    bool parsed() const { return app_->parsed(); }
    // Commands that call plugins in this process, whose crash is named.
    virtual bool calls_plugins() const { return false; }
    virtual int run(Context &ctx) = 0;

  protected:
    CLI::App *app_;
};

} // namespace talus::cli
