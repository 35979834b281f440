// talus plugin list: every model on the plugin search path.
#include "commands.hpp"

#include <fmt/format.h>

#include <iostream>

namespace talus::cli {

namespace {

class PluginList final : public Command {
  public:
    explicit PluginList(CLI::App &plugin)
        : Command(
              plugin.add_subcommand("list", "List every model found on the plugin search path")) {}
    int run(Context &ctx) override {
        PluginRegistry &registry = ctx.registry;
        registry.load_all();
        if (registry.libraries().empty()) {
            std::cout << "no plugins found; searched:\n";
            for (const auto &d : registry.search_dirs())
                std::cout << "  " << d.string() << '\n';
            return 1;
        }
        for (const auto &lib : registry.libraries())
            for (const Model &m : lib->models())
                std::cout << fmt::format("{:<20} {:<8} {:<50} {}\n", m.id(), m.version(), m.name(),
                                         lib->path().string());
        return 0;
    }
};

} // namespace

std::unique_ptr<Command> plugin_list_command(CLI::App &plugin) {
    return std::make_unique<PluginList>(plugin);
}

} // namespace talus::cli
