// talus plugin new: a ready-to-build plugin project (../plugin_new.cpp
// writes it).
#include "commands.hpp"

#include "../plugin_new.hpp"

#include <fmt/format.h>

#include <iostream>

namespace talus::cli {

namespace {

class PluginNew final : public Command {
  public:
    explicit PluginNew(CLI::App &plugin)
        : Command(plugin.add_subcommand("new", "Write a ready-to-build plugin project (CMake, "
                                               "source, driver case, tests)")) {
        app_->add_option("name", name_, "Model id and project name (lower_snake_case)")
            ->required()
            ->type_name("NAME");
        app_->add_option("--dir", dir_, "Folder to create the project in (default: .)")
            ->type_name("DIR");
    }
    int run(Context &) override {
        const std::filesystem::path dir = write_plugin_project(name_, dir_);
        std::cout << fmt::format(
            "talus: wrote the plugin project {0}\n"
            "  cmake -S {0} -B {0}/build -DCMAKE_PREFIX_PATH=<where Talus is installed>\n"
            "  cmake --build {0}/build && ctest --test-dir {0}/build\n",
            dir.string());
        return 0;
    }

  private:
    std::string name_, dir_ = ".";
};

} // namespace

std::unique_ptr<Command> plugin_new_command(CLI::App &plugin) {
    return std::make_unique<PluginNew>(plugin);
}

} // namespace talus::cli
