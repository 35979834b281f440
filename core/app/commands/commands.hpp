// The commands of `talus`, one file each; each adds its subcommand and
// options to `parent` and returns the command that runs it.
#pragma once

#include "../cli.hpp"

#include <memory>

namespace talus::cli {

std::unique_ptr<Command> run_command(CLI::App &parent);
std::unique_ptr<Command> validate_command(CLI::App &parent);
std::unique_ptr<Command> point_command(CLI::App &parent);
// The subcommands of `talus plugin`.
std::unique_ptr<Command> plugin_info_command(CLI::App &plugin);
std::unique_ptr<Command> plugin_new_command(CLI::App &plugin);
std::unique_ptr<Command> plugin_list_command(CLI::App &plugin);
std::unique_ptr<Command> plugin_check_command(CLI::App &plugin);

} // namespace talus::cli
